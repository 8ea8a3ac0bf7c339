// The step every part of hinf advances a system with (truth, filters, training): one definition, so a change of
// the time discretisation (e.g. discrete-time systems) is made here once. Not the systems themselves.
#include <vector>

#include "models/system.hpp"

namespace hinf {

void system_advance(const System& sys, double* x_next, const double* x, const double* v, double t, double dt,
                    std::int64_t count) {
    const int n = sys.state_dim(), nv = sys.disturbance_dim();
    std::vector<double> a(static_cast<std::size_t>(count) * n);
    sys.drift(a.data(), x, t, count);
    if (v == nullptr) {
        for (std::int64_t i = 0; i < count * n; ++i) x_next[i] = x[i] + dt * a[i];
        return;
    }
    std::vector<double> B(static_cast<std::size_t>(count) * n * nv);
    sys.disturbance_gain(B.data(), x, t, count);
    for (std::int64_t p = 0; p < count; ++p)
        for (int i = 0; i < n; ++i) {
            double bv = 0;
            for (int j = 0; j < nv; ++j) bv += B[(p * n + i) * nv + j] * v[p * nv + j];
            x_next[p * n + i] = x[p * n + i] + dt * (a[p * n + i] + bv);
        }
}

void system_advance_jacobian(const System& sys, double* F, double* G, const double* x, double t, double dt) {
    const int n = sys.state_dim(), nv = sys.disturbance_dim();
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
