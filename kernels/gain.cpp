// The gain variant's per-sample loss, its storage and gain head, and the chunked minibatch gradient (see gain.hpp).
// Small dense loops over n, m <= 32, one sample per call; the MLP is kernels/mlp.
#include "gain.hpp"
#include "gain_discrete.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

namespace hinf::kern {

namespace {
constexpr int kMax = kGainMaxDim;  // gain.hpp; the config refuses larger systems

// The sample's intermediate quantities: s = S x~, b = B's, u = K's, a = s'dA, kc = u'dC.
struct GainParts {
    double s[kMax], b[kMax], u[kMax];
    double a = 0, kc = 0, bb = 0, uu = 0;
};

void gain_parts(GainParts* g, const double* K, const double* S, const HjieSystemView& sv, std::int64_t i) {
    const int n = sv.n, nv = sv.nv, m = sv.m;
    assert(n <= kMax && nv <= kMax && m <= kMax);
    const double* xt = sv.xt + i * n;
    const double* dA = sv.dA + i * n;
    const double* B = sv.Bm + i * n * nv;
    const double* dC = sv.dC + i * m;
    for (int a = 0; a < n; ++a) {
        double t = 0;
        for (int c = 0; c < n; ++c) t += S[a * n + c] * xt[c];
        g->s[a] = t;
    }
    g->a = 0;
    for (int a = 0; a < n; ++a) g->a += g->s[a] * dA[a];
    g->bb = 0;
    for (int j = 0; j < nv; ++j) {
        double t = 0;
        for (int a = 0; a < n; ++a) t += B[a * nv + j] * g->s[a];
        g->b[j] = t;
        g->bb += t * t;
    }
    g->uu = 0;
    g->kc = 0;
    for (int j = 0; j < m; ++j) {
        double t = 0;
        for (int a = 0; a < n; ++a) t += K[a * m + j] * g->s[a];
        g->u[j] = t;
        g->uu += t * t;
        g->kc += t * dC[j];
    }
}

// relu(dt |K dC|_W / |x~|_W - kappa) with |z|_W = sqrt(z'Wz): W = D^-2 (the error scales) or, with
// gp.cap_in_storage, W = S (the storage). drK [n x m] (may be null) gets the ratio's derivative with respect to K;
// drS [n x n] (may be null; only with cap_in_storage) its derivative with respect to S's entries, as independent
double step_correction_excess(const double* K, const double* S, const HjieSystemView& sv, std::int64_t i,
                              const GainLossParams& gp, double* drK, double* drS) {
    if (!(gp.dt > 0)) return 0.0;
    const int n = sv.n, m = sv.m;
    const double* xt = sv.xt + i * n;
    const double* dC = sv.dC + i * m;
    double u[kMax];
    for (int a = 0; a < n; ++a) {
        double t = 0;
        for (int j = 0; j < m; ++j) t += K[a * m + j] * dC[j];
        u[a] = t;
    }
    if (gp.cap_in_storage) {
        double su[kMax], uu = 0, ee = 0;
        for (int a = 0; a < n; ++a) {
            double tu = 0, tx = 0;
            for (int c = 0; c < n; ++c) {
                tu += S[a * n + c] * u[c];
                tx += S[a * n + c] * xt[c];
            }
            su[a] = tu;
            uu += u[a] * tu;
            ee += xt[a] * tx;
        }
        if (!(ee > 0) || !(uu > 0)) return 0.0;
        const double nu = std::sqrt(uu), ne = std::sqrt(ee);
        const double r = gp.dt * nu / ne;
        if (r <= gp.kappa) return 0.0;
        if (drK != nullptr)  // d|u|_S / du = S u / |u|_S, u = K dC
            for (int a = 0; a < n; ++a)
                for (int j = 0; j < m; ++j) drK[a * m + j] = gp.dt / ne * (su[a] / nu) * dC[j];
        if (drS != nullptr)  // d(z'Sz)/dS_ac = z_a z_c
            for (int a = 0; a < n; ++a)
                for (int c = 0; c < n; ++c)
                    drS[a * n + c] = gp.dt * (u[a] * u[c] / (2.0 * nu * ne) - nu * xt[a] * xt[c] / (2.0 * ee * ne));
        return r - gp.kappa;
    }
    if (gp.dx == nullptr) return 0.0;
    double w[kMax], kk = 0, ee = 0;
    for (int a = 0; a < n; ++a) {
        w[a] = u[a] / gp.dx[a];
        kk += w[a] * w[a];
        ee += (xt[a] / gp.dx[a]) * (xt[a] / gp.dx[a]);
    }
    if (!(ee > 0) || !(kk > 0)) return 0.0;
    const double nk = std::sqrt(kk), ne = std::sqrt(ee);
    const double r = gp.dt * nk / ne;
    if (r <= gp.kappa) return 0.0;
    if (drK != nullptr)
        for (int a = 0; a < n; ++a)
            for (int j = 0; j < m; ++j) drK[a * m + j] = gp.dt / ne * (w[a] / nk) * dC[j] / gp.dx[a];
    if (drS != nullptr)
        for (int k = 0; k < n * n; ++k) drS[k] = 0.0;
    return r - gp.kappa;
}

// x' A x
double xqx(const double* A, const double* x, int n) {
    double r = 0;
    for (int a = 0; a < n; ++a) {
        double t = 0;
        for (int c = 0; c < n; ++c) t += A[a * n + c] * x[c];
        r += x[a] * t;
    }
    return r;
}

// tr(B'S B) and tr(K'S K)
double trace_form(const double* S, const double* X, int n, int cols) {
    double tr = 0;
    for (int j = 0; j < cols; ++j)
        for (int a = 0; a < n; ++a) {
            double t = 0;
            for (int c = 0; c < n; ++c) t += S[a * n + c] * X[c * cols + j];
            tr += X[a * cols + j] * t;
        }
    return tr;
}
}  // namespace

GainSampleValue gain_sample_forward(const double* K, const double* S, const HjieSystemView& sv, std::int64_t i,
                                    const GainLossParams& gp, const double* Sdot) {
    if (gp.discrete) return gain_discrete_sample_forward(K, S, sv, i, gp);  // the one-step game (gain_discrete.hpp)
    const int n = sv.n, nv = sv.nv, m = sv.m;
    GainParts g;
    gain_parts(&g, K, S, sv, i);
    const double q = sv.q[i], rho = gp.rho;
    const double sd = Sdot != nullptr ? xqx(Sdot, sv.xt + i * n, n) : 0.0;
    GainSampleValue v;
    // sup over v, n: v* = B's/rho, n* = -K's/rho (completing the squares in 2s'(Bv - Kn) - rho|v|^2 - rho|n|^2)
    v.residual = q + sd + 2.0 * g.a - 2.0 * g.kc + g.bb / rho + g.uu / rho;
    v.abs_sum = std::fabs(q) + std::fabs(sd) + 2.0 * std::fabs(g.a) + 2.0 * std::fabs(g.kc) + g.bb / rho + g.uu / rho;
    const double r = v.abs_sum > 0 ? v.residual / v.abs_sum : 0.0;
    const double h = std::max(0.0, r + gp.margin);
    v.hinge = h * h;
    const double c = step_correction_excess(K, S, sv, i, gp, nullptr, nullptr);
    v.hinge += c * c;
    v.h2 = gain_h2_value(S, K, sv.Bm + i * n * nv, n, nv, m, gp);
    return v;
}

double gain_h2_value(const double* S, const double* K, const double* B, int n, int nv, int m, const GainLossParams& gp) {
    double v0 = 0;
    if (gp.xt0 != nullptr && gp.initial_weight > 0) {
        for (int a = 0; a < n; ++a)
            for (int c = 0; c < n; ++c) v0 += gp.xt0[a] * S[a * n + c] * gp.xt0[c];
    }
    const double rate = gp.disturbance_intensity * trace_form(S, B, n, nv) + gp.noise_intensity * trace_form(S, K, n, m);
    return (gp.initial_weight * v0 / gp.horizon + rate) / gp.h2_reference;
}

void gain_h2_backward(double* gK, double* gS, const double* S, const double* K, const double* B, int n, int nv, int m,
                      const GainLossParams& gp, double d_h2) {
    if (d_h2 == 0) return;
    const double w = d_h2 / gp.h2_reference;
    // symmetric in (a, c): each product is computed once for both (the same operands in the same order, so the
    // same bits as computing (c, a) afresh)
    for (int a = 0; a < n; ++a)
        for (int c = 0; c <= a; ++c) {
            double t = 0, t2 = 0;
            if (gp.xt0 != nullptr && gp.initial_weight > 0) {
                t += gp.initial_weight * gp.xt0[a] * gp.xt0[c] / gp.horizon;
                t2 += gp.initial_weight * gp.xt0[c] * gp.xt0[a] / gp.horizon;
            }
            double bb = 0, kk = 0;
            for (int j = 0; j < nv; ++j) bb += B[a * nv + j] * B[c * nv + j];
            for (int j = 0; j < m; ++j) kk += K[a * m + j] * K[c * m + j];
            gS[a * n + c] += w * (t + gp.disturbance_intensity * bb + gp.noise_intensity * kk);
            if (c != a) gS[c * n + a] += w * (t2 + gp.disturbance_intensity * bb + gp.noise_intensity * kk);
        }
    // d tr(K'S K)/dK = (S + S') K = 2 S K
    for (int a = 0; a < n; ++a)
        for (int j = 0; j < m; ++j) {
            double t = 0;
            for (int c = 0; c < n; ++c) t += (S[a * n + c] + S[c * n + a]) * K[c * m + j];
            gK[a * m + j] += w * gp.noise_intensity * t;
        }
}

void gain_sample_backward(double* gK, double* gS, const double* K, const double* S, const HjieSystemView& sv,
                          std::int64_t i, const GainLossParams& gp, double d_hinge, double d_h2, const double* Sdot,
                          double* gSd) {
    if (gp.discrete) return gain_discrete_sample_backward(gK, gS, K, S, sv, i, gp, d_hinge, d_h2);
    const int n = sv.n, nv = sv.nv, m = sv.m;
    const double* xt = sv.xt + i * n;
    const double* dA = sv.dA + i * n;
    const double* B = sv.Bm + i * n * nv;
    const double* dC = sv.dC + i * m;
    GainParts g;
    gain_parts(&g, K, S, sv, i);
    const double q = sv.q[i], rho = gp.rho;
    const double sd = Sdot != nullptr ? xqx(Sdot, xt, n) : 0.0;
    const double H = q + sd + 2.0 * g.a - 2.0 * g.kc + g.bb / rho + g.uu / rho;
    const double Sc = std::fabs(q) + std::fabs(sd) + 2.0 * std::fabs(g.a) + 2.0 * std::fabs(g.kc) + g.bb / rho + g.uu / rho;
    for (int k = 0; k < n * m; ++k) gK[k] = 0.0;
    // hinge: d relu(r + margin)^2 / dr, r = H / Sc
    double g_r = 0;
    if (Sc > 0) {
        const double h = std::max(0.0, H / Sc + gp.margin);
        g_r = d_hinge * 2.0 * h;
    }
    if (g_r != 0) {
        const double gH = g_r / Sc, gSc = -g_r * H / (Sc * Sc);
        const double sa = g.a > 0 ? 1.0 : (g.a < 0 ? -1.0 : 0.0), skc = g.kc > 0 ? 1.0 : (g.kc < 0 ? -1.0 : 0.0);
        const double g_a = 2.0 * gH + 2.0 * sa * gSc;
        const double g_kc = -2.0 * gH + 2.0 * skc * gSc;
        const double g_quad = (gH + gSc) / rho;  // d/d(|b|^2) and d/d(|u|^2)
        if (Sdot != nullptr && gSd != nullptr) {    // x~'Sdot x~
            const double ssd = sd > 0 ? 1.0 : (sd < 0 ? -1.0 : 0.0), g_sd = gH + ssd * gSc;
            for (int a = 0; a < n; ++a)
                for (int c = 0; c < n; ++c) gSd[a * n + c] += g_sd * xt[a] * xt[c];
        }
        double gs[kMax], gu[kMax];
        for (int a = 0; a < n; ++a) gs[a] = g_a * dA[a];
        for (int j = 0; j < nv; ++j) {
            const double gb = 2.0 * g_quad * g.b[j];
            for (int a = 0; a < n; ++a) gs[a] += B[a * nv + j] * gb;
        }
        for (int j = 0; j < m; ++j) gu[j] = 2.0 * g_quad * g.u[j] + g_kc * dC[j];
        // u = K's: dL/dK_aj = s_a gu_j, dL/ds += K gu
        for (int a = 0; a < n; ++a) {
            double t = 0;
            for (int j = 0; j < m; ++j) {
                gK[a * m + j] += g.s[a] * gu[j];
                t += K[a * m + j] * gu[j];
            }
            gs[a] += t;
        }
        // s = S x~
        for (int a = 0; a < n; ++a)
            for (int c = 0; c < n; ++c) gS[a * n + c] += gs[a] * xt[c];
    }
    {  // the sampled-data cap
        double dr[kMax * kMax], drS[kMax * kMax];
        const double c = step_correction_excess(K, S, sv, i, gp, dr, gp.cap_in_storage ? drS : nullptr);
        if (c > 0) {
            for (int k = 0; k < n * m; ++k) gK[k] += d_hinge * 2.0 * c * dr[k];
            if (gp.cap_in_storage)
                for (int k = 0; k < n * n; ++k) gS[k] += d_hinge * 2.0 * c * drS[k];
        }
    }
    gain_h2_backward(gK, gS, S, K, B, n, nv, m, gp, d_h2);
}

namespace {
template <typename T>
void unpack_lower(double* M, const T* s, int n) {
    int k = 0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) M[a * n + b] = (a == b) ? 1.0 : 0.0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b) M[a * n + b] += double(s[k++]);
}
}  // namespace

template <typename T>
void storage_forward(double* S, const T* s, const double* d, int n, double c, double eps) {
    double M[kMax * kMax];
    unpack_lower(M, s, n);
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b) {
            double t = 0;
            for (int k = 0; k <= b; ++k) t += M[a * n + k] * M[b * n + k];
            t = c * (t + (a == b ? eps : 0.0)) / (d[a] * d[b]);
            S[a * n + b] = t;
            S[b * n + a] = t;
        }
}

template <typename T>
void storage_backward(T* ds, const double* gS, const T* s, const double* d, int n, double c) {
    // S_ab = c (M M')_ab / (d_a d_b): dL/dM = c (G + G') M with G_ab = gS_ab / (d_a d_b)
    double M[kMax * kMax];
    unpack_lower(M, s, n);
    int k = 0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b) {
            double t = 0;
            for (int e = 0; e < n; ++e) t += (gS[a * n + e] + gS[e * n + a]) / (d[a] * d[e]) * M[e * n + b];
            ds[k++] = T(c * t);
        }
}

template <typename T>
void gain_head_forward(double* K, const T* o, const double* dx, const double* dy, int n, int m, double rate) {
    for (int a = 0; a < n; ++a)
        for (int j = 0; j < m; ++j) K[a * m + j] = rate * dx[a] * double(o[a * m + j]) / dy[j];
}

template <typename T>
void gain_head_backward(T* d_o, const double* gK, const double* dx, const double* dy, int n, int m, double rate) {
    for (int a = 0; a < n; ++a)
        for (int j = 0; j < m; ++j) d_o[a * m + j] = T(rate * dx[a] * gK[a * m + j] / dy[j]);
}

namespace {
// Knot interval of time t: knots j and j + 1, weight w of knot j + 1, slope 1/h (0 after the span: S constant).
struct KnotAt {
    int j = 0;
    double w = 0, slope = 0;
};
KnotAt knot_at(double t, const GainSpec& g) {
    KnotAt k;
    const int J = g.knots;
    if (g.knot_ratio != 1.0 && J > 1) {  // graded knots: the interval from the inverse of knot_time, then checked
        if (!(t > 0)) return {0, 0.0, 1.0 / g.knot_time(1)};
        if (t >= g.knot_span) return {J - 1, 1.0, 0.0};
        const double lq = std::log(g.knot_ratio) / (J - 1);
        k.j = std::max(0, std::min(J - 1, int(std::log1p(t * std::expm1(J * lq) / g.knot_span) / lq)));
        while (k.j > 0 && t < g.knot_time(k.j)) --k.j;
        while (k.j < J - 1 && t >= g.knot_time(k.j + 1)) ++k.j;
        const double t0 = g.knot_time(k.j), h = g.knot_time(k.j + 1) - t0;
        k.w = (t - t0) / h;
        k.slope = 1.0 / h;
        return k;
    }
    const double h = g.knot_span / J;
    if (!(t > 0)) return {0, 0.0, 1.0 / h};
    if (t >= g.knot_span) return {J - 1, 1.0, 0.0};
    const double u = t / h;
    k.j = std::min(J - 1, int(u));
    k.w = u - k.j;
    k.slope = 1.0 / h;
    return k;
}

// M = diag(exp(v_aa)) + strict tril(v) and Md = dM/dt from the packed interpolated v and its rate vd
void unpack_tv(double* M, double* Md, const double* v, const double* vd, int n) {
    int k = 0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) M[a * n + b] = Md[a * n + b] = 0.0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b, ++k) {
            if (a == b) {
                M[a * n + a] = std::exp(v[k]);
                Md[a * n + a] = M[a * n + a] * vd[k];
            } else {
                M[a * n + b] = v[k];
                Md[a * n + b] = vd[k];
            }
        }
}

template <typename T>
void knot_values(double* v, double* vd, const T* s, const KnotAt& k, int np) {
    const T* s0 = s + std::int64_t(k.j) * np;
    const T* s1 = s0 + np;
    for (int e = 0; e < np; ++e) {
        v[e] = (1.0 - k.w) * double(s0[e]) + k.w * double(s1[e]);
        vd[e] = (double(s1[e]) - double(s0[e])) * k.slope;
    }
}

// Cholesky S = L L' (S positive definite by construction) and X <- S^-1 X for X [n x cols]
void chol(double* L, const double* S, int n) {
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b) {
            double t = S[a * n + b];
            for (int k = 0; k < b; ++k) t -= L[a * n + k] * L[b * n + k];
            L[a * n + b] = a == b ? std::sqrt(std::max(t, 1e-300)) : t / L[b * n + b];
        }
}
// Row by row over all columns at once (the columns are independent; each element sees the same operations in the
// same order as a column-by-column solve, so the bits are those of one)
void chol_solve(double* X, const double* L, int n, int cols) {
    double t[kMax];
    for (int a = 0; a < n; ++a) {
        for (int c = 0; c < cols; ++c) t[c] = X[a * cols + c];
        for (int k = 0; k < a; ++k) {
            const double l = L[a * n + k];
            for (int c = 0; c < cols; ++c) t[c] -= l * X[k * cols + c];
        }
        const double d = L[a * n + a];
        for (int c = 0; c < cols; ++c) X[a * cols + c] = t[c] / d;
    }
    for (int a = n - 1; a >= 0; --a) {
        for (int c = 0; c < cols; ++c) t[c] = X[a * cols + c];
        for (int k = a + 1; k < n; ++k) {
            const double l = L[k * n + a];
            for (int c = 0; c < cols; ++c) t[c] -= l * X[k * cols + c];
        }
        const double d = L[a * n + a];
        for (int c = 0; c < cols; ++c) X[a * cols + c] = t[c] / d;
    }
}
}  // namespace

namespace {
// storage_tv_forward, keeping M(t) and Md(t) [n x n] for the backward pass (M, Md must not be null)
template <typename T>
void storage_tv_parts(double* S, double* Sdot, double* M, double* Md, const T* s, double t, const GainSpec& g, int n) {
    const int np = n * (n + 1) / 2;
    double v[kMax * (kMax + 1) / 2], vd[kMax * (kMax + 1) / 2];
    knot_values(v, vd, s, knot_at(t, g), np);
    unpack_tv(M, Md, v, vd, n);
    const double c = g.storage_scale, eps = g.eps;
    const double* d = g.storage_dx();
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b) {
            double mm = 0, md = 0;
            for (int k = 0; k <= b; ++k) {
                mm += M[a * n + k] * M[b * n + k];
                md += Md[a * n + k] * M[b * n + k] + M[a * n + k] * Md[b * n + k];
            }
            const double sc = c / (d[a] * d[b]);
            if (S != nullptr) S[a * n + b] = S[b * n + a] = sc * (mm + (a == b ? eps : 0.0));
            if (Sdot != nullptr) Sdot[a * n + b] = Sdot[b * n + a] = sc * md;
        }
}

// storage_tv_backward with M(t), Md(t) from storage_tv_parts
void storage_tv_back_parts(double* d0, double* d1, int* j, const double* gS, const double* gSd, const double* M,
                           const double* Md, double t, const GainSpec& g, int n) {
    // S = c D^-1 (M M' + eps I) D^-1, Sdot = c D^-1 (Md M' + M Md') D^-1:
    // dL/dM = c (G + G') M + c (Gd + Gd') Md, dL/dMd = c (Gd + Gd') M  (G = D^-1 gS D^-1, Gd = D^-1 gSd D^-1)
    const KnotAt k = knot_at(t, g);
    const double c = g.storage_scale;
    const double* d = g.storage_dx();
    double Gs[kMax * kMax], Gd[kMax * kMax];  // (G + G')_aq and (Gd + Gd')_aq, once per (a, q)
    for (int a = 0; a < n; ++a)
        for (int q = 0; q < n; ++q) {
            const double dd = d[a] * d[q];
            Gs[a * n + q] = gS != nullptr ? (gS[a * n + q] + gS[q * n + a]) / dd : 0.0;
            Gd[a * n + q] = gSd != nullptr ? (gSd[a * n + q] + gSd[q * n + a]) / dd : 0.0;
        }
    int e = 0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b, ++e) {
            double gm = 0, gmd = 0;
            for (int q = 0; q < n; ++q) {
                const double gs = Gs[a * n + q], gd = Gd[a * n + q];
                gm += gs * M[q * n + b] + gd * Md[q * n + b];
                gmd += gd * M[q * n + b];
            }
            gm *= c;
            gmd *= c;
            // M_ab = exp(v) on the diagonal (Md_aa = exp(v) vd), v itself below it
            double gv = gm, gvd = gmd;
            if (a == b) {
                gv = gm * M[a * n + a] + gmd * Md[a * n + a];
                gvd = gmd * M[a * n + a];
            }
            d0[e] = (1.0 - k.w) * gv - k.slope * gvd;
            d1[e] = k.w * gv + k.slope * gvd;
        }
    *j = k.j;
}
}  // namespace

template <typename T>
void storage_tv_forward(double* S, double* Sdot, const T* s, double t, const GainSpec& g, int n) {
    double M[kMax * kMax], Md[kMax * kMax];
    storage_tv_parts(S, Sdot, M, Md, s, t, g, n);
}

template <typename T>
void storage_tv_backward(double* d0, double* d1, int* j, const double* gS, const double* gSd, const T* s, double t,
                         const GainSpec& g, int n) {
    double S[kMax * kMax], M[kMax * kMax], Md[kMax * kMax];
    storage_tv_parts(S, static_cast<double*>(nullptr), M, Md, s, t, g, n);
    storage_tv_back_parts(d0, d1, j, gS, gSd, M, Md, t, g, n);
}

template <typename T>
void gain_riccati_forward(double* K, const T* o, const double* S, const double* Hx, const GainSpec& g, int n, int m,
                          double rho, double* Lout) {
    double Lloc[kMax * kMax];
    double* L = Lout != nullptr ? Lout : Lloc;
    for (int a = 0; a < n; ++a)
        for (int q = 0; q < m; ++q)
            K[a * m + q] = rho * (Hx[q * n + a] + (g.corr.empty() ? double(o[a * m + q]) * g.dy[q] / g.dx[a]
                                                                   : double(o[a * m + q]) * g.corr[a * m + q]));
    chol(L, S, n);
    chol_solve(K, L, n, m);
}

template <typename T>
void gain_riccati_backward(T* d_o, double* gS, const double* gK, const double* K, const double* S, const GainSpec& g,
                           int n, int m, double rho, const double* Lin) {
    double Lloc[kMax * kMax], G[kMax * kMax];
    for (int e = 0; e < n * m; ++e) G[e] = gK[e];
    const double* L = Lin;
    if (L == nullptr) {
        chol(Lloc, S, n);
        L = Lloc;
    }
    chol_solve(G, L, n, m);  // dL/d(rho (Hx' + ...)) = S^-1 gK
    for (int a = 0; a < n; ++a)
        for (int c = 0; c < n; ++c) {
            double t = 0;
            for (int q = 0; q < m; ++q) t += G[a * m + q] * K[c * m + q];
            gS[a * n + c] -= t;
        }
    for (int a = 0; a < n; ++a)
        for (int q = 0; q < m; ++q) d_o[a * m + q] = T(g.corr.empty() ? rho * G[a * m + q] * g.dy[q] / g.dx[a] : rho * G[a * m + q] * g.corr[a * m + q]);
}

namespace {
// The Kalman-form head's shared part: P from o, W = H P H' + diag(dy)^2 and its Cholesky factor L [m x m], and
// At = W^-1 H P = A' [m x n] (A = P H' W^-1; H P is formed in At first). dinv [n] = 1 / dx, P's scale.
template <typename T>
void kalman_parts(double* dinv, double* L, double* At, const T* o, const double* Hx, const GainSpec& g, int n, int m) {
    double P[kMax * kMax], W[kMax * kMax];
    for (int a = 0; a < n; ++a) dinv[a] = 1.0 / g.dx[a];
    storage_forward(P, o, dinv, n, g.kalman_scale, g.eps);  // c D (M M' + eps I) D
    for (int q = 0; q < m; ++q)
        for (int a = 0; a < n; ++a) {
            double t = 0;
            for (int c = 0; c < n; ++c) t += P[a * n + c] * Hx[q * n + c];
            At[q * n + a] = t;  // (P H')' = H P
        }
    for (int q = 0; q < m; ++q)
        for (int r = 0; r <= q; ++r) {
            double t = 0;
            for (int a = 0; a < n; ++a) t += Hx[q * n + a] * At[r * n + a];
            if (q == r) t += g.dy[q] * g.dy[q];
            W[q * m + r] = W[r * m + q] = t;
        }
    chol(L, W, m);
    chol_solve(At, L, m, n);
}
}  // namespace

template <typename T>
void gain_kalman_forward(double* K, double* A, const T* o, const double* Fx, const double* Hx, const GainSpec& g,
                         int n, int m) {
    double dinv[kMax], L[kMax * kMax], At[kMax * kMax];
    kalman_parts(dinv, L, At, o, Hx, g, n, m);
    for (int a = 0; a < n; ++a)
        for (int q = 0; q < m; ++q) {
            double t = 0;
            for (int c = 0; c < n; ++c) t += Fx[a * n + c] * At[q * n + c];
            K[a * m + q] = t;
        }
    if (A != nullptr)
        for (int a = 0; a < n; ++a)
            for (int q = 0; q < m; ++q) A[a * m + q] = At[q * n + a];
}

template <typename T>
void gain_kalman_backward(T* d_o, const double* gK, const T* o, const double* Fx, const double* Hx, const GainSpec& g,
                          int n, int m) {
    // dK = F (I - A H) dP H' W^-1, so dL/dP = (I - H'A') X H with X = F'gK W^-1 [n x m]
    double dinv[kMax], L[kMax * kMax], At[kMax * kMax], Xt[kMax * kMax], AX[kMax * kMax], Y[kMax * kMax];
    double gP[kMax * kMax];
    kalman_parts(dinv, L, At, o, Hx, g, n, m);
    for (int q = 0; q < m; ++q)
        for (int c = 0; c < n; ++c) {
            double t = 0;
            for (int a = 0; a < n; ++a) t += Fx[a * n + c] * gK[a * m + q];
            Xt[q * n + c] = t;  // (F'gK)'
        }
    chol_solve(Xt, L, m, n);  // X' = W^-1 (F'gK)'
    for (int q = 0; q < m; ++q)
        for (int r = 0; r < m; ++r) {
            double t = 0;
            for (int c = 0; c < n; ++c) t += At[q * n + c] * Xt[r * n + c];
            AX[q * m + r] = t;  // (A'X)_qr
        }
    for (int a = 0; a < n; ++a)
        for (int r = 0; r < m; ++r) {
            double t = Xt[r * n + a];
            for (int q = 0; q < m; ++q) t -= Hx[q * n + a] * AX[q * m + r];
            Y[a * m + r] = t;  // (X - H'A'X)_ar
        }
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) {
            double t = 0;
            for (int r = 0; r < m; ++r) t += Y[a * m + r] * Hx[r * n + b];
            gP[a * n + b] = t;
        }
    storage_backward(d_o, gP, o, dinv, n, g.kalman_scale);
}

namespace {
// rows first .. first + B of the network input (D0 entries a row, GainSpec::input_count): the estimate of sample
// idx[row * G] (G = 1: idx[row])
template <typename T>
void load_z(T* in, const double* z, const std::int64_t* idx, std::int64_t first, int B, int D0, int G = 1) {
    for (int s = 0; s < B; ++s) {
        const std::int64_t i = idx ? idx[(first + s) * G] : first + s;
        for (int a = 0; a < D0; ++a) in[s * D0 + a] = T(z[i * D0 + a]);
    }
}
}  // namespace

int gain_step_chunks(int M, const StepConfig& cfg) {
    const int G = std::max(1, cfg.gain.group), C = (cfg.chunk + G - 1) / G;
    return (M / G + C - 1) / C;
}

template <typename T>
StepLoss gain_step_gradient(T* grad, const T* theta, const HjieSystemView& sys, const double* z,
                            const std::int64_t* idx, int M, const StepConfig& cfg, StepWorkspace<T>& ws,
                            const StepSplit* split) {
    const MlpShape& sh = cfg.shape;
    const GainSpec& gs = cfg.gain;
    // rows: one per estimate, each with G samples (errors) idx[r G .. r G + G - 1] that share its z, t and Hx; a
    // chunk holds about cfg.chunk samples, C = ceil(cfg.chunk / G) rows (as many chunks, and threads, for any G)
    const int G = std::max(1, gs.group), R = M / G;
    const int n = sys.n, m = sys.m, C = (cfg.chunk + G - 1) / G, O = sh.outputs(), D0 = sh.inputs();
    assert(M % G == 0);
    const int chunks = gain_step_chunks(M, cfg);
    // this process's chunks [c_first, c_last) (all of them without a split), and where each process's rows start
    const int ranks = split != nullptr ? split->ranks : 1, rank = split != nullptr ? split->rank : 0;
    const int c_first = step_split_begin(chunks, rank, ranks), c_last = step_split_begin(chunks, rank + 1, ranks);
    std::vector<std::int64_t> row_begin, sample_begin;
    for (int r = 0; ranks > 1 && r <= ranks; ++r) {
        row_begin.push_back(std::min<std::int64_t>(R, std::int64_t(step_split_begin(chunks, r, ranks)) * C));
        sample_begin.push_back(row_begin.back() * G);
    }
    const std::int64_t P = sh.param_count(), Ps = step_partial_stride(sh), As = step_acts_stride(cfg);
    const bool tv = gs.knots > 0;  // time-varying storage and the Riccati-form head (section 16.7)
    const int np = n * (n + 1) / 2;
    assert(!tv || (sys.t != nullptr && sys.Hx != nullptr));
    assert(!gs.kalman || (!tv && sys.Fx != nullptr && sys.Hx != nullptr));
    ws.reserve(cfg, M);  // M rows' room: as many chunks as M samples make
    if (std::int64_t(ws.partial.size()) < chunks * Ps) ws.partial.assign(chunks * Ps, T(0));
    gemm_prepare(sh.gemm);
    const T* wt = step_pack_weights(ws.pack, theta, sh);
    GainLossParams lp = gs.loss;
    lp.xt0 = gs.xt0.data();
    lp.dx = gs.dx.data();
    const double initial_weight = lp.initial_weight;
    if (tv) lp.initial_weight = 0.0;  // the V(x~(0), 0) term is one per step, below, not per sample
    const T* sparams = theta + P;
    double S[kMax * kMax];
    if (!tv) storage_forward(S, sparams, gs.dx.data(), n, gs.storage_scale, gs.eps);
    if (tv && ws.storage.size() < std::size_t(R) * 5 * n * n) ws.storage.resize(std::size_t(R) * 5 * n * n);
    std::vector<GainSampleValue> vals(static_cast<std::size_t>(M));

    // pass 1: forward and gain head per row, loss pieces per sample
#pragma omp parallel for schedule(static)
    for (int c = c_first; c < c_last; ++c) {
        const int b0 = c * C, B = std::min(C, R - b0);
        T* in = ws.input.data() + std::int64_t(b0) * D0;
        T* acts = ws.acts.data() + std::int64_t(c) * As;
        load_z(in, z, idx, b0, B, D0, G);
        mlp_forward(acts, theta, in, B, sh, wt);
        const T* out = acts + sh.act_offset(sh.layers(), B);
        for (int s = 0; s < B; ++s) {
            const int r = b0 + s;
            const std::int64_t i0 = idx[std::int64_t(r) * G];
            double* K = ws.K.data() + std::int64_t(r) * n * m;
            if (tv) {  // S(t), dS/dt, its Cholesky factor, M(t) and dM/dt of the row, kept for pass 2 (the same bits)
                double* st = ws.storage.data() + std::int64_t(r) * 5 * n * n;
                double *Si = st, *Sd = st + n * n, *L = st + 2 * n * n, *Mt = st + 3 * n * n, *Mdt = st + 4 * n * n;
                storage_tv_parts(Si, Sd, Mt, Mdt, sparams, sys.t[i0], gs, n);
                gain_riccati_forward(K, out + std::int64_t(s) * O, Si, sys.Hx + i0 * m * n, gs, n, m, lp.rho, L);
                double Km[kMax * kMax];  // the gain the filter runs: K with its structural zeros (ws.K keeps K)
                gs.gain_mask(Km, K, n, m);
                for (int g = 0; g < G; ++g)
                    vals[std::int64_t(r) * G + g] = gain_sample_forward(Km, Si, sys, idx[std::int64_t(r) * G + g], lp, Sd);
            } else {
                if (gs.kalman)
                    gain_kalman_forward(K, static_cast<double*>(nullptr), out + std::int64_t(s) * O,
                                        sys.Fx + i0 * n * n, sys.Hx + i0 * m * n, gs, n, m);
                else
                    gain_head_forward(K, out + std::int64_t(s) * O, gs.dx.data(), gs.dy.data(), n, m, gs.rate);
                double Km[kMax * kMax];
                gs.gain_mask(Km, K, n, m);
                for (int g = 0; g < G; ++g)
                    vals[std::int64_t(r) * G + g] = gain_sample_forward(Km, S, sys, idx[std::int64_t(r) * G + g], lp);
            }
        }
    }
    // every process needs every sample's loss pieces: the loss (and so each dL/dK) is a function of all of them
    if (ranks > 1) split->allgather(vals.data(), sizeof(GainSampleValue), sample_begin.data());
    double sum_hinge = 0, sum_h2 = 0;
    for (int s = 0; s < M; ++s) {
        sum_hinge += vals[s].hinge;
        sum_h2 += vals[s].h2;
    }
    StepLoss loss;
    loss.hinge = std::sqrt(sum_hinge / M);
    loss.h2 = sum_h2 / M;
    double S0[kMax * kMax];
    const bool initial = tv && initial_weight > 0;
    if (initial) {  // E V(x~(0), 0) / T = tr(S(0) P0) / T, P0 = D^2: the initial error's share of the H2 bound
        storage_tv_forward(S0, static_cast<double*>(nullptr), sparams, 0.0, gs, n);
        double v0 = 0;
        for (int a = 0; a < n; ++a) v0 += S0[a * n + a] * gs.dx[a] * gs.dx[a];
        loss.h2 += initial_weight * v0 / (lp.horizon * lp.h2_reference);
    }
    loss.loss = loss.hinge + gs.h2_weight * loss.h2;
    const double d_hinge = loss.hinge > 0 ? 1.0 / (2.0 * M * loss.hinge) : 0.0;
    const double d_h2 = gs.h2_weight / M;
    std::vector<double> knot_part(tv ? static_cast<std::size_t>(R) * 2 * np : 0);
    std::vector<int> knot_j(tv ? R : 0);

    // pass 2: dL/dK summed over the row's samples -> dL/do -> partial dL/dtheta per chunk; dL/dS per row (ws.P, or
    // the knots' shares). Both are linear in dL/dK and dL/dS, so one head backward per row serves its G samples.
#pragma omp parallel for schedule(static)
    for (int c = c_first; c < c_last; ++c) {
        const int b0 = c * C, B = std::min(C, R - b0);
        const T* in = ws.input.data() + std::int64_t(b0) * D0;
        const T* acts = ws.acts.data() + std::int64_t(c) * As;
        const T* out = acts + sh.act_offset(sh.layers(), B);  // the network outputs of pass 1 (Kalman-form head)
        T* dout = ws.dout.data() + std::int64_t(b0) * O;
        double gK[kMax * kMax], gKg[kMax * kMax], gSd[kMax * kMax];
        for (int s = 0; s < B; ++s) {
            const int r = b0 + s;
            const std::int64_t i0 = idx[std::int64_t(r) * G];
            const double* K = ws.K.data() + std::int64_t(r) * n * m;
            double Km[kMax * kMax];  // the samples saw mask .* K: their dL/dK is masked before the head's backward
            gs.gain_mask(Km, K, n, m);
            double* gSs = ws.P.data() + std::int64_t(r) * n * n;
            for (int e = 0; e < n * n; ++e) gSs[e] = 0.0;
            if (tv) {
                for (int e = 0; e < n * n; ++e) gSd[e] = 0.0;
                const double* st = ws.storage.data() + std::int64_t(r) * 5 * n * n;
                const double *Si = st, *Sd = st + n * n, *L = st + 2 * n * n, *Mt = st + 3 * n * n, *Mdt = st + 4 * n * n;
                gain_sample_backward(gK, gSs, Km, Si, sys, i0, lp, d_hinge, d_h2, Sd, gSd);
                for (int g = 1; g < G; ++g) {
                    gain_sample_backward(gKg, gSs, Km, Si, sys, idx[std::int64_t(r) * G + g], lp, d_hinge, d_h2, Sd, gSd);
                    for (int e = 0; e < n * m; ++e) gK[e] += gKg[e];
                }
                gs.gain_mask(gK, gK, n, m);
                gain_riccati_backward(dout + std::int64_t(s) * O, gSs, gK, K, Si, gs, n, m, lp.rho, L);
                double* kp = knot_part.data() + std::int64_t(r) * 2 * np;
                storage_tv_back_parts(kp, kp + np, &knot_j[r], gSs, gSd, Mt, Mdt, sys.t[i0], gs, n);
            } else {
                gain_sample_backward(gK, gSs, Km, S, sys, i0, lp, d_hinge, d_h2);
                for (int g = 1; g < G; ++g) {
                    gain_sample_backward(gKg, gSs, Km, S, sys, idx[std::int64_t(r) * G + g], lp, d_hinge, d_h2);
                    for (int e = 0; e < n * m; ++e) gK[e] += gKg[e];
                }
                gs.gain_mask(gK, gK, n, m);
                if (gs.kalman)
                    gain_kalman_backward(dout + std::int64_t(s) * O, gK, out + std::int64_t(s) * O, sys.Fx + i0 * n * n,
                                         sys.Hx + i0 * m * n, gs, n, m);
                else
                    gain_head_backward(dout + std::int64_t(s) * O, gK, gs.dx.data(), gs.dy.data(), n, m, gs.rate);
            }
        }
        T* part = ws.partial.data() + std::int64_t(c) * Ps;
        T* scratch = ws.scratch.data() + std::int64_t(c) * sh.scratch_size(C);
        mlp_backward(part, static_cast<T*>(nullptr), theta, in, acts, dout, B, sh, scratch, /*overwrite=*/true, wt);
    }
    // every chunk's partial and every row's storage gradient to every process (all-gathers: the sums below keep
    // one process's order)
    if (ranks > 1) {
        std::vector<std::int64_t> chunk_begin;
        for (int r = 0; r <= ranks; ++r) chunk_begin.push_back(step_split_begin(chunks, r, ranks));
        split->allgather(ws.partial.data(), Ps * std::int64_t(sizeof(T)), chunk_begin.data());
        if (tv) {
            split->allgather(knot_part.data(), 2 * np * std::int64_t(sizeof(double)), row_begin.data());
            split->allgather(knot_j.data(), sizeof(int), row_begin.data());
        } else {
            split->allgather(ws.P.data(), std::int64_t(n) * n * std::int64_t(sizeof(double)), row_begin.data());
        }
    }
    sum_chunk_partials(grad, ws.partial.data(), chunks, Ps, P);  // chunk order (train_step.hpp)
    if (tv) {  // the knots' gradients, summed in sample order (bits independent of the thread count)
        std::vector<double> gk(static_cast<std::size_t>(gs.knots + 1) * np, 0.0);
        for (int s = 0; s < R; ++s) {
            const double* kp = knot_part.data() + std::int64_t(s) * 2 * np;
            double* g0 = gk.data() + std::int64_t(knot_j[s]) * np;
            for (int e = 0; e < 2 * np; ++e) g0[e] += kp[e];
        }
        if (initial) {
            double gS0[kMax * kMax], d0[kMax * (kMax + 1) / 2], d1[kMax * (kMax + 1) / 2];
            const double w = gs.h2_weight * initial_weight / (lp.horizon * lp.h2_reference);
            for (int a = 0; a < n; ++a)
                for (int b = 0; b < n; ++b) gS0[a * n + b] = a == b ? w * gs.dx[a] * gs.dx[a] : 0.0;
            int j0 = 0;
            storage_tv_backward(d0, d1, &j0, gS0, static_cast<const double*>(nullptr), sparams, 0.0, gs, n);
            for (int e = 0; e < np; ++e) {
                gk[std::int64_t(j0) * np + e] += d0[e];
                gk[std::int64_t(j0 + 1) * np + e] += d1[e];
            }
        }
        for (std::size_t e = 0; e < gk.size(); ++e) grad[P + std::int64_t(e)] = T(gk[e]);
        gs.hold_storage(grad + P, n);
        return loss;
    }
    // the storage's gradient: dL/dS summed in sample order, then through S = c D^-1 (M M' + eps I) D^-1
    double gS[kMax * kMax] = {};
    for (int s = 0; s < R; ++s) {
        const double* gSs = ws.P.data() + std::int64_t(s) * n * n;
        for (int e = 0; e < n * n; ++e) gS[e] += gSs[e];
    }
    storage_backward(grad + P, gS, sparams, gs.dx.data(), n, gs.storage_scale);
    gs.hold_storage(grad + P, n);
    return loss;
}

template <typename T>
void gain_network_eval(double* K, const T* theta, const double* z, const double* Hx, const double* t,
                       std::int64_t count, const StepConfig& cfg, StepWorkspace<T>& ws, const double* Fx, double* A,
                       const T* pack) {
    const MlpShape& sh = cfg.shape;
    const GainSpec& gs = cfg.gain;
    const int n = cfg.head.n, m = gs.m, C = cfg.chunk, O = sh.outputs(), D0 = sh.inputs();
    if (count <= 0) return;
    const bool tv = gs.knots > 0;
    assert(!tv || (t != nullptr && Hx != nullptr));
    assert(!gs.kalman || (Fx != nullptr && Hx != nullptr));
    ws.reserve(cfg, static_cast<int>(count));
    gemm_prepare(sh.gemm);
    const T* wt = pack != nullptr ? pack : step_pack_weights(ws.pack, theta, sh);
    const int chunks = static_cast<int>((count + C - 1) / C);
#pragma omp parallel for schedule(static) if (chunks > 1)
    for (int c = 0; c < chunks; ++c) {
        const std::int64_t b0 = std::int64_t(c) * C;
        const int B = static_cast<int>(std::min<std::int64_t>(C, count - b0));
        T* in = ws.input.data() + b0 * D0;
        T* acts = ws.acts.data() + std::int64_t(c) * step_acts_stride(cfg);
        load_z<T>(in, z, nullptr, b0, B, D0);
        mlp_forward(acts, theta, in, B, sh, wt);
        const T* out = acts + sh.act_offset(sh.layers(), B);
        double S[kMax * kMax];
        for (int s = 0; s < B; ++s) {
            if (tv) {
                storage_tv_forward(S, static_cast<double*>(nullptr), theta + sh.param_count(), t[b0 + s], gs, n);
                gain_riccati_forward(K + (b0 + s) * n * m, out + std::int64_t(s) * O, S, Hx + (b0 + s) * m * n, gs,
                                     n, m, gs.loss.rho);
            } else if (gs.kalman) {
                gain_kalman_forward(K + (b0 + s) * n * m, A != nullptr ? A + (b0 + s) * n * m : nullptr,
                                    out + std::int64_t(s) * O, Fx + (b0 + s) * n * n, Hx + (b0 + s) * m * n, gs, n, m);
            } else {
                gain_head_forward(K + (b0 + s) * n * m, out + std::int64_t(s) * O, gs.dx.data(), gs.dy.data(), n, m,
                                  gs.rate);
            }
            gs.gain_mask(K + (b0 + s) * n * m, K + (b0 + s) * n * m, n, m);
        }
    }
}

template <typename T>
void gain_storage_eval(double* S, double* Sdot, const T* theta, double t, const StepConfig& cfg) {
    const GainSpec& gs = cfg.gain;
    const int n = cfg.head.n;
    const T* sp = theta + cfg.shape.param_count();
    if (gs.knots > 0) {
        storage_tv_forward(S, Sdot, sp, t, gs, n);
        return;
    }
    if (S != nullptr) storage_forward(S, sp, gs.dx.data(), n, gs.storage_scale, gs.eps);
    if (Sdot != nullptr)
        for (int e = 0; e < n * n; ++e) Sdot[e] = 0.0;
}

namespace {
// X <- A^-1 X for A [n x n] (copied), X [n x cols]: Gauss-Jordan with partial pivoting (the naive twin's solve)
void gauss_solve(const double* A, double* X, int n, int cols) {
    double a[kMax * kMax];
    for (int e = 0; e < n * n; ++e) a[e] = A[e];
    for (int k = 0; k < n; ++k) {
        int p = k;
        for (int r = k + 1; r < n; ++r)
            if (std::fabs(a[r * n + k]) > std::fabs(a[p * n + k])) p = r;
        for (int c = 0; c < n; ++c) std::swap(a[k * n + c], a[p * n + c]);
        for (int c = 0; c < cols; ++c) std::swap(X[k * cols + c], X[p * cols + c]);
        for (int r = 0; r < n; ++r) {
            if (r == k) continue;
            const double f = a[r * n + k] / a[k * n + k];
            for (int c = 0; c < n; ++c) a[r * n + c] -= f * a[k * n + c];
            for (int c = 0; c < cols; ++c) X[r * cols + c] -= f * X[k * cols + c];
        }
    }
    for (int k = 0; k < n; ++k)
        for (int c = 0; c < cols; ++c) X[k * cols + c] /= a[k * n + k];
}

// S(t) and dS/dt from the knots by the definition: M(t) = diag(exp(v)) + strict tril(v), v linear in t between
// knots (constant after the span), S = c Ds^-1 (M M' + eps I) Ds^-1, Sdot = c Ds^-1 (Md M' + M Md') Ds^-1
template <typename T>
void naive_storage_tv(double* S, double* Sd, const T* s, double t, const GainSpec& g, int n) {
    const int np = n * (n + 1) / 2, J = g.knots;
    // the knot intervals one by one: h_0 = span / J evenly, else h_0 q^j with sum span (a sum, not knot_time's form)
    const double q = J > 1 && g.knot_ratio != 1.0 ? std::pow(g.knot_ratio, 1.0 / (J - 1)) : 1.0;
    const double h0 = q == 1.0 ? g.knot_span / J : g.knot_span * (q - 1) / (std::pow(q, J) - 1);
    int j = 0;
    double w = 0, slope = 1.0 / h0;
    if (t >= g.knot_span) {
        j = J - 1;
        w = 1.0;
        slope = 0.0;
    } else if (t > 0 && q == 1.0) {
        j = std::min(J - 1, int(t / h0));
        w = t / h0 - j;
    } else if (t > 0) {
        double tj = 0, h = h0;
        while (j < J - 1 && t >= tj + h) {
            tj += h;
            h *= q;
            ++j;
        }
        w = (t - tj) / h;
        slope = 1.0 / h;
    }
    double Mt[kMax * kMax] = {}, Md[kMax * kMax] = {};
    int e = 0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b, ++e) {
            const double v0 = double(s[j * np + e]), v1 = double(s[(j + 1) * np + e]);
            const double v = (1 - w) * v0 + w * v1, vd = (v1 - v0) * slope;
            Mt[a * n + b] = a == b ? std::exp(v) : v;
            Md[a * n + b] = a == b ? std::exp(v) * vd : vd;
        }
    const double* d = g.storage_dx();
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) {
            double mm = 0, md = 0;
            for (int k = 0; k < n; ++k) {
                mm += Mt[a * n + k] * Mt[b * n + k];
                md += Md[a * n + k] * Mt[b * n + k] + Mt[a * n + k] * Md[b * n + k];
            }
            S[a * n + b] = g.storage_scale * (mm + (a == b ? g.eps : 0.0)) / (d[a] * d[b]);
            Sd[a * n + b] = g.storage_scale * md / (d[a] * d[b]);
        }
}

// K = rho S^-1 (Hx' + o .* w) (the Riccati head by its definition, w from GainSpec::corr or dy_j / dx_a)
template <typename T>
void naive_riccati(double* K, const T* o, const double* S, const double* Hx, const GainSpec& g, int n, int m,
                   double rho) {
    for (int a = 0; a < n; ++a)
        for (int q = 0; q < m; ++q) {
            const double w = g.corr.empty() ? g.dy[q] / g.dx[a] : g.corr[a * m + q];
            K[a * m + q] = rho * (Hx[q * n + a] + double(o[a * m + q]) * w);
        }
    gauss_solve(S, K, n, m);
}

// The Kalman-form head by its definition: P = c D (M M' + eps I) D, Wi = (H P H' + diag(dy)^2)^-1 by Gauss-Jordan,
// A = P H' Wi, K = F A; with gK (not null) also d_o from dL/dP = (I - H'A') F'gK Wi H.
template <typename T>
void naive_kalman(double* K, T* d_o, const double* gK, const T* o, const double* F, const double* H, const GainSpec& g,
                  int n, int m) {
    double dinv[kMax], P[kMax * kMax], W[kMax * kMax], Wi[kMax * kMax], A[kMax * kMax];
    for (int a = 0; a < n; ++a) dinv[a] = 1.0 / g.dx[a];
    storage_forward(P, o, dinv, n, g.kalman_scale, g.eps);
    for (int q = 0; q < m; ++q)
        for (int r = 0; r < m; ++r) {
            double t = q == r ? g.dy[q] * g.dy[q] : 0.0;
            for (int a = 0; a < n; ++a)
                for (int c = 0; c < n; ++c) t += H[q * n + a] * P[a * n + c] * H[r * n + c];
            W[q * m + r] = t;
            Wi[q * m + r] = q == r ? 1.0 : 0.0;
        }
    gauss_solve(W, Wi, m, m);
    for (int a = 0; a < n; ++a)
        for (int q = 0; q < m; ++q) {
            double t = 0;
            for (int c = 0; c < n; ++c)
                for (int r = 0; r < m; ++r) t += P[a * n + c] * H[r * n + c] * Wi[r * m + q];
            A[a * m + q] = t;
        }
    for (int a = 0; a < n; ++a)
        for (int q = 0; q < m; ++q) {
            double t = 0;
            for (int c = 0; c < n; ++c) t += F[a * n + c] * A[c * m + q];
            K[a * m + q] = t;
        }
    if (gK == nullptr) return;
    double X[kMax * kMax], gP[kMax * kMax];
    for (int c = 0; c < n; ++c)
        for (int q = 0; q < m; ++q) {
            double t = 0;
            for (int a = 0; a < n; ++a)
                for (int r = 0; r < m; ++r) t += F[a * n + c] * gK[a * m + r] * Wi[r * m + q];
            X[c * m + q] = t;
        }
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) {
            double t = 0;
            for (int q = 0; q < m; ++q) {
                double ih = X[a * m + q];  // ((I - H'A') X)_aq
                for (int c = 0; c < n; ++c)
                    for (int r = 0; r < m; ++r) ih -= H[r * n + a] * A[c * m + r] * X[c * m + q];
                t += ih * H[q * n + b];
            }
            gP[a * n + b] = t;
        }
    storage_backward(d_o, gP, o, dinv, n, g.kalman_scale);
}
}  // namespace

template <typename T>
StepLoss gain_step_gradient_naive(T* grad, const T* theta, const HjieSystemView& sys, const double* z,
                                  const std::int64_t* idx, int M, const StepConfig& cfg) {
    const MlpShape& sh = cfg.shape;
    const GainSpec& gs = cfg.gain;
    const int n = sys.n, m = sys.m, O = sh.outputs(), np = n * (n + 1) / 2;
    const std::int64_t P = sh.param_count();
    const bool tv = gs.knots > 0;
    GainLossParams lp = gs.loss;
    lp.xt0 = gs.xt0.data();
    lp.dx = gs.dx.data();
    const double initial_weight = lp.initial_weight;
    if (tv) lp.initial_weight = 0.0;
    const T* sp = theta + P;
    std::vector<T> acts(static_cast<std::size_t>(sh.act_per_sample())), in(static_cast<std::size_t>(sh.inputs()));
    std::vector<T> dout(static_cast<std::size_t>(O)), gtheta(static_cast<std::size_t>(P), T(0));
    double Sc[kMax * kMax];
    if (!tv) storage_forward(Sc, sp, gs.dx.data(), n, gs.storage_scale, gs.eps);
    // the sample's K, S and dS/dt, from scratch each time it is needed
    auto sample = [&](int s, double* K, double* S, double* Sd) {
        const std::int64_t i = idx[s];
        for (int a = 0; a < sh.inputs(); ++a) in[a] = T(z[i * sh.inputs() + a]);
        mlp_forward_naive(acts.data(), theta, in.data(), 1, sh);
        const T* o = acts.data() + sh.act_offset(sh.layers(), 1);
        if (tv) {
            naive_storage_tv(S, Sd, sp, sys.t[i], gs, n);
            naive_riccati(K, o, S, sys.Hx + i * m * n, gs, n, m, lp.rho);
        } else {
            for (int e = 0; e < n * n; ++e) S[e] = Sc[e], Sd[e] = 0.0;
            if (gs.kalman)
                naive_kalman(K, static_cast<T*>(nullptr), static_cast<const double*>(nullptr), o, sys.Fx + i * n * n,
                             sys.Hx + i * m * n, gs, n, m);
            else
                for (int a = 0; a < n; ++a)
                    for (int q = 0; q < m; ++q) K[a * m + q] = gs.rate * gs.dx[a] * double(o[a * m + q]) / gs.dy[q];
        }
    };
    double K[kMax * kMax], S[kMax * kMax], Sd[kMax * kMax];
    double sum_hinge = 0, sum_h2 = 0;
    double Km[kMax * kMax];  // K with its structural zeros, by its definition
    auto masked = [&]() {
        for (int e = 0; e < n * m; ++e) Km[e] = gs.mask.empty() ? K[e] : (gs.mask[e] != 0.0 ? K[e] : 0.0);
    };
    for (int s = 0; s < M; ++s) {
        sample(s, K, S, Sd);
        masked();
        const GainSampleValue v = gain_sample_forward(Km, S, sys, idx[s], lp, tv ? Sd : nullptr);
        sum_hinge += v.hinge;
        sum_h2 += v.h2;
    }
    StepLoss loss;
    loss.hinge = std::sqrt(sum_hinge / M);
    loss.h2 = sum_h2 / M;
    if (tv && initial_weight > 0) {
        double S0[kMax * kMax], Sd0[kMax * kMax], v0 = 0;
        naive_storage_tv(S0, Sd0, sp, 0.0, gs, n);
        for (int a = 0; a < n; ++a) v0 += S0[a * n + a] * gs.dx[a] * gs.dx[a];
        loss.h2 += initial_weight * v0 / (lp.horizon * lp.h2_reference);
    }
    loss.loss = loss.hinge + gs.h2_weight * loss.h2;
    const double d_hinge = loss.hinge > 0 ? 1.0 / (2.0 * M * loss.hinge) : 0.0;
    const double d_h2 = gs.h2_weight / M;

    std::vector<double> gk(tv ? std::size_t(gs.knots + 1) * np : 0, 0.0);
    double gSsum[kMax * kMax] = {};
    for (int s = 0; s < M; ++s) {
        const std::int64_t i = idx[s];
        sample(s, K, S, Sd);
        masked();
        double gK[kMax * kMax], gS[kMax * kMax] = {}, gSd[kMax * kMax] = {};
        gain_sample_backward(gK, gS, Km, S, sys, i, lp, d_hinge, d_h2, tv ? Sd : nullptr, tv ? gSd : nullptr);
        for (int e = 0; e < n * m && !gs.mask.empty(); ++e)
            if (gs.mask[e] == 0.0) gK[e] = 0.0;
        if (tv) {
            // K = rho S^-1 R: dL/dR = rho S^-1 gK, dL/dS -= (S^-1 gK) K'
            double G[kMax * kMax];
            for (int e = 0; e < n * m; ++e) G[e] = gK[e];
            gauss_solve(S, G, n, m);
            for (int a = 0; a < n; ++a)
                for (int c = 0; c < n; ++c)
                    for (int q = 0; q < m; ++q) gS[a * n + c] -= G[a * m + q] * K[c * m + q];
            for (int a = 0; a < n; ++a)
                for (int q = 0; q < m; ++q) {
                    const double w = gs.corr.empty() ? gs.dy[q] / gs.dx[a] : gs.corr[a * m + q];
                    dout[a * m + q] = T(lp.rho * G[a * m + q] * w);
                }
            double d0[kMax * (kMax + 1) / 2], d1[kMax * (kMax + 1) / 2];
            int j = 0;
            storage_tv_backward(d0, d1, &j, gS, gSd, sp, sys.t[i], gs, n);
            for (int e = 0; e < np; ++e) {
                gk[std::size_t(j) * np + e] += d0[e];
                gk[std::size_t(j + 1) * np + e] += d1[e];
            }
        } else {
            if (gs.kalman) {
                double Kk[kMax * kMax];
                naive_kalman(Kk, dout.data(), gK, acts.data() + sh.act_offset(sh.layers(), 1), sys.Fx + i * n * n,
                             sys.Hx + i * m * n, gs, n, m);
            } else {
                for (int a = 0; a < n; ++a)
                    for (int q = 0; q < m; ++q) dout[a * m + q] = T(gs.rate * gs.dx[a] * gK[a * m + q] / gs.dy[q]);
            }
            for (int e = 0; e < n * n; ++e) gSsum[e] += gS[e];
        }
        mlp_backward_naive(gtheta.data(), static_cast<T*>(nullptr), theta, in.data(), acts.data(), dout.data(), 1, sh);
    }
    for (std::int64_t e = 0; e < P; ++e) grad[e] = gtheta[e];
    if (!tv) {
        storage_backward(grad + P, gSsum, sp, gs.dx.data(), n, gs.storage_scale);
        for (int e = 0; e < np && !gs.smask.empty(); ++e)  // entries between components: held
            if (gs.smask[e] == 0.0) grad[P + e] = T(0);
        return loss;
    }
    if (initial_weight > 0) {
        double gS0[kMax * kMax] = {}, d0[kMax * (kMax + 1) / 2], d1[kMax * (kMax + 1) / 2];
        const double w = gs.h2_weight * initial_weight / (lp.horizon * lp.h2_reference);
        for (int a = 0; a < n; ++a) gS0[a * n + a] = w * gs.dx[a] * gs.dx[a];
        int j0 = 0;
        storage_tv_backward(d0, d1, &j0, gS0, static_cast<const double*>(nullptr), sp, 0.0, gs, n);
        for (int e = 0; e < np; ++e) {
            gk[std::size_t(j0) * np + e] += d0[e];
            gk[std::size_t(j0 + 1) * np + e] += d1[e];
        }
    }
    for (std::size_t e = 0; e < gk.size(); ++e)  // entries between components: held
        grad[P + std::int64_t(e)] = !gs.smask.empty() && gs.smask[e % np] == 0.0 ? T(0) : T(gk[e]);
    return loss;
}

#define HINF_GAIN_INST(T)                                                                                        \
    template void storage_forward<T>(double*, const T*, const double*, int, double, double);                     \
    template void storage_backward<T>(T*, const double*, const T*, const double*, int, double);                  \
    template void gain_head_forward<T>(double*, const T*, const double*, const double*, int, int, double);        \
    template void gain_head_backward<T>(T*, const double*, const double*, const double*, int, int, double);      \
    template void gain_kalman_forward<T>(double*, double*, const T*, const double*, const double*, const GainSpec&, \
                                         int, int);                                                              \
    template void gain_kalman_backward<T>(T*, const double*, const T*, const double*, const double*,              \
                                          const GainSpec&, int, int);                                            \
    template StepLoss gain_step_gradient<T>(T*, const T*, const HjieSystemView&, const double*,                  \
                                            const std::int64_t*, int, const StepConfig&, StepWorkspace<T>&,      \
                                            const StepSplit*);                                                   \
    template void gain_network_eval<T>(double*, const T*, const double*, const double*, const double*,            \
                                       std::int64_t, const StepConfig&, StepWorkspace<T>&, const double*,       \
                                       double*, const T*);                                                       \
    template void gain_storage_eval<T>(double*, double*, const T*, double, const StepConfig&);                    \
    template StepLoss gain_step_gradient_naive<T>(T*, const T*, const HjieSystemView&, const double*,            \
                                                  const std::int64_t*, int, const StepConfig&);                  \
    template void storage_tv_forward<T>(double*, double*, const T*, double, const GainSpec&, int);                \
    template void storage_tv_backward<T>(double*, double*, int*, const double*, const double*, const T*, double,  \
                                         const GainSpec&, int);                                                    \
    template void gain_riccati_forward<T>(double*, const T*, const double*, const double*, const GainSpec&, int,  \
                                          int, double, double*);                                                   \
    template void gain_riccati_backward<T>(T*, double*, const double*, const double*, const double*,              \
                                           const GainSpec&, int, int, double, const double*);
HINF_GAIN_INST(float)
HINF_GAIN_INST(double)
#undef HINF_GAIN_INST

}  // namespace hinf::kern
