// On-line checking and retraining of the `gain` variant (issue 14 item 2, seed 000 Fig. 3: "when |eps| > delta,
// train on-line"; docs/method.md section 16.6): a gain filter x^' = A(x^) + K(x^)(y - C(x^)) that checks the
// dissipation inequality (14.1) at its own estimate every step and, when the check's violation exceeds delta, runs
// a bounded number of Adam steps on errors drawn around the current x^ with the training's kernels
// (kern::gain_step_gradient + kern::adam_update), then goes on with the updated network. Not the check's reporting
// (eval/operate.cpp) and not the offline training (trainer.cpp).
//
// Shape legend: n = states, m = outputs, P = network parameters (MLP + storage).
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "filters/filter.hpp"
#include "io/checkpoint.hpp"
#include "train/gain_samples.hpp"

namespace hinf {

/// Errors the on-line check draws per step (the check of `hinf operate`, docs/method.md section 16.5).
constexpr std::int64_t kOnlineCheckErrors = 16;

/// Philox counters (stream RNG_STREAM_GAIN) of the on-line check and of the retraining samples at (run, step).
/// Training uses a = time step (< 2^30: configs allow at most 1e9 steps); the check 2^40 + run 2^24 + step; the
/// retraining 2^62 + run 2^32 + step, above both for every run < 2^30 and step < 2^30.
inline std::uint64_t online_check_counter(std::uint64_t run, std::int64_t step) {
    return (std::uint64_t(1) << 40) + (run << 24) + std::uint64_t(step);
}
inline std::uint64_t online_retrain_counter(std::uint64_t run, std::int64_t step) {
    return (std::uint64_t(1) << 62) + (run << 32) + std::uint64_t(step);
}

/// What a retraining filter counts over one run (OnlineFilter::run_report, in this order).
struct OnlineRetrainCounts {
    double check_violations = 0;  // sampled errors with H > 0.01 S (the check's share, as operate reports it)
    double check_samples = 0;     // sampled errors checked (kOnlineCheckErrors per step)
    double triggers = 0;          // steps whose violation eps = max_j H_j/S_j exceeded delta
    double adam_steps = 0;        // Adam steps taken (retrain_steps per trigger)
    double rejected = 0;          // triggers whose update was not finite and was undone
    double eps_before = 0;        // sum over triggers of eps before the Adam steps
    double eps_after = 0;         // sum over triggers of eps after them (the same check errors, the updated network)
    std::vector<double> to_vector() const;
    static OnlineRetrainCounts from_vector(const std::vector<double>& v);  // zeros for an empty vector
};

/// The retraining settings of a config ([online] retrain_*), the Adam constants of [training], and the learning rate
/// (retrain_learning_rate, else the checkpoint's final training rate: its config's rate times its roll-back scale).
struct OnlineRetrainSettings {
    bool retrain = true;
    double delta = 0.05;
    std::int64_t steps = 5, samples = 64;
    double learning_rate = 1e-3, beta1 = 0.9, beta2 = 0.999, tau = 1e-7;
    bool reset_adam = true;  // as training: the moments restart at every trigger (training.reset_adam_each_step)
};
OnlineRetrainSettings online_retrain_settings(const RunConfig& cfg, const std::string& checkpoint_path);

/// The violation of (14.1) the trigger compares with delta: eps = max over the check's errors of H_j / S_j
/// (in [-1, 1]; 0 where S_j = 0), for gains K [n x m], storage S and its rate Sdot [n x n] (null: constant);
/// *violations += count of H_j > 0.01 S_j. discrete: the one-step inequality (16.8.1) instead of (14.1).
double online_check_violation(const GainSamples& check, const double* K, const double* S, const double* Sdot, double rho,
                              bool discrete, double* violations);

/// The filter, for the network of `checkpoint` (variant gain) with its Adam state; cfg is operate's config (system,
/// Q, rho, training seed of the check's draws). Each clone() owns its network and Adam state; reset() restores the
/// checkpoint's, so runs never share what one of them learned. The run index of reset() and FilterInput::step key
/// the draws: a run gives the same bits whatever thread or process computes it.
std::unique_ptr<OnlineFilter> make_retrain_gain_filter(const FilterModel& model, const RunConfig& cfg,
                                                       const std::string& checkpoint_path,
                                                       const OnlineRetrainSettings& settings, const std::string& name);

/// The filter's current state as a checkpoint (its network and Adam moments; state.step = the next step index, one
/// past the last FilterInput::step it took; state.xhat = its estimate, state.x = x^ too: an on-line run has no true state to
/// keep), written atomically with the source checkpoint's config. `hinf operate --network PATH` then starts from the
/// retrained weights; make_retrain_gain_filter(PATH), reset to the file's x^ and the same run and stepped on from
/// state.step, continues the run bit for bit (tests/train/test_online_retrain.cpp).
void online_retrain_write(const OnlineFilter& filter, const std::string& path);

}  // namespace hinf
