// The HJIE of the H-infinity filtering game (seed 000 eq. (9)/(16)) and the two coupled HJIEs of the
// mixed H2/H-infinity game (seed 001 eqs. (12)-(13)/(19)-(20)) per sample, the per-sample loss terms
// built on them, and their gradients with respect to p = dV/dx~ (and P for the quadratic head).
// Not the network (mlp.hpp, head.hpp) and not any particular system: the system enters only
// through per-sample constants computed once per time step.
//
// Shape legend: N = samples, n = states, nv = disturbance inputs, m = outputs.
//   xt [N x n]  estimation errors x~_i          dA [N x n]  A(x^+x~_i) - A(x^)
//   Bm [N x n x nv]  B(x^+x~_i) row-major       dC [N x m]  C(x^+x~_i) - C(x^)
//   q  [N]      x~_i^T Q x~_i
#pragma once
#include <cstdint>

namespace hinf::kern {

enum HjieObjective {
    HJIE_OBJECTIVE_PAPER = 0,        // seed 000: residual of eq. (16) driven to zero, L = sqrt(mean eps^2)
    HJIE_OBJECTIVE_DISSIPATIVE = 1,  // default: hinge on HJIE <= -margin*S plus an H2 term (docs/method.md)
};

// Which game: one HJIE (seed 000) or the two coupled ones (seed 001). Both share the four terms
// [x~^TQx~, p^T dA, |B^T p|^2/(4 rho), -rho |dC|^2] (rho = r^2 in seed 001); residual k is
// t0 + t1 + c_k (t2 + t3) with c_1 = 1 (eq. (12)/(19), = seed 000 eq. (16)) and c_2 = 2 (eq. (13)/(20):
// 1/(2 r^2) and -2 r^2 as printed).
enum HjieGame {
    HJIE_GAME_HINF = 0,   // seed 000: one residual
    HJIE_GAME_MIXED = 1,  // seed 001: residuals eps_1, eps_2
};
constexpr double kHjieCoupling[2] = {1.0, 2.0};  // c_k above
inline int hjie_residual_count(HjieGame g) { return g == HJIE_GAME_MIXED ? 2 : 1; }

struct HjieSystemView {
    int n = 0, nv = 0, m = 0;
    const double* xt = nullptr;
    const double* dA = nullptr;
    const double* Bm = nullptr;
    const double* dC = nullptr;
    const double* q = nullptr;
    const double* t = nullptr;   // [N] sample times (variant gain with a time-varying storage)
    const double* Hx = nullptr;  // [N x m x n] output Jacobian at each sample's estimate (same; and Kalman-form head)
    const double* Fx = nullptr;  // [N x n x n] the map's Jacobian at each sample's estimate (Kalman-form head)
};

struct HjieParams {
    double rho = 0.03;                  // prescribed attenuation level (seed 000 eq. (5))
    double margin = 0.02;               // dissipative: enforce HJIE <= -margin * S
    double h2_weight = 0.1;             // dissipative: eta, weight of the H2 term
    double disturbance_intensity = 4.0; // dissipative: sigma_v^2 of the white disturbance (per unit time)
    double noise_intensity = 4.0;       // dissipative: sigma_n^2 of the white measurement noise
    double horizon = 70.0;              // dissipative: T in the H2 bound V(x~) + T * rate  [s]
    double h2_reference = 1.0;          // dissipative: the H2 bound is divided by this constant [V]
    HjieGame game = HJIE_GAME_HINF;     // one residual (seed 000) or two (seed 001)
};

/// The four terms of eq. (16) at sample i: [x~^TQx~, p^T dA, |B^T p|^2/(4 rho), -rho |dC|^2].
void hjie_terms(double* terms, const double* p, const HjieSystemView& s, std::int64_t i, double rho);

/// Per-sample loss pieces: `hinge` enters L through sqrt(mean(hinge)), `h2` through mean(h2) * weight.
/// Sums over the game's residuals k: paper: hinge = sum eps_k^2 (seed 001: eps_1^2 + eps_2^2), h2 = 0.
/// Dissipative: hinge = sum relu(eps_k/S_k + margin)^2,
/// h2 = (p^T x~ / 2 + horizon * H2 rate) / h2_reference  (the H2 bound V(x~) + T * rate, docs/method.md).
/// Also returns eps_k (residual of eq. (16), resp. (19) and (20)) and S_k (sum of absolute values of its
/// terms, S_k = |t0| + |t1| + c_k (|t2| + |t3|)); residual2/abs_sum2 are 0 for the H-infinity game.
struct HjieSampleValue {
    double residual = 0, abs_sum = 0, hinge = 0, h2 = 0;
    double residual2 = 0, abs_sum2 = 0;
};
HjieSampleValue hjie_sample_forward(const double* p, const double* P, const HjieSystemView& s, std::int64_t i,
                                    const HjieParams& hp, HjieObjective obj);

/// gp [n] = dL/dp, gP [n x n] = dL/dP (dissipative only; may be null for paper) for one sample,
/// given d_hinge = dL/d(hinge_i) and d_h2 = dL/d(h2_i). Overwrites gp and gP. work [hjie_backward_workspace(n)]
/// is the caller's scratch (any n; nothing allocated here).
std::int64_t hjie_backward_workspace(int n);
void hjie_sample_backward(double* gp, double* gP, const double* p, const double* P, const HjieSystemView& s,
                          std::int64_t i, const HjieParams& hp, HjieObjective obj, double d_hinge, double d_h2,
                          double* work);

/// H2 rate of the dissipative objective: sigma_v^2/2 tr(B^T P B) + sigma_n^2/2 tr(k^T P k),
/// k = 2 rho p dC^T / |p|^2 (seed 000 eq. (8)).
double hjie_h2_rate(const double* p, const double* P, const HjieSystemView& s, std::int64_t i, const HjieParams& hp);

}  // namespace hinf::kern
