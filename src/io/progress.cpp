// Progress reporting with ETA (see progress.hpp).
#include "io/progress.hpp"

#include <cstdio>
#include <unistd.h>

#include "par/par.hpp"

namespace hinf {

std::string format_duration(double s) {
    char buf[32];
    if (s < 60)
        std::snprintf(buf, sizeof buf, "%.1fs", s);
    else if (s < 3600)
        std::snprintf(buf, sizeof buf, "%dm%02ds", int(s) / 60, int(s) % 60);
    else
        std::snprintf(buf, sizeof buf, "%dh%02dm", int(s) / 3600, (int(s) % 3600) / 60);
    return buf;
}

Progress::Progress(std::string label, std::int64_t first, std::int64_t total, bool quiet)
    : label_(std::move(label)), first_(first), total_(total), quiet_(quiet || par_world_rank() != 0), tty_(isatty(STDERR_FILENO) != 0) {
    start_ = last_ = std::chrono::steady_clock::now();
}

void Progress::update(std::int64_t done, const std::string& detail) {
    if (quiet_) return;
    auto now = std::chrono::steady_clock::now();
    double since = std::chrono::duration<double>(now - last_).count();
    if (since < (tty_ ? 0.25 : 5.0) && done < total_) return;
    last_ = now;
    double elapsed = std::chrono::duration<double>(now - start_).count();
    double rate = (done - first_) > 0 ? elapsed / double(done - first_) : 0.0;
    double eta = rate * double(total_ - done);
    std::fprintf(stderr, "%s%s %lld/%lld (%.1f%%) %s elapsed %s ETA %s%s", tty_ ? "\r\033[K" : "", label_.c_str(),
                 static_cast<long long>(done), static_cast<long long>(total_),
                 total_ > 0 ? 100.0 * double(done) / double(total_) : 100.0, detail.c_str(),
                 format_duration(elapsed).c_str(), format_duration(eta).c_str(), tty_ ? "" : "\n");
    std::fflush(stderr);
}

void Progress::finish(const std::string& summary) {
    if (quiet_) return;
    double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    std::fprintf(stderr, "%s%s done in %s. %s\n", tty_ ? "\r\033[K" : "", label_.c_str(),
                 format_duration(elapsed).c_str(), summary.c_str());
}

}  // namespace hinf
