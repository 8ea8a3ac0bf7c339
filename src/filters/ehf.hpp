// The extended H-infinity filter of hinf's own game, on the discrete model of filter.hpp: the classical robust
// baseline beside the EKF (ekf.hpp), with the game's weights instead of noise statistics. Not the DNN filter.
#pragma once
#include <cstdint>
#include <memory>
#include <vector>

#include "filters/filter.hpp"

namespace hinf {

/// The a priori H-infinity filter (Simon, Optimal State Estimation, 2006, 11.3) of the game
///   sum_k x~_k' Q x~_k tau  <=  rho sum_k (|v_k|^2 + |n_k|^2) tau   (tau = dt in continuous time, 1 in discrete),
/// x~_k = x_k - x^_k the prediction's error, applied to the nonlinear model as the EKF is (the Jacobians at the
/// estimate; docs/compare.md "The extended H-infinity filter"). Per step, with L L' = P:
///   P+ = L (I + tau L'(H'H - Q / rho) L)^-1 L',   x^+ = x^ + tau P+ H' (y - C(x^)),
///   x^_{k+1} = step(x^+),   P_{k+1} = F P+ F' + G G' / tau   (F, G the step's Jacobians at x^+).
/// P_0 = P0, the EKF's: at rho -> infinity the filter is the EKF of a system in units of its noise started from
/// tau P0, since the game's weights are the unit statistics over tau (docs/compare.md, "The extended H-infinity
/// filter").
/// Where I + tau L'(H'H - Q / rho) L is not positive definite (no filter of level rho along this estimate) the
/// step drops the -Q / rho term (a Kalman step with the game's unit weights) and counts it: level_steps_held().
/// Q [n x n] row-major, rho > 0.
std::unique_ptr<OnlineFilter> make_ehf(const FilterModel& model, const std::vector<double>& Q, double rho);
/// The steps since reset() where the level failed (above); -1 for a filter that is not an ehf.
std::int64_t ehf_level_steps_held(const OnlineFilter& f);

}  // namespace hinf
