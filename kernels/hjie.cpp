// HJIE terms, per-sample losses and their gradients with respect to p and P (see hjie.hpp).
#include "hjie.hpp"

#include <cassert>
#include <cmath>

namespace hinf::kern {

namespace {
// u_j = (B^T p)_j, one component at a time (no [nv] array: any disturbance dimension)
inline double bt_times_j(const double* B, const double* p, int n, int nv, int j) {
    double s = 0;
    for (int a = 0; a < n; ++a) s += B[a * nv + j] * p[a];
    return s;
}

// The four terms of seed 000 eq. (16) at one sample, given bb = |B^T p|^2: x~'Qx~, p'dA, |B^T p|^2/(4 rho),
// -rho |dC|^2. The one definition for hjie_terms and the per-sample backward.
inline void terms_from_bb(double* t, const double* p, const double* dA, double bb, const double* dC, double q,
                          double rho, int n, int m) {
    double pa = 0, cc = 0;
    for (int a = 0; a < n; ++a) pa += p[a] * dA[a];
    for (int k = 0; k < m; ++k) cc += dC[k] * dC[k];
    t[0] = q;
    t[1] = pa;
    t[2] = bb / (4.0 * rho);
    t[3] = -rho * cc;
}
}  // namespace

namespace {

template <int N>
void terms_n(double* t, const double* p, const HjieSystemView& s, std::int64_t i, double rho) {
    const int n = N > 0 ? N : s.n, nv = s.nv, m = s.m;
    const double* dA = s.dA + i * n;
    const double* B = s.Bm + i * n * nv;
    const double* dC = s.dC + i * m;
    double bb = 0;
    for (int j = 0; j < nv; ++j) {
        const double u = bt_times_j(B, p, n, nv, j);
        bb += u * u;
    }
    terms_from_bb(t, p, dA, bb, dC, s.q[i], rho, n, m);
}

template <int N>
double h2_rate_n(const double* p, const double* P, const HjieSystemView& s, std::int64_t i, const HjieParams& hp) {
    const int n = N > 0 ? N : s.n, nv = s.nv, m = s.m;
    const double* B = s.Bm + i * n * nv;
    const double* dC = s.dC + i * m;
    double tr_bpb = 0;
    for (int j = 0; j < nv; ++j)
        for (int a = 0; a < n; ++a)
            for (int b = 0; b < n; ++b) tr_bpb += B[a * nv + j] * P[a * n + b] * B[b * nv + j];
    double cc = 0, pp = 0, pPp = 0;
    for (int k = 0; k < m; ++k) cc += dC[k] * dC[k];
    for (int a = 0; a < n; ++a) {
        pp += p[a] * p[a];
        double row = 0;
        for (int b = 0; b < n; ++b) row += P[a * n + b] * p[b];
        pPp += p[a] * row;
    }
    // tr(k^T P k) with k = 2 rho p dC^T/|p|^2  =  4 rho^2 |dC|^2 p^T P p / |p|^4
    double tr_kpk = pp > 0 ? 4.0 * hp.rho * hp.rho * cc * pPp / (pp * pp) : 0.0;
    return 0.5 * hp.disturbance_intensity * tr_bpb + 0.5 * hp.noise_intensity * tr_kpk;
}

template <int N>
HjieSampleValue sample_forward_n(const double* p, const double* P, const HjieSystemView& s, std::int64_t i,
                                 const HjieParams& hp, HjieObjective obj) {
    const int n = N > 0 ? N : s.n;
    double t[4];
    terms_n<N>(t, p, s, i, hp.rho);
    HjieSampleValue v;
    const int R = hjie_residual_count(hp.game);
    double eps[2], S[2];
    for (int k = 0; k < R; ++k) {
        const double c = kHjieCoupling[k];
        eps[k] = t[0] + t[1] + c * t[2] + c * t[3];  // c = 1: same bits as seed 000's sum
        S[k] = std::fabs(t[0]) + std::fabs(t[1]) + c * std::fabs(t[2]) + c * std::fabs(t[3]);
        if (obj == HJIE_OBJECTIVE_PAPER) {
            v.hinge += eps[k] * eps[k];
        } else if (S[k] > 0) {
            double u = eps[k] / S[k] + hp.margin;
            v.hinge += u > 0 ? u * u : 0.0;
        }
    }
    v.residual = eps[0];
    v.abs_sum = S[0];
    if (R == 2) {
        v.residual2 = eps[1];
        v.abs_sum2 = S[1];
    }
    if (obj == HJIE_OBJECTIVE_PAPER) return v;
    // H2 bound: V(x~) ~ p^T x~ / 2 (exact for constant P) plus horizon * rate; one constant for all samples
    double px = 0;
    for (int a = 0; a < n; ++a) px += p[a] * s.xt[i * n + a];
    v.h2 = (0.5 * px + hp.horizon * h2_rate_n<N>(p, P, s, i, hp)) / hp.h2_reference;
    return v;
}

template <int N>
void sample_backward_n(double* gp, double* gP, const double* p, const double* P, const HjieSystemView& s,
                       std::int64_t i, const HjieParams& hp, HjieObjective obj, double d_hinge, double d_h2,
                       double* work) {
    const int n = N > 0 ? N : s.n, nv = s.nv, m = s.m;
    const double* dA = s.dA + i * n;
    const double* B = s.Bm + i * n * nv;
    const double* dC = s.dC + i * m;
    // bbp [n] = B B^T p / (2 rho) = d(|B^T p|^2/(4 rho))/dp, accumulated over u_j = (B^T p)_j in j order (the
    // same sums in the same order as with a stored u); bb = |u|^2 alongside
    double* bbp = work;
    double bb = 0;
    for (int a = 0; a < n; ++a) bbp[a] = 0.0;
    for (int j = 0; j < nv; ++j) {
        const double u = bt_times_j(B, p, n, nv, j);
        bb += u * u;
        for (int a = 0; a < n; ++a) bbp[a] += B[a * nv + j] * u;
    }
    for (int a = 0; a < n; ++a) bbp[a] = bbp[a] / (2.0 * hp.rho);
    // the four terms of eq. (16), as hjie_terms computes them
    double t[4];
    terms_from_bb(t, p, dA, bb, dC, s.q[i], hp.rho, n, m);
    if (gP)
        for (int a = 0; a < n * n; ++a) gP[a] = 0.0;
    for (int a = 0; a < n; ++a) gp[a] = 0.0;
    const int R = hjie_residual_count(hp.game);
    const double sg = t[1] >= 0 ? 1.0 : -1.0;
    for (int k = 0; k < R; ++k) {
        // eps_k = t0 + t1 + c (t2 + t3):  d eps_k/dp = dA + c B B^T p/(2 rho)
        const double c = kHjieCoupling[k];
        const double eps = t[0] + t[1] + c * t[2] + c * t[3];
        if (obj == HJIE_OBJECTIVE_PAPER) {
            // hinge term eps_k^2
            for (int a = 0; a < n; ++a) gp[a] += d_hinge * 2.0 * eps * (dA[a] + c * bbp[a]);
            continue;
        }
        const double S = std::fabs(t[0]) + std::fabs(t[1]) + c * std::fabs(t[2]) + c * std::fabs(t[3]);
        if (S <= 0) continue;
        const double r = eps / S, uu = r + hp.margin;
        if (uu <= 0) continue;
        // d r/dp = (d eps/dp - r dS/dp)/S,  dS/dp = sign(p^T dA) dA + c B B^T p/(2 rho)
        const double f = d_hinge * 2.0 * uu / S;
        for (int a = 0; a < n; ++a) gp[a] += f * ((dA[a] + c * bbp[a]) - r * (sg * dA[a] + c * bbp[a]));
    }
    if (obj == HJIE_OBJECTIVE_PAPER) return;
    if (d_h2 == 0.0) return;
    // h2 = [sv/2 tr(B^T P B) + sn/2 * 4 rho^2 |dC|^2 p^T P p / |p|^4] / w
    double cc = 0, pp = 0, pPp = 0;
    double* Pp = work + n;  // [n] = P p
    for (int k = 0; k < m; ++k) cc += dC[k] * dC[k];
    for (int a = 0; a < n; ++a) {
        pp += p[a] * p[a];
        double row = 0;
        for (int b = 0; b < n; ++b) row += P[a * n + b] * p[b];
        Pp[a] = row;
    }
    for (int a = 0; a < n; ++a) pPp += p[a] * Pp[a];
    const double* xt = s.xt + i * n;
    for (int a = 0; a < n; ++a) gp[a] += d_h2 / hp.h2_reference * 0.5 * xt[a];
    const double scale = d_h2 * hp.horizon / hp.h2_reference;
    const double cn = 0.5 * hp.noise_intensity * 4.0 * hp.rho * hp.rho * cc;
    if (pp > 0) {
        const double p4 = pp * pp, p6 = p4 * pp;
        for (int a = 0; a < n; ++a) gp[a] += scale * cn * (2.0 * Pp[a] / p4 - 4.0 * pPp * p[a] / p6);
    }
    if (gP) {
        // symmetric: (a, b) and (b, a) are the same products in the same order, so compute b <= a and mirror
        for (int a = 0; a < n; ++a)
            for (int b = 0; b <= a; ++b) {
                double bb = 0;
                for (int j = 0; j < nv; ++j) bb += B[a * nv + j] * B[b * nv + j];
                double g = 0.5 * hp.disturbance_intensity * bb;
                if (pp > 0) g += cn * p[a] * p[b] / (pp * pp);
                gP[a * n + b] = scale * g;
                gP[b * n + a] = scale * g;
            }
    }
}

}  // namespace

// public entry points: n = 6 (the missile models) compiled with the state dimension known, so the
// small loops unroll; the same operations in the same order as the general version
void hjie_terms(double* t, const double* p, const HjieSystemView& s, std::int64_t i, double rho) {
    if (s.n == 6) return terms_n<6>(t, p, s, i, rho);
    terms_n<0>(t, p, s, i, rho);
}

double hjie_h2_rate(const double* p, const double* P, const HjieSystemView& s, std::int64_t i, const HjieParams& hp) {
    if (s.n == 6) return h2_rate_n<6>(p, P, s, i, hp);
    return h2_rate_n<0>(p, P, s, i, hp);
}

HjieSampleValue hjie_sample_forward(const double* p, const double* P, const HjieSystemView& s, std::int64_t i,
                                    const HjieParams& hp, HjieObjective obj) {
    if (s.n == 6) return sample_forward_n<6>(p, P, s, i, hp, obj);
    return sample_forward_n<0>(p, P, s, i, hp, obj);
}

std::int64_t hjie_backward_workspace(int n) { return 2 * std::int64_t(n); }

void hjie_sample_backward(double* gp, double* gP, const double* p, const double* P, const HjieSystemView& s,
                          std::int64_t i, const HjieParams& hp, HjieObjective obj, double d_hinge, double d_h2,
                          double* work) {
    if (s.n == 6) return sample_backward_n<6>(gp, gP, p, P, s, i, hp, obj, d_hinge, d_h2, work);
    sample_backward_n<0>(gp, gP, p, P, s, i, hp, obj, d_hinge, d_h2, work);
}

}  // namespace hinf::kern
