// Adam update (seed 000 eqs. (14)-(15)); see adam.hpp.
#include "adam.hpp"

#include <cmath>

namespace hinf::kern {

template <typename T>
void adam_update(T* theta, T* m, T* v, const T* g, std::int64_t count, std::int64_t k, const AdamParams& ap) {
    const T b1 = T(ap.beta1), b2 = T(ap.beta2);
    const T c1 = T(1.0 / (1.0 - std::pow(ap.beta1, double(k))));  // 1/(1 - lambda_1^k)
    const T c2 = T(1.0 / (1.0 - std::pow(ap.beta2, double(k))));  // 1/(1 - lambda_2^k)
    const T lr = T(ap.lr), tau = T(ap.tau);
#pragma omp parallel for schedule(static) if (count > 8192)
    for (std::int64_t i = 0; i < count; ++i) {
        m[i] = b1 * m[i] + (T(1) - b1) * g[i];
        v[i] = b2 * v[i] + (T(1) - b2) * g[i] * g[i];
        theta[i] -= lr * (m[i] * c1) / std::sqrt(v[i] * c2 + tau);
    }
}

template <typename T>
void adam_update_naive(T* theta, T* m, T* v, const T* g, std::int64_t count, std::int64_t k, const AdamParams& ap) {
    for (std::int64_t i = 0; i < count; ++i) {
        double mi = ap.beta1 * double(m[i]) + (1 - ap.beta1) * double(g[i]);
        double vi = ap.beta2 * double(v[i]) + (1 - ap.beta2) * double(g[i]) * double(g[i]);
        double mh = mi / (1 - std::pow(ap.beta1, double(k)));
        double vh = vi / (1 - std::pow(ap.beta2, double(k)));
        m[i] = T(mi);
        v[i] = T(vi);
        theta[i] = T(double(theta[i]) - ap.lr * mh / std::sqrt(vh + ap.tau));
    }
}

template void adam_update<float>(float*, float*, float*, const float*, std::int64_t, std::int64_t, const AdamParams&);
template void adam_update<double>(double*, double*, double*, const double*, std::int64_t, std::int64_t,
                                  const AdamParams&);
template void adam_update_naive<float>(float*, float*, float*, const float*, std::int64_t, std::int64_t,
                                       const AdamParams&);
template void adam_update_naive<double>(double*, double*, double*, const double*, std::int64_t, std::int64_t,
                                        const AdamParams&);

}  // namespace hinf::kern
