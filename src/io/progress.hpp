// Progress lines on stderr for long runs: a live line on a terminal, a plain line every few seconds
// otherwise. Not a logger: results go to files.
#pragma once
#include <chrono>
#include <cstdint>
#include <string>

namespace hinf {

class Progress {
public:
    Progress(std::string label, std::int64_t first, std::int64_t total, bool quiet = false);
    /// Reports that step `done` (absolute) is finished; `detail` is appended (loss, residual...).
    void update(std::int64_t done, const std::string& detail);
    void finish(const std::string& summary);

private:
    std::string label_;
    std::int64_t first_, total_;
    bool quiet_, tty_;
    std::chrono::steady_clock::time_point start_, last_;
};

std::string format_duration(double seconds);

}  // namespace hinf
