// See weighted_system.hpp.
#include "models/weighted_system.hpp"

#include <utility>

namespace hinf {

WeightedSystem::WeightedSystem(std::shared_ptr<const System> inner, std::vector<double> w, std::vector<double> u)
    : inner_(std::move(inner)), w_(std::move(w)), u_(std::move(u)) {}

void WeightedSystem::disturbance_gain(double* B, const double* x, double t, std::int64_t count) const {
    inner_->disturbance_gain(B, x, t, count);
    if (u_.empty()) return;
    const int n = state_dim(), nv = disturbance_dim();
    for (std::int64_t r = 0; r < count * n; ++r)
        for (int k = 0; k < nv; ++k) B[r * nv + k] *= u_[std::size_t(k)];
}

void WeightedSystem::measurement(double* c, const double* x, double t, std::int64_t count) const {
    inner_->measurement(c, x, t, count);
    if (w_.empty()) return;
    const int m = output_dim();
    for (std::int64_t p = 0; p < count; ++p)
        for (int j = 0; j < m; ++j) c[p * m + j] *= w_[std::size_t(j)];
}

void WeightedSystem::measurement_jacobian(double* H, const double* x, double t) const {
    inner_->measurement_jacobian(H, x, t);
    if (w_.empty()) return;
    const int m = output_dim(), n = state_dim();
    for (int j = 0; j < m; ++j)
        for (int k = 0; k < n; ++k) H[j * n + k] *= w_[std::size_t(j)];
}

}  // namespace hinf
