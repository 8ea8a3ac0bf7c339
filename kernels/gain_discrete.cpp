// The discrete-time one-step dissipation inequality of the gain variant (see gain_discrete.hpp). The sup over w is
// a quadratic form in the p x p matrix rho I - G'S G: one symmetric eigen-decomposition (fixed-capacity Eigen
// matrices, no heap) gives its definiteness, its inverse and the top eigenvector of the concavity hinge.
#include "gain_discrete.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cassert>
#include <cmath>

namespace hinf::kern {

namespace {
constexpr int kMax = kGainMaxDim;
constexpr int kMaxW = 2 * kGainMaxDim;  // p = nv + m
using MatW = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::ColMajor, kMaxW, kMaxW>;

// One sample's intermediate quantities (every S below is the symmetric part of the caller's S).
struct DiscreteParts {
    int p = 0;
    double S[kMax * kMax];  // (S + S') / 2
    double G[kMax * kMaxW]; // [B, -K], row-major n x p
    double e[kMax];         // dA - K dC
    double f[kMax];         // e + G w*: x~_{k+1} under the worst case
    double Sf[kMax];        // S f
    double w[kMaxW];        // w* = (rho I - G'S G)^-1 G'S e = (v*, n*)
    double top[kMaxW];      // unit eigenvector of G'S G for lambda_max
    double hv[kMax];        // G top
    double V0 = 0, ee = 0, T = 0;
    double lambda = 0;      // lambda_max(G'S G) / rho
    bool concave = false;
};

double quad(const double* S, const double* x, int n) {
    double v = 0;
    for (int a = 0; a < n; ++a) {
        double t = 0;
        for (int c = 0; c < n; ++c) t += S[a * n + c] * x[c];
        v += x[a] * t;
    }
    return v;
}

void mat_vec(double* y, const double* S, const double* x, int n) {
    for (int a = 0; a < n; ++a) {
        double t = 0;
        for (int c = 0; c < n; ++c) t += S[a * n + c] * x[c];
        y[a] = t;
    }
}

void discrete_parts(DiscreteParts* d, const double* K, const double* Sraw, const HjieSystemView& sv, std::int64_t i,
                    double rho) {
    const int n = sv.n, nv = sv.nv, m = sv.m, p = nv + m;
    assert(n <= kMax && nv <= kMax && m <= kMax);
    d->p = p;
    const double* xt = sv.xt + i * n;
    const double* dA = sv.dA + i * n;
    const double* B = sv.Bm + i * n * nv;
    const double* dC = sv.dC + i * m;
    for (int a = 0; a < n; ++a)
        for (int c = 0; c < n; ++c) d->S[a * n + c] = 0.5 * (Sraw[a * n + c] + Sraw[c * n + a]);
    for (int a = 0; a < n; ++a) {
        double t = dA[a];
        for (int j = 0; j < m; ++j) t -= K[a * m + j] * dC[j];
        d->e[a] = t;
        for (int j = 0; j < nv; ++j) d->G[a * p + j] = B[a * nv + j];
        for (int j = 0; j < m; ++j) d->G[a * p + nv + j] = -K[a * m + j];
    }
    d->V0 = quad(d->S, xt, n);
    d->ee = quad(d->S, d->e, n);
    // SG [n x p], Gh = G'S G [p x p], u = G'S e [p]
    double SG[kMax * kMaxW], Se[kMax], u[kMaxW];
    mat_vec(Se, d->S, d->e, n);
    for (int a = 0; a < n; ++a)
        for (int k = 0; k < p; ++k) {
            double t = 0;
            for (int c = 0; c < n; ++c) t += d->S[a * n + c] * d->G[c * p + k];
            SG[a * p + k] = t;
        }
    MatW Gh(p, p);
    for (int j = 0; j < p; ++j) {
        double t = 0;
        for (int a = 0; a < n; ++a) t += d->G[a * p + j] * Se[a];
        u[j] = t;
        for (int k = 0; k <= j; ++k) {
            double g = 0;
            for (int a = 0; a < n; ++a) g += d->G[a * p + j] * SG[a * p + k];
            Gh(j, k) = g;
            Gh(k, j) = g;
        }
    }
    Eigen::SelfAdjointEigenSolver<MatW> eig(Gh);  // ascending eigenvalues mu_k, orthonormal vectors
    const double mu_max = eig.eigenvalues()(p - 1);
    d->lambda = mu_max / rho;
    for (int j = 0; j < p; ++j) d->top[j] = eig.eigenvectors()(j, p - 1);
    for (int a = 0; a < n; ++a) {
        double t = 0;
        for (int j = 0; j < p; ++j) t += d->G[a * p + j] * d->top[j];
        d->hv[a] = t;
    }
    d->concave = eig.info() == Eigen::Success && rho - mu_max > 1e-12 * rho;
    d->T = 0;
    for (int j = 0; j < p; ++j) d->w[j] = 0.0;
    if (!d->concave) return;
    // w* = sum_k v_k (v_k'u) / (rho - mu_k), T = u'w* = sum_k (v_k'u)^2 / (rho - mu_k)
    for (int k = 0; k < p; ++k) {
        double c = 0;
        for (int j = 0; j < p; ++j) c += eig.eigenvectors()(j, k) * u[j];
        const double inv = 1.0 / (rho - eig.eigenvalues()(k));
        d->T += c * c * inv;
        for (int j = 0; j < p; ++j) d->w[j] += eig.eigenvectors()(j, k) * c * inv;
    }
    for (int a = 0; a < n; ++a) {
        double t = d->e[a];
        for (int j = 0; j < p; ++j) t += d->G[a * p + j] * d->w[j];
        d->f[a] = t;
    }
    mat_vec(d->Sf, d->S, d->f, n);
}

}  // namespace

GainSampleValue gain_discrete_sample_forward(const double* K, const double* S, const HjieSystemView& sv, std::int64_t i,
                                             const GainLossParams& gp) {
    const int n = sv.n, nv = sv.nv, m = sv.m;
    DiscreteParts d;
    discrete_parts(&d, K, S, sv, i, gp.rho);
    const double q = sv.q[i];
    GainSampleValue v;
    const double c = std::max(0.0, d.lambda - (1.0 - gp.margin));  // concavity hinge
    if (d.concave) {
        v.residual = q - d.V0 + d.ee + d.T;
        v.abs_sum = std::fabs(q) + d.V0 + d.ee + d.T;
        const double r = v.abs_sum > 0 ? v.residual / v.abs_sum : 0.0;
        const double h = std::max(0.0, r + gp.margin);
        v.hinge = h * h;
    } else {  // sup = +inf; the relative residual at its limit 1
        v.residual = INFINITY;
        v.abs_sum = std::fabs(q) + d.V0 + d.ee;
        v.hinge = (1.0 + gp.margin) * (1.0 + gp.margin);
    }
    v.hinge += c * c;
    v.h2 = gain_h2_value(d.S, K, sv.Bm + i * n * nv, n, nv, m, gp);  // gain.hpp: shared with continuous time
    return v;
}

void gain_discrete_sample_backward(double* gK, double* gS, const double* K, const double* S, const HjieSystemView& sv,
                                   std::int64_t i, const GainLossParams& gp, double d_hinge, double d_h2) {
    const int n = sv.n, nv = sv.nv, m = sv.m;
    const double* xt = sv.xt + i * n;
    const double* B = sv.Bm + i * n * nv;
    const double* dC = sv.dC + i * m;
    DiscreteParts d;
    discrete_parts(&d, K, S, sv, i, gp.rho);
    const double q = sv.q[i];
    for (int k = 0; k < n * m; ++k) gK[k] = 0.0;
    // Every dL/dS below is symmetric, so it is also the gradient with respect to the caller's (unsymmetrised) S.
    if (d.concave) {
        // envelope theorem at w*: dH/dS = f f' - x~ x~', dH/dK = -2 S f (dC + n*)'; S_i = H_i + 2 x~'S x~ + const
        const double H = q - d.V0 + d.ee + d.T;
        const double Sc = std::fabs(q) + d.V0 + d.ee + d.T;
        const double h = Sc > 0 ? std::max(0.0, H / Sc + gp.margin) : 0.0;
        if (h > 0) {
            const double g_r = d_hinge * 2.0 * h;
            const double gH = g_r * (Sc - H) / (Sc * Sc), gV0 = -g_r * 2.0 * H / (Sc * Sc);
            for (int a = 0; a < n; ++a)
                for (int c = 0; c < n; ++c)
                    gS[a * n + c] += gH * (d.f[a] * d.f[c] - xt[a] * xt[c]) + gV0 * xt[a] * xt[c];
            for (int a = 0; a < n; ++a)
                for (int j = 0; j < m; ++j) gK[a * m + j] -= gH * 2.0 * d.Sf[a] * (dC[j] + d.w[nv + j]);
        }
    }
    const double c = std::max(0.0, d.lambda - (1.0 - gp.margin));
    if (c > 0) {
        // d lambda_max(G'S G) = top' dGh top: dS -> hv hv', dG -> 2 S hv top', G = [B, -K]
        const double gc = d_hinge * 2.0 * c / gp.rho;
        double Sh[kMax];
        mat_vec(Sh, d.S, d.hv, n);
        for (int a = 0; a < n; ++a)
            for (int cc = 0; cc < n; ++cc) gS[a * n + cc] += gc * d.hv[a] * d.hv[cc];
        for (int a = 0; a < n; ++a)
            for (int j = 0; j < m; ++j) gK[a * m + j] -= gc * 2.0 * Sh[a] * d.top[nv + j];
    }
    gain_h2_backward(gK, gS, d.S, K, B, n, nv, m, gp, d_h2);
}

}  // namespace hinf::kern
