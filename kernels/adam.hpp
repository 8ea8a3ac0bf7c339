// Adam exactly as seed 000 eqs. (14)-(15): tau inside the square root, bias correction by the step k
// counted from 1. Elementwise, so the result does not depend on the thread count.
#pragma once
#include <cstdint>

namespace hinf::kern {

struct AdamParams {
    double lr = 1e-3;     // l
    double beta1 = 0.9;   // lambda_1
    double beta2 = 0.999; // lambda_2
    double tau = 1e-7;    // tau
};

/// theta [count] -= l * m^_k / sqrt(v^_k + tau); m, v [count] are the moving averages (updated);
/// g [count] the gradient; k >= 1.
template <typename T>
void adam_update(T* theta, T* m, T* v, const T* g, std::int64_t count, std::int64_t k, const AdamParams& ap);

/// Naive twin (serial, double arithmetic) for tests.
template <typename T>
void adam_update_naive(T* theta, T* m, T* v, const T* g, std::int64_t count, std::int64_t k, const AdamParams& ap);

}  // namespace hinf::kern
