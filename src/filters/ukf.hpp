// The unscented Kalman filter on the discrete model of filter.hpp, told the noise statistics in FilterModel.
// Not the EKF (ekf.hpp) nor the particle filter (pf.hpp).
#pragma once
#include <memory>

#include "filters/filter.hpp"

namespace hinf {

/// Unscented Kalman filter (Julier & Uhlmann 1997; Wan & van der Merwe 2000): additive noise, scaled sigma points
/// with alpha = 1, beta = 2, kappa = 0.
std::unique_ptr<OnlineFilter> make_ukf(const FilterModel& model);

}  // namespace hinf
