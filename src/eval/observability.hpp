// What the outputs can tell a filter about each state: the EKF's covariance equation run along the noise-free
// trajectory from x0 (the estimate on it, so the Jacobians are the nominal run's), once with every measurement, told
// a thousandth of their noise, and once with none (the open-loop predictor's), with the nominal disturbance and the
// P0 of compare. A state whose error variance near-exact measurements leave where the open loop has it is one the
// outputs tell next to nothing about over the run (to first order: not observable from them, or its effect on them
// masked by the disturbance); where it also keeps growing, no filter can estimate it (docs/method.md section 16.18).
// Not a filter (filters/ekf.hpp is the one used).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "config/run_config.hpp"

namespace hinf {

struct StateInformation {
    bool ran = false;              // false: the covariance equation left the finite numbers (no verdict)
    std::int64_t steps = 0;        // the steps run (the config's whole run)
    // [n] per state over the run's second half: sum of the filtered error variance P_ii(k+1|k) under near-exact
    // measurements over the open-loop predictor's (1: the outputs tell nothing about it; NaN: the open loop's is 0
    // there, nothing to tell)
    std::vector<double> ratio;
    // [n] the filtered variance at the last step over its value at the run's half (> 1: still growing)
    std::vector<double> growth;
};

/// The measurement noise the covariance run is told, as a factor of the config's
inline constexpr double kSeenNoiseFactor = 1e-3;
/// A state counts as unseen from this ratio on: near-exact measurements take less than a tenth off its open-loop
/// variance
inline constexpr double kUnseenRatio = 0.9;
/// ... and as one no filter can estimate where, besides, its filtered variance grows by this factor over the run's
/// second half
inline constexpr double kUnseenGrowth = 1.5;

/// The two covariance runs above for cfg over its whole run (discrete or continuous time, the truth's own step).
StateInformation state_information(const RunConfig& cfg);

/// One line naming the unseen states, "hinf: note: ..." without a newline; "" where every state is seen.
std::string unseen_states_note(const RunConfig& cfg, const StateInformation& s);

}  // namespace hinf
