// The offline phase (seed 000 Fig. 3; docs/architecture.md "One training time step"): the thin driver that chains
// time steps, writes the trajectory as it goes and a checkpoint every S steps.
#pragma once
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "config/run_config.hpp"

namespace hinf {

/// One finished time step, for a caller watching the run (the library's progress callback).
struct TrainStepInfo {
    std::int64_t step = 0, last_step = 0;  // time steps completed; where the run stops
    double t = 0;                          // simulated time reached [s]
    double loss_first = 0, loss_last = 0;  // before / after the step's Adam steps
    double rel_median = 0, violation = 0;  // the progress line's rel.resid and viol
};

struct TrainOptions {
    std::string out_dir = "runs/out/train";
    double until = -1;  // stop at this simulated time [s]; < 0: the config's t_final
    bool quiet = false;
    // the notes about the config itself (its default level, a constant state, samples across 0): off for a second
    // run of the same config (the constant-storage alternative), which would repeat them
    bool config_notes = true;
    // called after each time step (after its checkpoint); an exception thrown here ends the run with the
    // last checkpoint in place
    std::function<void(const TrainStepInfo&)> on_step;
    // a fresh run whose storage S(t) starts on the Riccati solution (network.storage_init = "riccati"): runs the
    // untrained network in the checkpoint at the given path as a filter on validation runs and returns how many of
    // them diverged (eval's selection_begin installs it; docs/method.md section 16.7, "A start that diverges").
    // Where some did, the flat start is validated too, and the run starts from it when it diverges in fewer
    std::function<std::int64_t(const RunConfig&, const std::string&)> start_diverged;
    // a fresh run that diverged from a Riccati start hinf chose (the config does not name network.storage_init) starts
    // again once from flat knots; this is called first, to forget what the diverged run validated (eval's
    // selection_begin installs it; no restart without it)
    std::function<void()> on_restart;
    std::vector<std::string> sets;  // resume only: "section.key=value" for the keys of kResumeKeys
};

/// The config keys `hinf resume --set` may change: they steer how the run continues, never what a checkpoint's
/// network, state or samples mean (the system, network shape, seed and sampling are fixed for a run).
inline const std::vector<std::string> kResumeKeys = {
    "training.learning_rate", "training.adam_steps",  "training.checkpoint_every", "training.loss_limit",
    "training.on_divergence", "training.rollback_factor", "training.max_rollbacks", "filter.t_final"};

struct TrainSummary {
    int status = 0;                 // 0 ok, 4 diverged (diagnostic already printed), 128 + signal: interrupted
    std::int64_t first_step = 0, last_step = 0;
    double wall_seconds = 0;
    double final_loss = 0;
    double median_rel_residual = 0;       // median over time steps of hjie_rel_residual_median
    double fraction_steps_rel_ok = 0;     // share of time steps with hjie_rel_residual_median <= 0.01
    double fraction_steps_violation_ok = 0;  // share with hji_violation_fraction <= 0.01
    double mean_cosine = 0;
    // mixed H2/H-infinity filter (seed 001) only
    bool mixed = false;
    double median_rel_residual2 = 0;           // as median_rel_residual, for the second residual (eq. (20))
    double fraction_steps_violation2_ok = 0;   // share with hji2_violation_fraction <= 0.01
    double max_consistency_gap = 0;            // largest consistency_gap over the run [state units]
    double max_consistency_gap_printed = 0;    // the same with eqs. (11) and (23) as printed
    // variant gain with knots: the first time step after which a knot's log-diagonal lay below
    // storage_runaway_level (a note says so when it happens; docs/method.md section 16.7), -1 if none did
    std::int64_t runaway_step = -1;
    int runaway_knot = -1, runaway_state = -1;
    double runaway_value = 0;
};

/// Asks a running training to stop at the next safe point (between time steps): it writes a checkpoint at the
/// current step, prints how to resume and returns status 128 + signal. Async-signal-safe (stores one flag): the
/// CLI calls it from its SIGINT/SIGTERM handler.
void train_request_stop(int signal);

/// The run's config with the storage's knots started flat instead of on the Riccati solution, recorded in its text,
/// at the margin the run trains with (a config naming the flat start would read the other default margin).
/// by_hinf: the switch is hinf's own (the start check, a start that diverged), and the keys the config as given left
/// unnamed are recorded as hinf's choice (RunConfig::chosen; a run resumed to t_final then decides as the same run
/// uninterrupted); false: they read as named (an alternative trained beside the run, kept as the user's choice).
RunConfig flat_start_config(const RunConfig& cfg, bool by_hinf);

/// Starts a run from the config (creates out_dir/trajectory.h5, out_dir/checkpoint.h5).
TrainSummary train_start(const RunConfig& cfg, const TrainOptions& opt);
/// Continues from a checkpoint into its directory (the trajectory is cut back to the checkpoint).
TrainSummary train_resume(const std::string& checkpoint, const TrainOptions& opt);

}  // namespace hinf
