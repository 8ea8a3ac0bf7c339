// The step every part of hinf advances a system with (truth, filters, training): one definition, and the one
// place where continuous time (forward Euler) and discrete time (the map itself) differ. Not the systems themselves.
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "models/system.hpp"

namespace hinf {

double wrap_angle(double x) { return std::remainder(x, 2.0 * M_PI); }

const std::vector<int>& System::angle_outputs() const {
    static const std::vector<int> none;
    return none;
}

namespace {
// d [count x dim] = a - b, the listed components wrapped into [-pi, pi] (d may alias a or b)
void wrapped_difference(double* d, const double* a, const double* b, std::int64_t count, int dim,
                        const std::vector<int>& angles) {
    for (std::int64_t k = 0; k < count * dim; ++k) d[k] = a[k] - b[k];
    for (int j : angles)
        for (std::int64_t p = 0; p < count; ++p) d[p * dim + j] = wrap_angle(d[p * dim + j]);
}
}  // namespace

void System::output_difference(double* r, const double* y, const double* c, std::int64_t count) const {
    wrapped_difference(r, y, c, count, output_dim(), angle_outputs());
}

const std::vector<int>& System::angle_states() const {
    static const std::vector<int> none;
    return none;
}

std::pair<double, double> System::time_span() const {
    return {-std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
}

void System::state_difference(double* d, const double* a, const double* b, std::int64_t count) const {
    wrapped_difference(d, a, b, count, state_dim(), angle_states());
}

void system_advance(const System& sys, double* x_next, const double* x, const double* v, double t, double dt,
                    std::int64_t count) {
    const int n = sys.state_dim(), nv = sys.disturbance_dim();
    const bool discrete = sys.discrete_time();
    std::vector<double> a(static_cast<std::size_t>(count) * n);
    sys.drift(a.data(), x, t, count);
    if (v == nullptr) {
        if (discrete) std::copy(a.begin(), a.end(), x_next);
        else
            for (std::int64_t i = 0; i < count * n; ++i) x_next[i] = x[i] + dt * a[i];
        return;
    }
    std::vector<double> B(static_cast<std::size_t>(count) * n * nv);
    sys.disturbance_gain(B.data(), x, t, count);
    for (std::int64_t p = 0; p < count; ++p)
        for (int i = 0; i < n; ++i) {
            double bv = 0;
            for (int j = 0; j < nv; ++j) bv += B[(p * n + i) * nv + j] * v[p * nv + j];
            x_next[p * n + i] = discrete ? a[p * n + i] + bv : x[p * n + i] + dt * (a[p * n + i] + bv);
        }
}

void system_advance_jacobian(const System& sys, double* F, double* G, const double* x, double t, double dt) {
    const int n = sys.state_dim(), nv = sys.disturbance_dim();
    if (sys.discrete_time()) {
        if (F != nullptr) sys.drift_jacobian(F, x, t);
        if (G != nullptr) sys.disturbance_gain(G, x, t, 1);
        return;
    }
    if (F != nullptr) {
        sys.drift_jacobian(F, x, t);
        for (int i = 0; i < n * n; ++i) F[i] *= dt;
        for (int i = 0; i < n; ++i) F[i * n + i] += 1.0;
    }
    if (G != nullptr) {
        sys.disturbance_gain(G, x, t, 1);
        for (int i = 0; i < n * nv; ++i) G[i] *= dt;
    }
}

}  // namespace hinf
