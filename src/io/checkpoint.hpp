// Checkpoint files: everything needed to continue a run bit-identically (network, Adam moments,
// time step, x, x^, the config text, the seed, the standardisation constants), written to a
// temporary name and renamed into place. Layout: docs/formats.md.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "net/network.hpp"

namespace hinf {

constexpr std::int64_t kCheckpointFormatVersion = 1;

struct TrainState {
    std::int64_t step = 0;          // time steps completed; the next one is at t = step * dt
    std::vector<double> x, xhat;    // true state and estimate at t = step * dt
    std::int64_t adam_step = 0;     // Adam steps taken in the current sequence (k of eq. (15))
    double learning_rate_scale = 1;  // < 1 after a divergence roll-back (training.on_divergence = "rollback")
};

template <typename T>
struct Checkpoint {
    Network<T> net;
    std::vector<T> adam_m, adam_v;
    TrainState state;
    std::string config_text;
};

/// "" when every weight, Adam moment, state and estimate is finite, else the first that is not ("network
/// weight[12] = nan"). ckpt_write refuses such a checkpoint and ckpt_read rejects one.
template <typename T>
std::string ckpt_non_finite(const Checkpoint<T>& ck);

/// Writes path atomically: path.tmp is written, flushed, fsynced, closed and read back; only then
/// is the old file renamed to `<path minus .h5>.prev.h5` and path.tmp renamed to path.
template <typename T>
void ckpt_write(const std::string& path, const Checkpoint<T>& ck, const RunConfig& cfg);

/// The precision ("float"/"double") a checkpoint was written with; checks it is a hinf checkpoint.
std::string ckpt_precision(const std::string& path);

/// Reads a checkpoint; checks format version, shapes and the config hash.
template <typename T>
Checkpoint<T> ckpt_read(const std::string& path);

/// `<path minus .h5>.prev.h5`: the checkpoint before the last one, kept by ckpt_write.
std::string ckpt_prev_name(const std::string& path);

/// Reads the whole checkpoint and throws one line naming the file and the problem if it is damaged,
/// of another format version, or its config does not match its hash; suggests the previous
/// checkpoint when that one reads back cleanly.
void ckpt_verify(const std::string& path);

/// Loads the config stored in a checkpoint, as it was trained: with ckpt_as_trained's settings applied.
RunConfig ckpt_config(const std::string& path);

/// The settings an older checkpoint's config leaves to defaults that have changed since it was written, in the values
/// it was trained with ("section.key=value"); empty for a file of this hinf. Resume records them in the config.
std::vector<std::string> ckpt_as_trained(const std::string& path);

/// Loads just the network, frozen, whatever its precision.
std::unique_ptr<FrozenNetwork> ckpt_frozen_network(const std::string& path, RunConfig* cfg_out = nullptr);

}  // namespace hinf
