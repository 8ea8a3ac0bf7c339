// The on-line phase (seed 000 Fig. 3, Section IV): the frozen network drives the filter while the
// true system runs with real disturbance and noise; attenuation ratios and error statistics.
#pragma once
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "filters/filter.hpp"
#include "net/network.hpp"
#include "config/run_config.hpp"

namespace hinf {

struct OperateOptions {
    std::string out_dir = "runs/out/operate";
    std::string mode;       // "oracle" | "measured"; empty: the config's [online] mode
    std::int64_t runs = 0;  // 0: the config's [online] runs
    double until = -1;      // < 0: t_final
    bool quiet = false;
};

struct OperateSummary {
    std::string mode;
    std::int64_t runs = 0;
    double attenuation_ratio = 0;            // mean over runs of int x~^TQx~ / int (v^Tv + n^Tn)
    double attenuation_ratio_open_loop = 0;  // same noise, gain set to zero (the open-loop predictor)
    double attenuation_ratio_minus_v0 = 0;   // (int x~^TQx~ - V(x~(0))) / int (...)   (NaN if V undefined)
    double v0 = 0;                           // V(x~(0))
    std::vector<double> error_mean, error_std;  // per state, time average over [0, T], mean over runs
    std::vector<double> error_mean_settled, error_std_settled;  // over t >= settle_time
    std::vector<double> error_mean_open_loop, error_std_open_loop;
    // [runs x n] each run's mean square error per state over t >= settle_time (over [0, T] when no step is settled);
    // +inf in every state of a diverged run, NaN in a run whose truth escaped. The checkpoint selection pairs
    // validations run by run with it.
    std::vector<double> run_mse_settled;
    double rmse_position = 0, rmse_position_open_loop = 0;
    double online_check_violation_fraction = NAN;  // variant gain: share of sampled errors at x^ violating (14.1)
    double online_hji_violation_fraction = 0;  // share of on-line steps where HJIE(p(x~), x, x^) > 0.01 S
    // per network given: an ensemble's mean gain against each member's storage; the two figures above are those of
    // member online_check_network, the one with the smallest sampled violation share (0 for one network)
    std::vector<double> online_check_violation_fraction_per_network, online_hji_violation_fraction_per_network;
    int online_check_network = 0;
    std::int64_t diverged_runs = 0;        // runs whose estimate became non-finite (ratio = inf)
    double first_divergence = -1;          // earliest divergence time [s], -1 if none
    // runs whose true state or measurement ran away (sim/truth.hpp: the model escaped under its noise): they count
    // for no figure (their run_mse_settled and per-run ratios are NaN); the earliest time one did (-1: none)
    std::int64_t truth_escaped_runs = 0;
    double first_truth_escape = -1;
    double wall_seconds = 0;
    // on-line retraining ([online] retrain, docs/method.md section 16.6)
    bool retrain = false;
    double retrain_triggers = 0, retrain_adam_steps = 0, retrain_rejected = 0;  // totals over runs
    double retrain_eps_before = NAN, retrain_eps_after = NAN;  // mean over triggers of max_j H_j/S_j before/after
    std::string online_checkpoint;  // run 0's final on-line network ("" when not written)
    RunNotes notes;  // the DNN filter's OnlineFilter::run_note() over the counted runs (method.md 16.10)
};

/// Runs the frozen network of `network` on the system of `cfg`; writes out_dir/operate.h5.
OperateSummary operate_run(const RunConfig& cfg, FrozenNetwork& network, const std::string& network_path,
                           const OperateOptions& opt);
/// The same for an ensemble of gain networks (two or more, checked to be one model by the caller:
/// load_gain_ensemble): the filter runs their mean gain (docs/method.md 16.15), the on-line check tests it against
/// each member's storage; V(x~(0)) is undefined (no common storage), and online.retrain is refused.
OperateSummary operate_run(const RunConfig& cfg, const std::vector<FrozenNetwork*>& networks,
                           const std::vector<std::string>& network_paths, const OperateOptions& opt);

}  // namespace hinf
