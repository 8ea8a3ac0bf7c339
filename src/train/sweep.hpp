// A sweep (issue 16): one config trained for several values of one key (seeds, learning rates...) as one job.
// Under mpirun the processes form min(values, processes) groups; group g trains values g, g + groups, ...
// (each training data-parallel over its group), each in its own directory with its own checkpoints. Run again
// after a kill, it skips finished values and resumes the others from their checkpoints.
// Not the training itself (trainer.hpp) and not the printing (cli/train_cmd.cpp).
#pragma once
#include <string>
#include <vector>

#include "train/trainer.hpp"

namespace hinf {

struct SweepOptions {
    std::string out_dir = "runs/out/sweep";
    std::string key;                  // a config key, e.g. training.seed
    std::vector<std::string> values;  // its values, one training each
    std::vector<std::string> sets;    // --set overrides common to all
    double until = -1;
};

struct SweepRow {
    std::string value, dir;
    std::string how;  // "trained", "resumed" (from a checkpoint), "done before" (an earlier job finished it)
    TrainSummary summary;
};

/// Trains every value (see above); returns one row per value, in the order given, on every process. Writes
/// DIR/<key>=<value>/{checkpoint.h5, trajectory.h5, summary.csv} and DIR/sweep.csv.
std::vector<SweepRow> sweep_run(const std::string& config_path, const SweepOptions& opt);

/// "key=value" with characters that cannot be in a file name replaced by '_'.
std::string sweep_dir_name(const std::string& key, const std::string& value);

}  // namespace hinf
