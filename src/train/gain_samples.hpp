// Training data of the `gain` variant (issue 14, docs/method.md section 14.3): estimates x^ along many simulated
// truth runs (the one truth simulator) and errors x~ over the region the filter meets, with their per-sample
// constants. Not the loss (kernels/gain.hpp) and not the time-step loop (trainer.cpp).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "config/run_config.hpp"
#include "hjie.hpp"
#include "sim/truth.hpp"
#include "train_step.hpp"

namespace hinf {

/// cfg.trajectories truth runs over [0, t_final] with the [online] noise, keyed by the training seed (never the
/// on-line seed: the filter is not trained on the runs it is measured on). A run whose state or measurement leaves
/// the finite numbers (a model that escapes under its noise, e.g. the Henon map) is left out: training draws from
/// the runs that stay finite; `escaped` counts those left out and `first_escape` is the earliest time one did (-1:
/// none). Throws when every run escapes.
struct GainPool {
    std::vector<TruthRun> runs;
    std::int64_t steps = 0;
    std::int64_t escaped = 0;
    double first_escape = -1;
};
GainPool gain_pool_build(const RunConfig& cfg);

/// One line for the user when some of the pool's runs were left out ("" when none was).
std::string gain_pool_note(const RunConfig& cfg, const GainPool& pool);

struct GainSamples {
    int n = 0, nv = 0, m = 0;
    std::vector<double> xt, dA, Bm, dC, q, z, xhat, x, t;  // [N x n] ... z [N x D0]: the network's input at x^
                                                            // (GainSpec::input_row, D0 = input_count(n))
    std::vector<double> Hx;  // [N x m x n] output Jacobian at x^ (the Riccati- and Kalman-form heads only)
    std::vector<double> Fx;  // [N x n x n] the map's Jacobian at x^ (the Kalman-form head only)
    kern::HjieSystemView view() const;
};

/// N samples for time step `step` (Philox (seed, RNG_STREAM_GAIN, a, 0/1)): run r and time index k uniform,
/// x = pool run r at k, x~_j = 10^(-D u) dx_j xi_j (u ~ U(0,1), xi ~ N(0,1), D = sampling.radius_decades),
/// x^ = x - x~. `a` is the counter (the time step; the on-line check uses its own range). With g.group = G > 1 the
/// samples come in groups of G around one estimate: the group's first sample is drawn as above, the others keep its
/// x^ and t and take x = x^ + x~ with their own x~ (N a multiple of G).
void gain_samples_build(GainSamples* s, const RunConfig& cfg, const GainPool& pool, const kern::GainSpec& g,
                        std::int64_t N, std::uint64_t a);

/// The box where the filter holds its network's input (network.input_box = q > 0, docs/method.md section 16.10):
/// kInputBoxEstimates estimates drawn as training draws its groups' first samples (counter kInputBoxCounter), and per
/// state the q and 1 - q quantiles of their z, into g->zlo, g->zhi. q = 0 leaves them empty (not held).
inline constexpr std::int64_t kInputBoxEstimates = 20000;
inline constexpr std::uint64_t kInputBoxCounter = std::uint64_t(1) << 63;
void gain_input_box(kern::GainSpec* g, const RunConfig& cfg, const GainPool& pool);

/// A state that stays on one side of 0 on every training truth run (x >= 0 with some x > 0: positive; or the
/// mirror) while a share >= kSignCrossingShare of the estimates training samples around the runs (drawn as the
/// input box draws them) lies on the other side: where a model means nothing there (a concentration, a level), the
/// user's [sampling] state_bounds should hold the samples. None when the config sets state_bounds.
struct SignCrossing {
    int state = 0;
    bool positive = true;  // the runs keep x >= 0 (else x <= 0)
    double share = 0;      // of the sampled estimates on the other side
};
inline constexpr double kSignCrossingShare = 0.01;
std::vector<SignCrossing> gain_sign_crossings(const RunConfig& cfg, const GainPool& pool, const kern::GainSpec& g);

/// One line naming the crossings and the state_bounds line that holds them ("" for none).
std::string gain_sign_note(const RunConfig& cfg, const std::vector<SignCrossing>& crossings);

/// The same for errors around one known estimate x^ (on-line check and retraining): x = x^ + x~, at time t. Their
/// network input z is the filter's, held in g's box (GainSpec::input); training's is as drawn.
void gain_samples_at(GainSamples* s, const RunConfig& cfg, const kern::GainSpec& g, const double* xhat, double t,
                     std::int64_t N, std::uint64_t a);

}  // namespace hinf
