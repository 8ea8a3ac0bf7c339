// The extended Kalman filter on the discrete model of filter.hpp (the step the truth is simulated with), told
// the noise statistics in FilterModel. Not the UKF (ukf.hpp) nor the particle filter (pf.hpp).
#pragma once
#include <memory>

#include "filters/filter.hpp"

namespace hinf {

/// Extended Kalman filter (Jazwinski 1970; discrete-time form, Simon, Optimal State Estimation, 13.2), with the
/// system's exact Jacobians and the Joseph-form covariance update.
std::unique_ptr<OnlineFilter> make_ekf(const FilterModel& model);

}  // namespace hinf
