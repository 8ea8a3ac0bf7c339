// Ballistic missile / radar model of seed 000 eqs. (21)-(25), batched, with analytic Jacobians.
#include "models/missile.hpp"

#include <cmath>
#include <cstring>

namespace hinf {

double MissileSystem::density(double z, double* d_dz) const {
    const bool high = z >= p_.switch_altitude;
    const double r0 = high ? p_.rho_high : p_.rho_low, al = high ? p_.alpha_high : p_.alpha_low;
    const double r = r0 * std::exp(-al * z);
    if (d_dz) *d_dz = -al * r;
    return r;
}

void MissileSystem::drift(double* a, const double* x, double, std::int64_t count) const {
    // eq. (25): positions follow -k_i x_i (guidance law u(t) folded in), velocities feel drag,
    // damping -0.01 v and gravity on the vertical axis.
    for (std::int64_t s = 0; s < count; ++s) {
        const double* X = x + 6 * s;
        double* A = a + 6 * s;
        const double speed = std::sqrt(X[3] * X[3] + X[4] * X[4] + X[5] * X[5]);
        const double drag = density(X[2]) * p_.gravity * speed / (2.0 * p_.ballistic);
        for (int i = 0; i < 3; ++i) A[i] = -p_.position_gain[i] * X[i];
        for (int i = 3; i < 6; ++i) A[i] = -drag * X[i] - p_.velocity_damping * X[i];
        A[5] -= p_.gravity;
    }
}

void MissileSystem::disturbance_gain(double* B, const double*, double, std::int64_t count) const {
    // B = [0 0 0 1 1 1]^T
    for (std::int64_t s = 0; s < count; ++s)
        for (int i = 0; i < 6; ++i) B[6 * s + i] = i < 3 ? 0.0 : 1.0;
}

void MissileSystem::measurement(double* c, const double* x, double, std::int64_t count) const {
    // eq. (24): C(X) = [x1 - 300, x2 - 200, x3, x4, x5, x6] (positions relative to the radar)
    for (std::int64_t s = 0; s < count; ++s) {
        const double* X = x + 6 * s;
        double* C = c + 6 * s;
        for (int i = 0; i < 3; ++i) C[i] = X[i] - p_.radar[i];
        for (int i = 3; i < 6; ++i) C[i] = X[i];
    }
}

void MissileSystem::drift_jacobian(double* J, const double* X, double) const {
    std::memset(J, 0, sizeof(double) * 36);
    for (int i = 0; i < 3; ++i) J[i * 6 + i] = -p_.position_gain[i];
    const double speed = std::sqrt(X[3] * X[3] + X[4] * X[4] + X[5] * X[5]);
    double drho = 0;
    const double rho = density(X[2], &drho);
    const double k = p_.gravity / (2.0 * p_.ballistic);
    for (int i = 3; i < 6; ++i) {
        // A_i = -k rho(z) |v| v_i - 0.01 v_i
        J[i * 6 + 2] = -k * drho * speed * X[i];
        for (int j = 3; j < 6; ++j) {
            double dspeed = speed > 0 ? X[j] / speed : 0.0;
            J[i * 6 + j] = -k * rho * (dspeed * X[i] + (i == j ? speed : 0.0));
        }
        J[i * 6 + i] -= p_.velocity_damping;
    }
}

void MissileSystem::measurement_jacobian(double* H, const double*, double) const {
    std::memset(H, 0, sizeof(double) * 36);
    for (int i = 0; i < 6; ++i) H[i * 6 + i] = 1.0;
}

}  // namespace hinf
