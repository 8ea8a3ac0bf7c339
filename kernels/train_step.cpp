// Chunked, thread-count-independent gradient of the HJIE loss (see train_step.hpp).
#include "train_step.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace hinf::kern {

namespace {

template <typename T>
void load_inputs(T* in, const double* xt, const std::int64_t* idx, std::int64_t first, int B, int n, double scale) {
    const double inv = 1.0 / scale;
    for (int s = 0; s < B; ++s) {
        std::int64_t i = idx ? idx[first + s] : first + s;
        for (int a = 0; a < n; ++a) in[s * n + a] = T(xt[i * n + a] * inv);
    }
}
}  // namespace

template <typename T>
const T* step_pack_weights(LineVector<T>& pack, const T* theta, const MlpShape& shape) {
    if (gemm_path_available(shape.gemm) != GEMM_OWN) return nullptr;
    pack.resize(mlp_pack_size(shape, sizeof(T)));
    mlp_pack_weights(pack.data(), theta, shape);
    return pack.data();
}

std::int64_t step_acts_stride(const StepConfig& cfg) {
    return (std::int64_t(cfg.chunk) * cfg.shape.act_per_sample() + 15) / 16 * 16;
}
std::int64_t step_partial_stride(const MlpShape& shape) { return (shape.param_count() + 15) / 16 * 16; }
std::int64_t step_work_stride(const StepConfig& cfg) {
    const std::int64_t n = cfg.head.n;
    // gp [n], gP or P [n x n], the head's scratch, the HJIE backward's scratch
    return n + n * n + head_workspace(cfg.head.kind, cfg.head.n) + hjie_backward_workspace(cfg.head.n);
}

template <typename T>
void StepWorkspace<T>::reserve(const StepConfig& cfg, int max_batch) {
    if (max_batch <= capacity) return;
    const int n = cfg.head.n, C = cfg.chunk;
    const int chunks = (max_batch + C - 1) / C;
    const std::int64_t padded = std::int64_t(chunks) * C;
    capacity = max_batch;
    input.assign(padded * cfg.shape.inputs(), T(0));
    acts.assign(chunks * step_acts_stride(cfg), T(0));
    dout.assign(padded * cfg.shape.outputs(), T(0));
    scratch.assign(std::int64_t(chunks) * cfg.shape.scratch_size(C), T(0));
    partial.clear();  // grown lazily by step_gradient (not needed for evaluation)
    p.assign(padded * n, 0.0);
    P.assign(padded * n * n, 0.0);
    values.assign(padded, HjieSampleValue{});
    work.assign(chunks * step_work_stride(cfg), 0.0);
    if (cfg.gain.enabled) K.assign(padded * n * cfg.gain.m, 0.0);
}

template <typename T>
StepLoss step_gradient(T* grad, const T* theta, const HjieSystemView& sys, const std::int64_t* idx, int M,
                       const StepConfig& cfg, StepWorkspace<T>& ws, const StepSplit* split) {
    const MlpShape& sh = cfg.shape;
    const int n = sys.n, C = cfg.chunk, O = sh.outputs(), D0 = sh.inputs();
    const int chunks = (M + C - 1) / C;
    const std::int64_t P = sh.param_count(), Ps = step_partial_stride(sh), As = step_acts_stride(cfg);
    ws.reserve(cfg, M);
    if (std::int64_t(ws.partial.size()) < chunks * Ps) ws.partial.assign(chunks * Ps, T(0));
    gemm_prepare(sh.gemm);
    const T* wt = step_pack_weights(ws.pack, theta, sh);
    const bool quad = cfg.head.kind == HEAD_QUADRATIC;
    // this process's chunks [c_first, c_last): all of them without a split
    const int ranks = split != nullptr ? split->ranks : 1, rank = split != nullptr ? split->rank : 0;
    const int c_first = step_split_begin(chunks, rank, ranks), c_last = step_split_begin(chunks, rank + 1, ranks);
    std::vector<std::int64_t> chunk_begin, sample_begin;
    if (ranks > 1) {
        for (int r = 0; r <= ranks; ++r) {
            chunk_begin.push_back(step_split_begin(chunks, r, ranks));
            sample_begin.push_back(std::min<std::int64_t>(M, chunk_begin.back() * C));
        }
    }

    // pass 1: forward, head, per-sample loss pieces
#pragma omp parallel for schedule(static)
    for (int c = c_first; c < c_last; ++c) {
        const int b0 = c * C, B = std::min(C, M - b0);
        T* in = ws.input.data() + std::int64_t(b0) * D0;
        T* acts = ws.acts.data() + std::int64_t(c) * As;
        load_inputs(in, sys.xt, idx, b0, B, n, cfg.input_scale);
        mlp_forward(acts, theta, in, B, sh, wt);
        const T* out = acts + sh.act_offset(sh.layers(), B);
        double* hw = ws.work.data() + std::int64_t(c) * step_work_stride(cfg);
        for (int s = 0; s < B; ++s) {
            const std::int64_t i = idx[b0 + s];
            double* p = ws.p.data() + std::int64_t(b0 + s) * n;
            double* Pm = ws.P.data() + std::int64_t(b0 + s) * n * n;
            head_forward(p, quad ? Pm : nullptr, out + std::int64_t(s) * O, sys.xt + i * n, cfg.head, hw);
            ws.values[b0 + s] = hjie_sample_forward(p, Pm, sys, i, cfg.hjie, cfg.objective);
        }
    }
    // every process needs every sample's loss pieces: the loss (and so dL/dp) is a function of all of them
    if (ranks > 1) split->allgather(ws.values.data(), sizeof(HjieSampleValue), sample_begin.data());
    // ordered reduction of the loss
    double sum_hinge = 0, sum_h2 = 0;
    for (int s = 0; s < M; ++s) {
        sum_hinge += ws.values[s].hinge;
        sum_h2 += ws.values[s].h2;
    }
    StepLoss loss;
    const double eta = cfg.objective == HJIE_OBJECTIVE_DISSIPATIVE ? cfg.hjie.h2_weight : 0.0;
    loss.hinge = std::sqrt(sum_hinge / M);
    loss.h2 = sum_h2 / M;
    loss.loss = loss.hinge + eta * loss.h2;
    const double d_hinge = loss.hinge > 0 ? 1.0 / (2.0 * M * loss.hinge) : 0.0;
    const double d_h2 = eta / M;

    // pass 2: per-sample dL/dp -> dL/do -> partial dL/dtheta per chunk
#pragma omp parallel for schedule(static)
    for (int c = c_first; c < c_last; ++c) {
        const int b0 = c * C, B = std::min(C, M - b0);
        const T* in = ws.input.data() + std::int64_t(b0) * D0;
        const T* acts = ws.acts.data() + std::int64_t(c) * As;
        const T* out = acts + sh.act_offset(sh.layers(), B);
        T* dout = ws.dout.data() + std::int64_t(b0) * O;
        // this chunk's scratch: gp [n], gP [n x n], the head's and the HJIE backward's
        double* gp = ws.work.data() + std::int64_t(c) * step_work_stride(cfg);
        double* gP = gp + n;
        double* hw = gP + std::int64_t(n) * n;
        double* jw = hw + head_workspace(cfg.head.kind, n);
        for (int s = 0; s < B; ++s) {
            const std::int64_t i = idx[b0 + s];
            const double* p = ws.p.data() + std::int64_t(b0 + s) * n;
            const double* Pm = ws.P.data() + std::int64_t(b0 + s) * n * n;
            hjie_sample_backward(gp, quad ? gP : nullptr, p, Pm, sys, i, cfg.hjie, cfg.objective, d_hinge, d_h2, jw);
            head_backward(dout + std::int64_t(s) * O, gp, quad ? gP : nullptr, out + std::int64_t(s) * O,
                          sys.xt + i * n, cfg.head, hw);
        }
        T* part = ws.partial.data() + std::int64_t(c) * Ps;
        T* scratch = ws.scratch.data() + std::int64_t(c) * sh.scratch_size(C);
        mlp_backward(part, static_cast<T*>(nullptr), theta, in, acts, dout, B, sh, scratch, /*overwrite=*/true, wt);
    }
    // every chunk's partial to every process (an all-gather, not an all-reduce, whose order MPI leaves open)
    if (ranks > 1) split->allgather(ws.partial.data(), Ps * std::int64_t(sizeof(T)), chunk_begin.data());
    // partial gradients summed in chunk order: 0 + part_0 + part_1 + ... for every component, in
    // blocks of components so that the inner loop runs along contiguous memory (vectorised)
    sum_chunk_partials(grad, ws.partial.data(), chunks, Ps, P);
    return loss;
}

template <typename T>
void network_eval(double* p, double* P, const T* theta, const double* xt, std::int64_t count, const StepConfig& cfg,
                  StepWorkspace<T>& ws, const T* pack) {
    const MlpShape& sh = cfg.shape;
    const int n = cfg.head.n, C = cfg.chunk, O = sh.outputs(), D0 = sh.inputs();
    ws.reserve(cfg, static_cast<int>(count));
    gemm_prepare(sh.gemm);
    const T* wt = pack != nullptr ? pack : step_pack_weights(ws.pack, theta, sh);
    const int chunks = static_cast<int>((count + C - 1) / C);
    const bool quad = cfg.head.kind == HEAD_QUADRATIC;
#pragma omp parallel for schedule(static) if (chunks > 1)
    for (int c = 0; c < chunks; ++c) {
        const std::int64_t b0 = std::int64_t(c) * C;
        const int B = static_cast<int>(std::min<std::int64_t>(C, count - b0));
        T* in = ws.input.data() + b0 * D0;
        T* acts = ws.acts.data() + std::int64_t(c) * step_acts_stride(cfg);
        load_inputs<T>(in, xt, nullptr, b0, B, n, cfg.input_scale);
        mlp_forward(acts, theta, in, B, sh, wt);
        const T* out = acts + sh.act_offset(sh.layers(), B);
        double* Ptmp = ws.work.data() + std::int64_t(c) * step_work_stride(cfg) + n;  // [n x n]
        double* hw = Ptmp + std::int64_t(n) * n;
        for (int s = 0; s < B; ++s) {
            double* Pm = (quad && P) ? P + (b0 + s) * n * n : Ptmp;
            head_forward(p + (b0 + s) * n, quad ? Pm : nullptr, out + std::int64_t(s) * O, xt + (b0 + s) * n,
                         cfg.head, hw);
        }
    }
}

template struct StepWorkspace<float>;
template struct StepWorkspace<double>;
template StepLoss step_gradient<float>(float*, const float*, const HjieSystemView&, const std::int64_t*, int,
                                       const StepConfig&, StepWorkspace<float>&, const StepSplit*);
template StepLoss step_gradient<double>(double*, const double*, const HjieSystemView&, const std::int64_t*, int,
                                        const StepConfig&, StepWorkspace<double>&, const StepSplit*);
template void network_eval<float>(double*, double*, const float*, const double*, std::int64_t, const StepConfig&,
                                  StepWorkspace<float>&, const float*);
template void network_eval<double>(double*, double*, const double*, const double*, std::int64_t, const StepConfig&,
                                   StepWorkspace<double>&, const double*);
template const float* step_pack_weights<float>(LineVector<float>&, const float*, const MlpShape&);
template const double* step_pack_weights<double>(LineVector<double>&, const double*, const MlpShape&);

template <typename T>
void sum_chunk_partials(T* grad, const T* partial, int chunks, std::int64_t stride, std::int64_t P) {
    // in blocks of components so that the inner loop runs along contiguous memory (vectorised)
    constexpr std::int64_t kBlock = 2048;
    const std::int64_t blocks = (P + kBlock - 1) / kBlock;
#pragma omp parallel for schedule(static)
    for (std::int64_t b = 0; b < blocks; ++b) {
        const std::int64_t j0 = b * kBlock, j1 = std::min(P, j0 + kBlock);
        for (std::int64_t j = j0; j < j1; ++j) grad[j] = T(0);
        for (int c = 0; c < chunks; ++c) {
            const T* part = partial + std::int64_t(c) * stride;
            for (std::int64_t j = j0; j < j1; ++j) grad[j] += part[j];
        }
    }
}

template void sum_chunk_partials<float>(float*, const float*, int, std::int64_t, std::int64_t);
template void sum_chunk_partials<double>(double*, const double*, int, std::int64_t, std::int64_t);

}  // namespace hinf::kern
