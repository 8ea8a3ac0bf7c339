// The side-by-side comparison (issue 5): every filter on the same truth, the same measurement noise
// realisations and the same initial estimate, R Monte Carlo runs, confidence intervals. Not the filters
// (src/filters) and not the argument parsing (cli/compare_cmd.cpp).
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "filters/filter.hpp"
#include "config/run_config.hpp"

namespace hinf {

/// What differs from the nominal protocol (seed 000 Section IV: v, n ~ std N(0, 1), statistics known).
struct CompareScenario {
    std::string name = "nominal";
    double told_disturbance_factor = 1.0;  // EKF/UKF/PF are told sv^2 x this (cov_small, v_cov_small: 0.1; *_large: 10)
    double told_noise_factor = 1.0;        // ... and sn^2 x this (cov_small, n_cov_small: 0.1; *_large: 10)
    bool student_t = false;             // n = std * t_3 / sqrt(3): heavy tails, same variance
    double noise_bias = 0.0;            // n = std * (N(0,1) + noise_bias) on every channel
    bool energy_pulse = false;          // v = std sqrt(T / 5 s) on [20 s, 25 s), 0 elsewhere (same energy as white v)
};
/// nominal, cov_small, cov_large, v_cov_small, v_cov_large, n_cov_small, n_cov_large, student_t, bias,
/// energy_pulse; throws on anything else.
CompareScenario compare_scenario(const std::string& name);
std::vector<std::string> compare_scenario_names();

struct CompareOptions {
    std::string out_dir = "runs/out/compare";
    std::int64_t runs = 50;
    double until = -1;  // < 0: t_final
    CompareScenario scenario;
    bool quiet = false;
};

struct CompareFilterResult {
    std::string name, mode;  // mode: "oracle" (reads the true state) or "measured"
    std::int64_t diverged_runs = 0;
    // per state, over the non-diverged runs: error x - x^ mean and std over time within a run (full horizon
    // and t >= settle_time), averaged over runs, with 95% half-widths 1.96 sd / sqrt(runs)
    std::vector<double> mean, mean_ci, std, std_ci;
    std::vector<double> mean_settled, mean_settled_ci, std_settled, std_settled_ci;
    double rmse_position = 0, rmse_velocity = 0, rmse_position_settled = 0, rmse_velocity_settled = 0;
    double attenuation_ratio = 0, attenuation_ratio_ci = 0;  // int x~'Qx~ / int (v'v + n'n), over non-diverged runs
    double us_per_step = 0;                                    // filter time only, per step
    std::uint64_t stream_hash = 0;                             // FNV-1a of every y this filter was fed
};

struct CompareSummary {
    std::string scenario;
    std::int64_t runs = 0, steps = 0;
    std::uint64_t truth_stream_hash = 0;  // FNV-1a of the simulated measurements, in run and step order
    std::vector<CompareFilterResult> filters;
    double wall_seconds = 0;
};

/// Runs every filter (prototypes, cloned per thread) on the same R simulated runs of cfg's system; writes
/// out_dir/compare.h5 and out_dir/compare.csv. OpenMP over runs; results do not depend on the thread count.
CompareSummary compare_run(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                           const CompareOptions& opt);

/// FNV-1a 64 over bytes, continuing from h (start with compare_hash_start).
constexpr std::uint64_t compare_hash_start = 1469598103934665603ull;
std::uint64_t compare_hash(std::uint64_t h, const void* data, std::size_t bytes);

}  // namespace hinf
