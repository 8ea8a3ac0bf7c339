// Theorem 1 of seed 000 evaluated at one point: the gain k* (eq. (8)) and the worst-case v*, n*
// (eqs. (6)-(7), with the sign of n* from the proof's completion of squares, docs/method.md). Seed 001's
// l*, v*, n* (eqs. (9)-(11)) are the same formulas with rho = r^2 (n* sign: method.md section 10.2).
#pragma once
#include <cmath>
#include <vector>

#include "models/system.hpp"

namespace hinf {

inline double quadratic_form(const double* Q, const double* x, int n) {
    double s = 0;
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) s += x[i] * Q[i * n + j] * x[j];
    return s;
}

inline double cosine(const double* a, const double* b, int n) {
    double ab = 0, aa = 0, bb = 0;
    for (int i = 0; i < n; ++i) {
        ab += a[i] * b[i];
        aa += a[i] * a[i];
        bb += b[i] * b[i];
    }
    return (aa > 0 && bb > 0) ? ab / std::sqrt(aa * bb) : 0.0;
}

struct WorstCase {
    std::vector<double> gain;    // k* [n x m]
    std::vector<double> v_star;  // [nv]
    std::vector<double> n_star;  // [m]
};

/// p = dV/dx~ [n], B = B(x) [n x nv], dc = C(x) - C(x^) [m].
/// k* = 2 rho p dc^T / |p|^2 (eq. (8)); v* = B^T p / (2 rho) (eq. (6)); n* = -k*^T p / (2 rho) = -dc.
/// With p = 0 the gain is undefined: k* = 0 and n* = 0.
inline WorstCase worst_case(const double* p, const double* B, const double* dc, int n, int nv, int m, double rho) {
    WorstCase w;
    w.gain.assign(static_cast<std::size_t>(n) * m, 0.0);
    w.v_star.assign(nv, 0.0);
    w.n_star.assign(m, 0.0);
    double pp = 0;
    for (int i = 0; i < n; ++i) pp += p[i] * p[i];
    for (int j = 0; j < nv; ++j) {
        double s = 0;
        for (int i = 0; i < n; ++i) s += B[i * nv + j] * p[i];
        w.v_star[j] = s / (2.0 * rho);
    }
    if (pp > 0) {
        for (int i = 0; i < n; ++i)
            for (int j = 0; j < m; ++j) w.gain[i * m + j] = 2.0 * rho * p[i] * dc[j] / pp;
        for (int j = 0; j < m; ++j) {
            double s = 0;
            for (int i = 0; i < n; ++i) s += w.gain[i * m + j] * p[i];
            w.n_star[j] = -s / (2.0 * rho);
        }
    }
    return w;
}

/// The sampled-data filter step every gain-driven filter shares (seed 000 eq. (19)):
/// x^_next = x^ + dt (A(x^) + k e), with a_hat = A(x^, t) [n], k [n x m], e = y - C(x^) [m]. x^_next may alias x^.
inline void luenberger_advance(double* xhat_next, const double* xhat, const double* a_hat, const double* k,
                               const double* e, int n, int m, double dt) {
    for (int i = 0; i < n; ++i) {
        double ke = 0;
        for (int j = 0; j < m; ++j) ke += k[i * m + j] * e[j];
        xhat_next[i] = xhat[i] + dt * (a_hat[i] + ke);
    }
}

/// The filtered-estimate equivalent of a sampled-data filter (docs/compare.md): the step above split into its
/// measurement correction x^_{k|k} = x^ + dt k e, then the prediction x^_next = x^_{k|k} + dt A(x^).
inline void luenberger_correct(double* xhat_filtered, const double* xhat, const double* k, const double* e, int n,
                               int m, double dt) {
    for (int i = 0; i < n; ++i) {
        double ke = 0;
        for (int j = 0; j < m; ++j) ke += k[i * m + j] * e[j];
        xhat_filtered[i] = xhat[i] + dt * ke;
    }
}

/// The `gain` variant's filter step for either kind of time (docs/method.md section 16.8): continuous time the
/// sampled-data law above; discrete time the one-step predictor x^_next = f(x^) + k e, a_hat = f(x^, t_k) (the map).
inline void gain_filter_advance(double* xhat_next, const double* xhat, const double* a_hat, const double* k,
                                const double* e, int n, int m, double dt, bool discrete) {
    if (!discrete) return luenberger_advance(xhat_next, xhat, a_hat, k, e, n, m, dt);
    for (int i = 0; i < n; ++i) {
        double ke = 0;
        for (int j = 0; j < m; ++j) ke += k[i * m + j] * e[j];
        xhat_next[i] = a_hat[i] + ke;
    }
}

/// Its filtered estimate x^_{k|k} (docs/compare.md): continuous time luenberger_correct; discrete time
/// x^ + F^-1 k e with F = df/dx at x^ (the estimate of x_k whose linearised one-step prediction is the filter's
/// x^_{k+1}; a least-squares solve where F is singular).
void gain_filter_correct(double* xhat_filtered, const System& sys, const double* xhat, double t, const double* k,
                         const double* e, double dt);

/// The four terms of the HJIE (seed 000 eq. (16)) at one point: p = dV/dx~ at x~ = x - x^, with dA = A(x) - A(x^),
/// B(x), dC = C(x) - C(x^), x~'Q x~ (kern::hjie_terms). Their sum is the residual; the sum of their absolute
/// values is its scale S. Used by the trainer's record and the on-line HJI check.
void hjie_point_terms(double* terms, const double* p, const System& sys, const double* x, const double* xhat,
                      double t, const double* Q, double rho);

class FrozenNetwork;
/// Variant gain (docs/method.md section 14): the dissipation inequality's value H at x~ = x - x^ for the network's
/// K(x^) and storage S (kern::gain_sample_forward); *abs_sum gets its scale. *v0 (may be null) gets x~'S x~.
/// K (n x m, may be null): this gain instead of the network's, against the network's storage (an ensemble's mean gain).
double gain_point_residual(double* abs_sum, double* v, FrozenNetwork& net, const System& sys, const double* x,
                           const double* xhat, double t, const double* Q, double rho, const double* K = nullptr);

}  // namespace hinf
