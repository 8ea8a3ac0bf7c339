// The open-loop predictor: the model's own step from the initial estimate, measurements ignored (gain zero).
// The floor every filter must beat. Not a filter with a covariance.
#pragma once
#include <memory>

#include "filters/filter.hpp"

namespace hinf {

/// x^_{k+1} = system_advance(x^_k, v = 0): measurements ignored.
std::unique_ptr<OnlineFilter> make_open_loop_filter(const FilterModel& model);

}  // namespace hinf
