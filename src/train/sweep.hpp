// A sweep (issue 16): one config trained for several values of one key (seeds, learning rates...) as one job.
// Under mpirun the processes form min(values, processes) groups; group g trains values g, g + groups, ...
// (each training data-parallel over its group), each in its own directory with its own checkpoints. Run again
// after a kill, it skips finished values and resumes the others from their checkpoints.
// Not the training itself (trainer.hpp), not what is checked around it (SweepOptions::around: the caller's, e.g.
// the CLI's checkpoint selection and acceptance check of src/eval) and not the printing (cli/train_cmd.cpp).
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "train/trainer.hpp"

namespace hinf {

/// What a value's training ended with beyond the trainer's summary, for choosing between the values: the checkpoint
/// the selection kept and its validation score, and the acceptance check's verdict (filled in by SweepOptions::around).
struct SweepVerdict {
    std::int64_t best_step = -1;   // the step of DIR/best.h5 (-1: no selection ran, or none kept)
    double select_score = NAN;     // its settled Q-weighted MSE on the validation noise (training.select_runs runs)
    std::string acceptance = "-";  // "pass", "fail", or "-" (no check ran)
    double rmse_position = NAN;    // the acceptance Monte Carlo's position RMSE ([online] noise)
    double worst_ratio = NAN;      // the largest attenuation ratio the acceptance search found (NaN: none ran)
    // the acceptance Monte Carlo's runs against the EKF: the DNN filter's and the EKF's position RMSE after
    // settle_time (AcceptanceOutcome::rmse_position_settled, _ekf)
    double rmse_settled = NAN, rmse_settled_ekf = NAN;
    // the same over all states weighted by Q (AcceptanceOutcome::rms_q_settled, _ekf; NaN in a row written before)
    double rms_q_settled = NAN, rms_q_settled_ekf = NAN;
    // `hinf sweep --worst`: the value's level and the full worst-case search of its checkpoint (eval LevelSearch:
    // the DNN filter's, the EKF's and the UKF's largest ratio found; NaN where none ran), 1 where the DNN filter
    // diverged under its worst signals (0 where it did not, -1 where no search ran)
    double rho = NAN, search_ratio = NAN, search_ratio_ekf = NAN, search_ratio_ukf = NAN;
    int search_diverged = -1;
    /// "yes" where the search ran and found the DNN filter at or below its level without diverging, "no" where it
    /// found it above, "-" where none ran
    const char* keeps_level() const {
        if (search_diverged < 0 || std::isnan(search_ratio)) return "-";
        return search_diverged == 0 && search_ratio <= rho ? "yes" : "no";
    }
    /// The settled error over the EKF's: the larger of the position and the all-state ratio, as the acceptance's note
    /// keys on (the position ratio alone for a row without the all-state figures)
    double behind_ekf() const {
        const double p = rmse_settled / rmse_settled_ekf, q = rms_q_settled / rms_q_settled_ekf;
        return std::isnan(q) ? p : std::max(p, q);
    }
};

/// One value's training with the given options: a fresh start, or a resume from the value's own checkpoint.
using SweepTrain = std::function<TrainSummary(const TrainOptions&)>;

struct SweepOptions {
    std::string out_dir = "runs/out/sweep";
    std::string key;                  // a config key, e.g. training.seed
    std::vector<std::string> values;  // its values, one training each
    std::vector<std::string> sets;    // --set overrides common to all
    double until = -1;
    /// false: a line after each value (what it ended with, how many are done, the time left) and, with one process
    /// group (values trained one after another), each training's and check's own progress lines; true: none
    bool quiet = false;
    /// Trains each value in its process group in place of the training alone, with what the caller runs around it
    /// (the CLI: eval's training_run, as `hinf train` and `hinf resume`): given the value's config (its
    /// checkpoint's when resumed: DIR/checkpoint.h5, readable), directory and options, it trains (fresh, or resumed
    /// from DIR/checkpoint.h5), returns the summary in `s` and what it checked. Empty: the training alone.
    std::function<SweepVerdict(const RunConfig& cfg, const std::string& dir, bool resumed, TrainOptions options,
                               TrainSummary& s)> around;
};

struct SweepRow {
    std::string value, dir;
    std::string how;  // "trained", "resumed" (from a checkpoint), "done before" (an earlier job finished it)
    TrainSummary summary;
    SweepVerdict verdict;
};

/// Trains every value (see above); returns one row per value, in the order given, on every process. Writes
/// DIR/<key>=<value>/{checkpoint.h5, trajectory.h5, summary.csv} (and what `around` writes there, e.g. best.h5)
/// and DIR/sweep.csv.
std::vector<SweepRow> sweep_run(const std::string& config_path, const SweepOptions& opt);

/// "key=value" with characters that cannot be in a file name replaced by '_'.
std::string sweep_dir_name(const std::string& key, const std::string& value);

}  // namespace hinf
