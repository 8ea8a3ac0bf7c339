// Shared test helpers: allclose / bitwise comparisons, temporary directories, running the CLI.
#pragma once
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <sys/wait.h>
#include <vector>

namespace hinf::test {

/// A fresh directory under the system temp dir, removed at scope exit.
struct TempDir {
    std::filesystem::path path;
    explicit TempDir(const std::string& tag) {
        std::string tmpl = (std::filesystem::temp_directory_path() / ("hinf-" + tag + "-XXXXXX")).string();
        std::vector<char> buf(tmpl.begin(), tmpl.end());
        buf.push_back('\0');
        path = mkdtemp(buf.data());
    }
    ~TempDir() {
        std::error_code ec;
        std::filesystem::remove_all(path, ec);
    }
    std::string operator/(const std::string& name) const { return (path / name).string(); }
};

struct CommandResult {
    int status = -1;
    std::string output;  // stdout and stderr together
};

/// Runs a shell command, capturing its output and exit status.
inline CommandResult run_command(const std::string& cmd) {
    CommandResult r;
    FILE* p = popen((cmd + " 2>&1").c_str(), "r");
    if (!p) return r;
    std::array<char, 4096> buf;
    while (std::size_t n = std::fread(buf.data(), 1, buf.size(), p)) r.output.append(buf.data(), n);
    int st = pclose(p);
    r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    return r;
}

/// Runs the hinf binary with the given arguments.
inline CommandResult run_hinf(const std::string& args) { return run_command(std::string(HINF_CLI_PATH) + " " + args); }

inline std::string source_path(const std::string& rel) { return std::string(HINF_SOURCE_DIR) + "/" + rel; }

template <typename T>
bool bitwise_equal(const std::vector<T>& a, const std::vector<T>& b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

/// Largest |a-b| / max(|a|,|b|,floor) over the two vectors.
template <typename T>
double max_rel_diff(const std::vector<T>& a, const std::vector<T>& b, double floor = 1e-12) {
    double worst = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        double d = std::fabs(double(a[i]) - double(b[i]));
        double s = std::max({std::fabs(double(a[i])), std::fabs(double(b[i])), floor});
        worst = std::max(worst, d / s);
    }
    return worst;
}

}  // namespace hinf::test
