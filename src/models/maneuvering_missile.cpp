// Maneuvering missile of seed 001 eqs. (24)-(29), batched, time-varying, with analytic Jacobians.
#include "models/maneuvering_missile.hpp"

#include <cmath>
#include <cstring>

namespace hinf {

double ManeuveringMissileSystem::wave(double t) const {
    // eq. (28): a(t) = A e^{-0.1 t} (4/pi) sin(t)
    return p_.amplitude * std::exp(-p_.decay * t) * (4.0 / M_PI) * std::sin(p_.wave_frequency * t);
}

double ManeuveringMissileSystem::maneuver_coefficient(double t) const {
    return std::exp(-p_.decay * t) * std::sin(p_.maneuver_frequency * t);
}

void ManeuveringMissileSystem::drift(double* a, const double* x, double t, std::int64_t count) const {
    // eq. (29): f = f_(25) + u(t), u of eq. (28). In rows 1-3 u's -x4..-x6 cancel the kinematics
    // x1' = x4 (as printed): x1' = -0.1 x1 + a(t), x2' = -0.1 x2, x3' = -0.08 x3.
    const MissileParams& b = p_.base;
    const double at = wave(t), mt = maneuver_coefficient(t);
    for (std::int64_t s = 0; s < count; ++s) {
        const double* X = x + 6 * s;
        double* A = a + 6 * s;
        const double speed = std::sqrt(X[3] * X[3] + X[4] * X[4] + X[5] * X[5]);
        const double drag = drag_.density(X[2]) * b.gravity * speed / (2.0 * b.ballistic);
        for (int i = 0; i < 3; ++i) A[i] = -b.position_gain[i] * X[i];
        A[0] += at;
        A[3] = -drag * X[3] - mt * X[3];
        A[4] = -drag * X[4] - b.velocity_damping * X[4];
        A[5] = -drag * X[5] - b.velocity_damping * X[5] - b.gravity;
    }
}

void ManeuveringMissileSystem::disturbance_gain(double* B, const double*, double, std::int64_t count) const {
    // eq. (26): g = diag(0, 0, 0, 1, 1, 1), row-major 6 x 6 per state
    for (std::int64_t s = 0; s < count; ++s) {
        double* G = B + 36 * s;
        std::memset(G, 0, sizeof(double) * 36);
        for (int i = 3; i < 6; ++i) G[i * 6 + i] = 1.0;
    }
}

void ManeuveringMissileSystem::measurement(double* c, const double* x, double, std::int64_t count) const {
    // eq. (27): h = [x1 - 300, x2 - 300, x3, x4, x5, x6] (radar at (300, 300, 0))
    for (std::int64_t s = 0; s < count; ++s) {
        const double* X = x + 6 * s;
        double* C = c + 6 * s;
        for (int i = 0; i < 3; ++i) C[i] = X[i] - p_.base.radar[i];
        for (int i = 3; i < 6; ++i) C[i] = X[i];
    }
}

void ManeuveringMissileSystem::drift_jacobian(double* J, const double* X, double t) const {
    const MissileParams& b = p_.base;
    std::memset(J, 0, sizeof(double) * 36);
    for (int i = 0; i < 3; ++i) J[i * 6 + i] = -b.position_gain[i];
    const double speed = std::sqrt(X[3] * X[3] + X[4] * X[4] + X[5] * X[5]);
    double drho = 0;
    const double rho = drag_.density(X[2], &drho);
    const double k = b.gravity / (2.0 * b.ballistic);
    for (int i = 3; i < 6; ++i) {
        J[i * 6 + 2] = -k * drho * speed * X[i];
        for (int j = 3; j < 6; ++j) {
            double dspeed = speed > 0 ? X[j] / speed : 0.0;
            J[i * 6 + j] = -k * rho * (dspeed * X[i] + (i == j ? speed : 0.0));
        }
    }
    J[3 * 6 + 3] -= maneuver_coefficient(t);
    J[4 * 6 + 4] -= b.velocity_damping;
    J[5 * 6 + 5] -= b.velocity_damping;
}

void ManeuveringMissileSystem::measurement_jacobian(double* H, const double*, double) const {
    std::memset(H, 0, sizeof(double) * 36);
    for (int i = 0; i < 6; ++i) H[i * 6 + i] = 1.0;
}

}  // namespace hinf
