// One time step's training data: N errors around x~(t) and their per-sample constants
// dA_i, B_i, dC_i, x~_i^T Q x~_i (docs/architecture.md: computed once per time step, independent of the weights).
#pragma once
#include <cstdint>
#include <vector>

#include "hjie.hpp"
#include "config/run_config.hpp"

namespace hinf {

struct TimeStepSamples {
    std::vector<double> xt, dA, Bm, dC, q, xs;  // [N x n], [N x n], [N x n x nv], [N x m], [N], scratch [N x n]
    std::vector<double> a_hat, c_hat;           // A(x^), C(x^)
    kern::HjieSystemView view() const;
    int n = 0, nv = 0, m = 0;
};

/// Fills s for the time step `step` at x, x^ (samples from Philox (seed, step): resume-exact).
void samples_build(TimeStepSamples* s, const RunConfig& cfg, const std::vector<double>& x,
                   const std::vector<double>& xhat, std::int64_t step);

}  // namespace hinf
