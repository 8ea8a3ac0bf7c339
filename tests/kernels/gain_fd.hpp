// Central differences of the gain variant's minibatch loss against its analytic gradient, shared by the kernel tests
// of both gain heads (test_gain.cpp, test_gain_kalman.cpp): every third MLP parameter and every storage parameter.
#pragma once
#include <catch2/catch.hpp>
#include <cstdint>
#include <vector>

#include "gain.hpp"

namespace hinf::test {

/// CHECKs grad[k] against (L(theta + h e_k) - L(theta - h e_k)) / 2h, h = 1e-6, and returns how many were checked.
inline int check_gain_gradient_fd(const std::vector<double>& grad, const std::vector<double>& theta,
                                  const kern::HjieSystemView& view, const double* z, const std::int64_t* idx, int M,
                                  const kern::StepConfig& sc) {
    const double h = 1e-6;
    const std::int64_t P = std::int64_t(theta.size());
    std::vector<double> scratch(theta.size());
    int checked = 0;
    for (std::int64_t k = 0; k < P; k += (k < sc.shape.param_count() ? 3 : 1)) {
        std::vector<double> tp = theta, tm = theta;
        tp[k] += h;
        tm[k] -= h;
        kern::StepWorkspace<double> w2;
        const double lp = kern::gain_step_gradient(scratch.data(), tp.data(), view, z, idx, M, sc, w2).loss;
        const double lm = kern::gain_step_gradient(scratch.data(), tm.data(), view, z, idx, M, sc, w2).loss;
        INFO("parameter " << k);
        CHECK(grad[k] == Approx((lp - lm) / (2 * h)).epsilon(1e-5).margin(1e-8));
        ++checked;
    }
    return checked;
}

}  // namespace hinf::test
