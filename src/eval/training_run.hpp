// A training run from its first step to its verdict, once for `hinf train`/`resume` and the library's (and Python's)
// train/resume: the selection of the best validated checkpoint, the trainer, the second runs a config may call for
// (another storage or game kept in DIR, the other in DIR/alternative), and the acceptance check. What each caller
// does with the results (print them, or fill a report) comes through the hooks.
#pragma once
#include <functional>
#include <memory>
#include <string>

#include "config/run_config.hpp"
#include "eval/acceptance.hpp"
#include "train/trainer.hpp"

namespace hinf {

/// What the caller sees as the run goes; each may be empty.
struct TrainingRunHooks {
    // after the selection started, just before the trainer (the CLI installs its Ctrl-C handlers there)
    std::function<void()> before_training;
    // a run trained to its end and the one kept: its config, summary and selection (null where none runs). Called
    // once, and once more with again = true where choose_storage_far_behind kept another storage's run
    std::function<void(const RunConfig& cfg, const TrainSummary& s, const Selection* best, bool again)> trained;
    // each acceptance check's outcome (ran = false where none ran), after the matching `trained`
    std::function<void(const AcceptanceOutcome& a)> checked;
};

/// The run as it ended.
struct TrainingRun {
    RunConfig cfg;          // the kept run's config (keys changed on resume included)
    TrainSummary summary;   // status != 0: it stopped (4 diverged, 128 + signal interrupted), and nothing after ran
    std::shared_ptr<Selection> best;  // the kept run's selection (null where none ran)
    AcceptanceOutcome acceptance;     // the kept run's check (ran = false where none ran)
};

/// A fresh run of cfg in opt.out_dir; first, where opt.config_notes, the note naming the states the outputs do not see
/// (eval/observability.hpp), on stderr. The caller holds that directory's lock (RunDirLock) and has refused one that
/// holds a run unless told to start afresh (the two callers say how to continue in their own words).
TrainingRun training_run_fresh(RunConfig cfg, TrainOptions opt, const TrainingRunHooks& hooks);

/// The run of `checkpoint` (DIR/checkpoint.h5) continued with opt (opt.sets: keys changed on resume). Finishes an
/// exchange of two runs a kill interrupted in DIR first, and holds DIR's lock (named `command`) to the end where the
/// checkpoint can be read; a checkpoint that cannot be read is the trainer's to report (with its hint about
/// checkpoint.prev.h5).
TrainingRun training_run_resume(const std::string& checkpoint, TrainOptions opt, const std::string& command,
                                const TrainingRunHooks& hooks);

}  // namespace hinf
