// The unscented Kalman filter on the discrete model of filter.hpp, told the noise statistics in FilterModel.
// Not the EKF (ekf.hpp) nor the particle filter (pf.hpp).
#pragma once
#include <memory>

#include "filters/filter.hpp"

namespace hinf {

/// Unscented Kalman filter (Julier & Uhlmann 1997; Wan & van der Merwe 2000): additive noise, scaled sigma points
/// with alpha = 1, beta = 2, kappa = 0.
/// Scaled sigma points (Wan & van der Merwe 2000): lambda = alpha^2 (n + kappa) - n, beta for the centre's
/// covariance weight; the default (1, 2, 0) has no negative weight. Särkkä's EKF/UKF toolbox uses (1, 0, 3 - n).
std::unique_ptr<OnlineFilter> make_ukf(const FilterModel& model, double alpha = 1.0, double beta = 2.0,
                                       double kappa = 0.0);

}  // namespace hinf
