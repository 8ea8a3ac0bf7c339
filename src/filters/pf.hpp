// The bootstrap particle filter on the discrete model of filter.hpp, told the noise statistics in FilterModel.
// Not the Kalman filters (ekf.hpp, ukf.hpp).
#pragma once
#include <cstdint>
#include <memory>

#include "filters/filter.hpp"

namespace hinf {

/// Bootstrap particle filter: log-weights, systematic resampling when ESS < ess_fraction * particles;
/// roughening K > 0 jitters the resampled particles by K E_i N^(-1/n) N(0,1) per state (E_i: the cloud's
/// range; Gordon, Salmond & Smith 1993), against sample impoverishment. K = 0: the plain bootstrap filter.
/// Resampling when ESS < ess_fraction x particles (1: every step): systematic (one uniform offset) or, with
/// `stratified`, one uniform per stratum (Kitagawa 1996; the toolbox's bootstrap PF).
std::unique_ptr<OnlineFilter> make_particle_filter(const FilterModel& model, std::int64_t particles,
                                                   double ess_fraction = 0.5, double roughening = 0.0,
                                                   bool stratified = false);

}  // namespace hinf
