// The one truth simulator: the true system driven by disturbance v and noise n, and the measurements it
// gives. Every Monte Carlo user (operate, compare, the worst-case search) draws its signals here only.
// Not the filters (src/filters) nor any statistic (src/eval).
//
// Shape legend: steps = time steps, n = states, nv = disturbance inputs, m = outputs.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "config/run_config.hpp"
#include "core/spelling.hpp"
#include "filters/filter.hpp"

namespace hinf {

/// What differs from the nominal protocol (seed 000 Section IV: v, n ~ std N(0, 1), statistics known).
struct Scenario {
    std::string name = "nominal";
    double told_disturbance_factor = 1.0;  // EKF/UKF/PF are told sv^2 x this (cov_small, v_cov_small: 0.1; *_large: 10)
    double told_noise_factor = 1.0;        // ... and sn^2 x this (cov_small, n_cov_small: 0.1; *_large: 10)
    bool student_t = false;                // n = std * t_3 / sqrt(3): heavy tails, same variance
    double noise_bias = 0.0;               // n = std * (N(0,1) + noise_bias) on every channel
    bool energy_pulse = false;             // v = std sqrt(T / 5 s) on [20 s, 25 s), 0 elsewhere (same energy as white v)
};
/// nominal, cov_small, cov_large, v_cov_small, v_cov_large, n_cov_small, n_cov_large, student_t, bias,
/// energy_pulse; throws on anything else (the line names the option as `spelling` does).
Scenario scenario_named(const std::string& name, Spelling spelling = Spelling::program);
std::vector<std::string> scenario_names();

/// energy_pulse's window, fixed in the system's time unit: seed 000's manoeuvre at 20 <= t < 25 s of its 70 s
constexpr double kPulseStart = 20.0, kPulseEnd = 25.0;
/// How much of that window lies inside a run of `steps` steps (0: the pulse comes after the run ends, and the
/// scenario then has no disturbance at all)
double energy_pulse_span(const RunConfig& cfg, std::int64_t steps);

/// Explicit disturbance and noise sequences; when given they replace the random draws (worst-case search, replay).
struct Signals {
    std::vector<double> v;  // [steps x nv]
    std::vector<double> n;  // [steps x m]
};

/// One simulated run: x(t_k) before step k, y(t_k) = C(x(t_k)) + n_k, the signals, and v'v + n'n per step.
struct TruthRun {
    std::vector<double> x;       // [steps x n]
    std::vector<double> y;       // [steps x m]
    std::vector<double> v;       // [steps x nv]
    std::vector<double> n;       // [steps x m]
    std::vector<double> energy;  // [steps]
};

/// Run `run` of cfg's system from cfg.x0 over `steps` steps (system_advance with the real v). Draws: Philox keyed by
/// (online seed, RNG_STREAM_NOISE, run, step), scaled by [online] disturbance_std / noise_std, then changed by the
/// scenario; `given` replaces them.
TruthRun truth_simulate(const RunConfig& cfg, const Scenario& sc, std::uint64_t run, std::int64_t steps,
                        const Signals* given = nullptr);

/// Where a truth has run away (docs/compare.md, "A truth that escapes"): per state kTruthEscapeFactor times the
/// largest of |x0_i|, |x^0_i|, [baseline] initial_std_i and |x_i| along the noise-free run from x0 over `steps` steps;
/// +inf for a state where all of them are 0 (only a non-finite value counts there). A truth 10^12 times beyond every
/// scale its config gives it is no state a filter can be blamed for losing, and an escape that has begun but not yet
/// overflowed at the horizon (the Henon map's last few steps) is caught by it.
inline constexpr double kTruthEscapeFactor = 1e12;
std::vector<double> truth_escape_bound(const RunConfig& cfg, std::int64_t steps);

/// Steps a truth is simulated past its horizon to see whether it is running away (an escape begun in the horizon's
/// last steps, still finite there: the Henon map overflows within about ten steps of leaving its basin). The runs
/// are cut back to the horizon after the look; the steps inside it do not change (counter-based draws).
inline constexpr std::int64_t kTruthEscapeLookahead = 16;

/// truth_simulate over steps + kTruthEscapeLookahead steps, then cut back to `steps`; given signals (which end at
/// the horizon) are continued by zeros for the look. *escaped_at: the first step (within the look-ahead too) at
/// which it ran away by truth_escape_step, or -1.
TruthRun truth_simulate_checked(const RunConfig& cfg, const Scenario& sc, std::uint64_t run, std::int64_t steps,
                                const double* bound, std::int64_t* escaped_at, const Signals* given = nullptr);

/// The first step k whose state x(t_k) is not finite or beyond bound [n] (nullptr: no bound), or whose measurement
/// y(t_k) is not finite (a model that escapes under its noise, e.g. the Henon map from the edge of its basin); -1
/// when the run stays.
std::int64_t truth_escape_step(const TruthRun& run, int n, int m, const double* bound);

/// What a user reads when every run escapes: "the truth of every one of the R <what> ran away (the
/// first at t = T s): ..." with what to change (for a continuous-time system also a shorter dt: forward Euler).
std::string truth_escape_refusal(const RunConfig& cfg, std::int64_t runs, const std::string& what, double first);

/// Why some truth runs ran away, for train's, compare's and operate's notes: "the system escapes under its [online]
/// noise", and for a continuous-time system also that forward Euler's step may be too long for the dynamics where the
/// noise took the run (Lorenz-96 at dt = 0.01 s: 1 of 20 runs ran away, none at 0.005 s; docs/compare.md).
std::string truth_escape_cause(const RunConfig& cfg);

/// What EKF/UKF/PF are told under a scenario: the [baseline] model and statistics (default: the truth's) with
/// variances scaled by the scenario's told factors.
FilterModel scenario_told_model(const RunConfig& cfg, const Scenario& sc);

}  // namespace hinf
