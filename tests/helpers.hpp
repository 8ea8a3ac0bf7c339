// Shared test helpers: allclose / bitwise comparisons, temporary directories, running the CLI.
#pragma once
#include <array>
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <sys/wait.h>
#include <vector>

#include "config/run_config.hpp"
#include "gemm.hpp"
#include "hinf/config.hpp"
#include "hinf/error.hpp"

namespace hinf::test {

/// A run config from TOML text, with one `--set` override (KEY=VALUE) applied first when `set` is given.
inline RunConfig config_from_text(const std::string& text, const std::string& set = "") {
    ConfigDoc doc = ConfigDoc::from_text(text, "t.toml");
    if (!set.empty()) doc.set(set);
    return load_run_config(doc);
}

/// A phase-locked loop's [system] section (the angle tests): the phase and frequency of a sinusoid seen through
/// y = sin(phi), the phase an angle state that winds.
inline std::string phase_lock_system() {
    return R"cfg([system]
kind = "expr"
states = ["phi", "w"]
disturbances = 2
measurements = 1
f = ["w", "0"]
g = [["1", "0"], ["0", "1"]]
h = ["sin(phi)"]
angle_states = [1]
)cfg";
}

/// The number of newline characters in `s`.
inline int count_lines(const std::string& s) { return static_cast<int>(std::count(s.begin(), s.end(), '\n')); }

/// How often `what` occurs in `text` (overlapping occurrences counted).
inline int count_occurrences(const std::string& text, const std::string& what) {
    int n = 0;
    for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
    return n;
}

/// A whole file's text ("" when it cannot be opened).
inline std::string read_text(const std::string& path) {
    std::ifstream in(path);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

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

/// A run written by an older hinf: tests/corpus/legacy/NAME_checkpoint.h5 and NAME_trajectory.h5 copied into dir
/// (created) as checkpoint.h5 and trajectory.h5, ready to resume; returns dir/checkpoint.h5. NAME_full.h5 beside
/// them is that hinf's checkpoint at the end of the uninterrupted run.
inline std::string copy_legacy_run(const std::string& name, const std::string& dir) {
    std::filesystem::create_directories(dir);
    std::filesystem::copy_file(source_path("tests/corpus/legacy/" + name + "_checkpoint.h5"), dir + "/checkpoint.h5");
    std::filesystem::copy_file(source_path("tests/corpus/legacy/" + name + "_trajectory.h5"), dir + "/trajectory.h5");
    return dir + "/checkpoint.h5";
}

/// An array of a legacy run's NAME_full.h5 against today's resume of it: bit for bit where the GEMM path that wrote
/// the fixtures runs (hinf's own AVX-512 kernels, kern::gemm_own_available()). Elsewhere the MLP's products run through
/// OpenBLAS, whose f32 sums round in another order, so within 10^-6 of the array's largest entry (measured on an AVX2
/// machine: at most 9·10^-8 after the runs' resumed steps).
inline void check_legacy_array(const std::vector<double>& got, const std::vector<double>& want) {
    REQUIRE(got.size() == want.size());
    if (hinf::kern::gemm_own_available()) {
        CHECK(got == want);
        return;
    }
    double scale = 0;
    for (double w : want) scale = std::max(scale, std::fabs(w));
    for (std::size_t i = 0; i < got.size(); ++i) CHECK(std::fabs(got[i] - want[i]) <= 1e-6 * scale);
}

/// The [network] and [training] sections of a training that takes a fraction of a second (an 8-neuron network, 100
/// samples, 2 Adam steps a time step); lines for [training] may follow.
inline std::string tiny_network_and_training() {
    return "[network]\nhidden = [8]\n[training]\nsamples = 100\nbatch = 40\nadam_steps = 2\ncheckpoint_every = 10\n";
}

/// A Van der Pol config of the `gain` variant (position-only, nonlinear sensor: m < n) that trains in a fraction of
/// a second; `training_extra` lines go into [training].
inline std::string tiny_vdp_gain_config(const std::string& t_final = "0.5", const std::string& training_extra = "") {
    return R"([system]
kind = "expr"
states = ["p", "w"]
disturbances = 1
measurements = 1
parameters = { mu = 1.0, c = 0.3 }
f = ["w", "mu*(1 - p^2)*w - p"]
g = [["0"], ["1"]]
h = ["p + c*p^3"]
[filter]
variant = "gain"
rho = 0.5
Q = [1.0, 1.0]
x0 = [2.0, 0.0]
xhat0 = [0.5, 1.0]
dt = 0.01
t_final = )" + t_final + "\n" + tiny_network_and_training() + training_extra + R"([sampling]
error_floor = [0.2, 0.2]
trajectories = 3
[objective]
disturbance_intensity = 0.0025
noise_intensity = 0.0001
[online]
mode = "measured"
disturbance_std = 0.5
noise_std = 0.1
runs = 3
)";
}

/// The [system] block of a small linear discrete-time system (n = 2, nv = 1, m = 1) the `gain` variant trains on.
inline std::string linear_discrete_system_toml() {
    return R"([system]
kind = "expr"
time = "discrete"
states = ["a", "b"]
disturbances = 1
measurements = 1
f = ["1.05*a + 0.2*b", "-0.1*a + 0.9*b"]
g = [["0.5"], ["1"]]
h = ["a + 0.5*b"]
)";
}

/// A missile config that trains in a fraction of a second (tiny network, few samples).
/// (variant `dissipative`, named: the CLI tests that use it read its oracle mode and its p = dV/dx~ columns; the
/// default variant, `gain`, has its own tests)
inline std::string tiny_missile_config(const std::string& t_final = "0.05") {
    return "[system]\nkind = \"missile\"\n[filter]\nvariant = \"dissipative\"\nt_final = " + t_final +
           "\n[network]\nhidden = [8]\n[training]\nsamples = 50\nbatch = 20\nadam_steps = 2\ncheckpoint_every = 2\n";
}

/// Writes `text` to dir/name (binary, exact bytes) and returns the path.
inline std::string write_file(const TempDir& dir, const std::string& name, const std::string& text) {
    std::string path = dir / name;
    std::ofstream(path, std::ios::binary) << text;
    return path;
}

/// `hinf ARGS` must exit 2 with exactly one line "hinf: error: ...FRAGMENT...".
inline void expect_one_line_error(const std::string& args, const std::string& fragment) {
    INFO("hinf " << args);
    CommandResult r = run_hinf(args);
    INFO(r.output);
    CHECK(r.status == 2);
    CHECK(r.output.find(fragment) != std::string::npos);
    CHECK(r.output.rfind("hinf: error: ", 0) == 0);
    CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 1);
}

/// call() throws hinf::Error whose message is one line and contains fragment.
inline bool one_line_error(const std::function<void()>& call, const std::string& fragment) {
    try {
        call();
    } catch (const hinf::Error& e) {
        const std::string what = e.what();
        INFO(what);
        CHECK(what.find('\n') == std::string::npos);
        return what.find(fragment) != std::string::npos;
    }
    return false;
}

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

/// A CSV file with a header line (no quoted cells): one map per row, column name -> cell.
inline std::vector<std::map<std::string, std::string>> read_csv_rows(const std::string& path) {
    std::ifstream in(path);
    std::string line;
    std::vector<std::string> head;
    std::vector<std::map<std::string, std::string>> rows;
    for (bool first = true; std::getline(in, line); first = false) {
        std::vector<std::string> cells;
        std::stringstream s(line);
        for (std::string c; std::getline(s, c, ',');) cells.push_back(c);
        if (first) {
            head = cells;
            continue;
        }
        REQUIRE(cells.size() == head.size());
        std::map<std::string, std::string> row;
        for (std::size_t i = 0; i < cells.size(); ++i) row[head[i]] = cells[i];
        rows.push_back(row);
    }
    return rows;
}

}  // namespace hinf::test
