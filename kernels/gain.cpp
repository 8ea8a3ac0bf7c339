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

// relu(dt |D^-1 K dC| / |D^-1 x~| - kappa); dr [n x m] (may be null) gets d(dt |D^-1 K dC| / |D^-1 x~|)/dK
double step_correction_excess(const double* K, const HjieSystemView& sv, std::int64_t i, const GainLossParams& gp,
                              double* dr) {
    if (!(gp.dt > 0) || gp.dx == nullptr) return 0.0;
    const int n = sv.n, m = sv.m;
    const double* xt = sv.xt + i * n;
    const double* dC = sv.dC + i * m;
    double w[kMax], kk = 0, ee = 0;
    for (int a = 0; a < n; ++a) {
        double t = 0;
        for (int j = 0; j < m; ++j) t += K[a * m + j] * dC[j];
        w[a] = t / gp.dx[a];
        kk += w[a] * w[a];
        ee += (xt[a] / gp.dx[a]) * (xt[a] / gp.dx[a]);
    }
    if (!(ee > 0) || !(kk > 0)) return 0.0;
    const double nk = std::sqrt(kk), ne = std::sqrt(ee);
    const double r = gp.dt * nk / ne;
    if (r <= gp.kappa) return 0.0;
    if (dr != nullptr)
        for (int a = 0; a < n; ++a)
            for (int j = 0; j < m; ++j) dr[a * m + j] = gp.dt / ne * (w[a] / nk) * dC[j] / gp.dx[a];
    return r - gp.kappa;
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
                                    const GainLossParams& gp) {
    if (gp.discrete) return gain_discrete_sample_forward(K, S, sv, i, gp);  // the one-step game (gain_discrete.hpp)
    const int n = sv.n, nv = sv.nv, m = sv.m;
    GainParts g;
    gain_parts(&g, K, S, sv, i);
    const double q = sv.q[i], rho = gp.rho;
    GainSampleValue v;
    // sup over v, n: v* = B's/rho, n* = -K's/rho (completing the squares in 2s'(Bv - Kn) - rho|v|^2 - rho|n|^2)
    v.residual = q + 2.0 * g.a - 2.0 * g.kc + g.bb / rho + g.uu / rho;
    v.abs_sum = std::fabs(q) + 2.0 * std::fabs(g.a) + 2.0 * std::fabs(g.kc) + g.bb / rho + g.uu / rho;
    const double r = v.abs_sum > 0 ? v.residual / v.abs_sum : 0.0;
    const double h = std::max(0.0, r + gp.margin);
    v.hinge = h * h;
    const double c = step_correction_excess(K, sv, i, gp, nullptr);
    v.hinge += c * c;
    double v0 = 0;
    if (gp.xt0 != nullptr && gp.initial_weight > 0) {
        for (int a = 0; a < n; ++a)
            for (int c = 0; c < n; ++c) v0 += gp.xt0[a] * S[a * n + c] * gp.xt0[c];
    }
    const double rate = gp.disturbance_intensity * trace_form(S, sv.Bm + i * n * nv, n, nv) +
                        gp.noise_intensity * trace_form(S, K, n, m);
    v.h2 = (gp.initial_weight * v0 / gp.horizon + rate) / gp.h2_reference;
    return v;
}

void gain_sample_backward(double* gK, double* gS, const double* K, const double* S, const HjieSystemView& sv,
                          std::int64_t i, const GainLossParams& gp, double d_hinge, double d_h2) {
    if (gp.discrete) return gain_discrete_sample_backward(gK, gS, K, S, sv, i, gp, d_hinge, d_h2);
    const int n = sv.n, nv = sv.nv, m = sv.m;
    const double* xt = sv.xt + i * n;
    const double* dA = sv.dA + i * n;
    const double* B = sv.Bm + i * n * nv;
    const double* dC = sv.dC + i * m;
    GainParts g;
    gain_parts(&g, K, S, sv, i);
    const double q = sv.q[i], rho = gp.rho;
    const double H = q + 2.0 * g.a - 2.0 * g.kc + g.bb / rho + g.uu / rho;
    const double Sc = std::fabs(q) + 2.0 * std::fabs(g.a) + 2.0 * std::fabs(g.kc) + g.bb / rho + g.uu / rho;
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
        double dr[kMax * kMax];
        const double c = step_correction_excess(K, sv, i, gp, dr);
        if (c > 0)
            for (int k = 0; k < n * m; ++k) gK[k] += d_hinge * 2.0 * c * dr[k];
    }
    if (d_h2 != 0) {
        const double w = d_h2 / gp.h2_reference;
        for (int a = 0; a < n; ++a)
            for (int c = 0; c < n; ++c) {
                double t = 0;
                if (gp.xt0 != nullptr && gp.initial_weight > 0)
                    t += gp.initial_weight * gp.xt0[a] * gp.xt0[c] / gp.horizon;
                double bb = 0, kk = 0;
                for (int j = 0; j < nv; ++j) bb += B[a * nv + j] * B[c * nv + j];
                for (int j = 0; j < m; ++j) kk += K[a * m + j] * K[c * m + j];
                gS[a * n + c] += w * (t + gp.disturbance_intensity * bb + gp.noise_intensity * kk);
            }
        // d tr(K'S K)/dK = (S + S') K = 2 S K
        for (int a = 0; a < n; ++a)
            for (int j = 0; j < m; ++j) {
                double t = 0;
                for (int c = 0; c < n; ++c) t += (S[a * n + c] + S[c * n + a]) * K[c * m + j];
                gK[a * m + j] += w * gp.noise_intensity * t;
            }
    }
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
template <typename T>
void load_z(T* in, const double* z, const std::int64_t* idx, std::int64_t first, int B, int n) {
    for (int s = 0; s < B; ++s) {
        const std::int64_t i = idx ? idx[first + s] : first + s;
        for (int a = 0; a < n; ++a) in[s * n + a] = T(z[i * n + a]);
    }
}
template <typename T>
const T* pack_weights(StepWorkspace<T>& ws, const T* theta, const MlpShape& sh) {
    if (gemm_path_available(sh.gemm) != GEMM_OWN) return nullptr;
    ws.pack.resize(mlp_pack_size(sh, sizeof(T)));
    mlp_pack_weights(ws.pack.data(), theta, sh);
    return ws.pack.data();
}
}  // namespace

template <typename T>
StepLoss gain_step_gradient(T* grad, const T* theta, const HjieSystemView& sys, const double* z,
                            const std::int64_t* idx, int M, const StepConfig& cfg, StepWorkspace<T>& ws) {
    const MlpShape& sh = cfg.shape;
    const GainSpec& gs = cfg.gain;
    const int n = sys.n, m = sys.m, C = cfg.chunk, O = sh.outputs(), D0 = sh.inputs();
    const int chunks = (M + C - 1) / C;
    const std::int64_t P = sh.param_count(), Ps = step_partial_stride(sh), As = step_acts_stride(cfg);
    ws.reserve(cfg, M);
    if (std::int64_t(ws.partial.size()) < chunks * Ps) ws.partial.assign(chunks * Ps, T(0));
    gemm_prepare(sh.gemm);
    const T* wt = pack_weights(ws, theta, sh);
    GainLossParams lp = gs.loss;
    lp.xt0 = gs.xt0.data();
    lp.dx = gs.dx.data();
    const T* sparams = theta + P;
    double S[kMax * kMax];
    storage_forward(S, sparams, gs.dx.data(), n, gs.storage_scale, gs.eps);
    std::vector<GainSampleValue> vals(static_cast<std::size_t>(M));

    // pass 1: forward, gain head, per-sample loss pieces
#pragma omp parallel for schedule(static)
    for (int c = 0; c < chunks; ++c) {
        const int b0 = c * C, B = std::min(C, M - b0);
        T* in = ws.input.data() + std::int64_t(b0) * D0;
        T* acts = ws.acts.data() + std::int64_t(c) * As;
        load_z(in, z, idx, b0, B, n);
        mlp_forward(acts, theta, in, B, sh, wt);
        const T* out = acts + sh.act_offset(sh.layers(), B);
        for (int s = 0; s < B; ++s) {
            double* K = ws.K.data() + std::int64_t(b0 + s) * n * m;
            gain_head_forward(K, out + std::int64_t(s) * O, gs.dx.data(), gs.dy.data(), n, m, gs.rate);
            vals[b0 + s] = gain_sample_forward(K, S, sys, idx[b0 + s], lp);
        }
    }
    double sum_hinge = 0, sum_h2 = 0;
    for (int s = 0; s < M; ++s) {
        sum_hinge += vals[s].hinge;
        sum_h2 += vals[s].h2;
    }
    StepLoss loss;
    loss.hinge = std::sqrt(sum_hinge / M);
    loss.h2 = sum_h2 / M;
    loss.loss = loss.hinge + gs.h2_weight * loss.h2;
    const double d_hinge = loss.hinge > 0 ? 1.0 / (2.0 * M * loss.hinge) : 0.0;
    const double d_h2 = gs.h2_weight / M;

    // pass 2: dL/dK -> dL/do -> partial dL/dtheta per chunk; dL/dS per sample (ws.P)
#pragma omp parallel for schedule(static)
    for (int c = 0; c < chunks; ++c) {
        const int b0 = c * C, B = std::min(C, M - b0);
        const T* in = ws.input.data() + std::int64_t(b0) * D0;
        const T* acts = ws.acts.data() + std::int64_t(c) * As;
        T* dout = ws.dout.data() + std::int64_t(b0) * O;
        double gK[kMax * kMax];
        for (int s = 0; s < B; ++s) {
            const double* K = ws.K.data() + std::int64_t(b0 + s) * n * m;
            double* gSs = ws.P.data() + std::int64_t(b0 + s) * n * n;
            for (int e = 0; e < n * n; ++e) gSs[e] = 0.0;
            gain_sample_backward(gK, gSs, K, S, sys, idx[b0 + s], lp, d_hinge, d_h2);
            gain_head_backward(dout + std::int64_t(s) * O, gK, gs.dx.data(), gs.dy.data(), n, m, gs.rate);
        }
        T* part = ws.partial.data() + std::int64_t(c) * Ps;
        T* scratch = ws.scratch.data() + std::int64_t(c) * sh.scratch_size(C);
        mlp_backward(part, static_cast<T*>(nullptr), theta, in, acts, dout, B, sh, scratch, /*overwrite=*/true, wt);
    }
    sum_chunk_partials(grad, ws.partial.data(), chunks, Ps, P);  // chunk order (train_step.hpp)
    // the storage's gradient: dL/dS summed in sample order, then through S = c D^-1 (M M' + eps I) D^-1
    double gS[kMax * kMax] = {};
    for (int s = 0; s < M; ++s) {
        const double* gSs = ws.P.data() + std::int64_t(s) * n * n;
        for (int e = 0; e < n * n; ++e) gS[e] += gSs[e];
    }
    storage_backward(grad + P, gS, sparams, gs.dx.data(), n, gs.storage_scale);
    return loss;
}

template <typename T>
void gain_network_eval(double* K, double* S, const T* theta, const double* z, std::int64_t count,
                       const StepConfig& cfg, StepWorkspace<T>& ws) {
    const MlpShape& sh = cfg.shape;
    const GainSpec& gs = cfg.gain;
    const int n = cfg.head.n, m = gs.m, C = cfg.chunk, O = sh.outputs(), D0 = sh.inputs();
    if (S != nullptr) storage_forward(S, theta + sh.param_count(), gs.dx.data(), n, gs.storage_scale, gs.eps);
    if (count <= 0) return;
    ws.reserve(cfg, static_cast<int>(count));
    gemm_prepare(sh.gemm);
    const T* wt = pack_weights(ws, theta, sh);
    const int chunks = static_cast<int>((count + C - 1) / C);
#pragma omp parallel for schedule(static) if (chunks > 1)
    for (int c = 0; c < chunks; ++c) {
        const std::int64_t b0 = std::int64_t(c) * C;
        const int B = static_cast<int>(std::min<std::int64_t>(C, count - b0));
        T* in = ws.input.data() + b0 * D0;
        T* acts = ws.acts.data() + std::int64_t(c) * step_acts_stride(cfg);
        load_z<T>(in, z, nullptr, b0, B, n);
        mlp_forward(acts, theta, in, B, sh, wt);
        const T* out = acts + sh.act_offset(sh.layers(), B);
        for (int s = 0; s < B; ++s)
            gain_head_forward(K + (b0 + s) * n * m, out + std::int64_t(s) * O, gs.dx.data(), gs.dy.data(), n, m,
                              gs.rate);
    }
}

#define HINF_GAIN_INST(T)                                                                                        \
    template void storage_forward<T>(double*, const T*, const double*, int, double, double);                     \
    template void storage_backward<T>(T*, const double*, const T*, const double*, int, double);                  \
    template void gain_head_forward<T>(double*, const T*, const double*, const double*, int, int, double);        \
    template void gain_head_backward<T>(T*, const double*, const double*, const double*, int, int, double);      \
    template StepLoss gain_step_gradient<T>(T*, const T*, const HjieSystemView&, const double*,                  \
                                            const std::int64_t*, int, const StepConfig&, StepWorkspace<T>&);     \
    template void gain_network_eval<T>(double*, double*, const T*, const double*, std::int64_t,                  \
                                       const StepConfig&, StepWorkspace<T>&);
HINF_GAIN_INST(float)
HINF_GAIN_INST(double)
#undef HINF_GAIN_INST

}  // namespace hinf::kern
