// MLP forward/backward on one chunk (single-threaded; the caller splits samples over threads) with the
// GEMMs by OpenBLAS (default) or Eigen's own products, bias + LeakyReLU fused into one pass over the
// product, and their naive twins. See mlp.hpp for the shape legend and docs/method.md section 11.
#include "mlp.hpp"

#include <cblas.h>

#include "gemm.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cstdlib>
#include <cstring>

namespace hinf::kern {

int MlpShape::max_width() const { return *std::max_element(sizes.begin(), sizes.end()); }

std::int64_t MlpShape::param_count() const {
    std::int64_t n = 0;
    for (int l = 1; l <= layers(); ++l) n += std::int64_t(sizes[l]) * sizes[l - 1] + sizes[l];
    return n;
}

std::int64_t MlpShape::weight_offset(int l) const {
    std::int64_t n = 0;
    for (int k = 1; k < l; ++k) n += std::int64_t(sizes[k]) * sizes[k - 1] + sizes[k];
    return n;
}

int MlpShape::act_ld(int l) const {
    const int d = sizes[l];
    return (l < layers() && d % 64 == 0) ? d + 16 : d;
}

int MlpShape::scratch_width() const {
    int w = 0;
    for (int l = 0; l <= layers(); ++l) w = std::max(w, l == 0 ? sizes[0] : act_ld(l));
    return w;
}

std::int64_t MlpShape::scratch_size(int B) const {
    std::int64_t tr = 0;  // the own kernels' transposed dW of any layer whose rows are narrower than a vector
    for (int l = 1; l <= layers(); ++l) tr = std::max(tr, std::int64_t(sizes[l - 1]) * sizes[l]);
    return 2 * std::int64_t(B) * scratch_width() + tr;
}

std::int64_t MlpShape::act_per_sample() const {
    std::int64_t n = 0;
    for (int l = 1; l <= layers(); ++l) n += act_ld(l);
    return n;
}

std::int64_t MlpShape::act_offset(int l, int B) const {
    std::int64_t n = 0;
    for (int k = 1; k < l; ++k) n += std::int64_t(act_ld(k)) * B;
    return n;
}

namespace {

template <typename T>
using RowMat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
template <typename T>
using MapM = Eigen::Map<RowMat<T>, 0, Eigen::OuterStride<>>;
template <typename T>
using MapCM = Eigen::Map<const RowMat<T>, 0, Eigen::OuterStride<>>;
template <typename T>
using MapCV = Eigen::Map<const Eigen::Matrix<T, Eigen::Dynamic, 1>>;
template <typename T>
using MapV = Eigen::Map<Eigen::Matrix<T, Eigen::Dynamic, 1>>;

}  // namespace

namespace {

// C [m x n] = A' B' + beta C, all row-major; A' = A or A^T, B' = B or B^T. One serial OpenBLAS call.
inline void gemm(bool ta, bool tb, int m, int n, int k, const float* A, int lda, const float* Bm, int ldb, float beta,
                 float* C, int ldc) {
    cblas_sgemm(CblasRowMajor, ta ? CblasTrans : CblasNoTrans, tb ? CblasTrans : CblasNoTrans, m, n, k, 1.0f, A, lda,
                Bm, ldb, beta, C, ldc);
}
inline void gemm(bool ta, bool tb, int m, int n, int k, const double* A, int lda, const double* Bm, int ldb,
                 double beta, double* C, int ldc) {
    cblas_dgemm(CblasRowMajor, ta ? CblasTrans : CblasNoTrans, tb ? CblasTrans : CblasNoTrans, m, n, k, 1.0, A, lda,
                Bm, ldb, beta, C, ldc);
}

// H [B x d] <- LeakyReLU(H + 1 b^T) (hidden layers) or H + 1 b^T (output layer): the GEMM's epilogue.
template <typename T>
void bias_activation(T* H, int ld, const T* b, int B, int d, bool hidden, T a1, T a2) {
    for (int s = 0; s < B; ++s) {
        T* h = H + std::int64_t(s) * ld;
        if (hidden) {
            for (int o = 0; o < d; ++o) {
                const T z = h[o] + b[o];
                h[o] = z > T(0) ? a1 * z : a2 * z;
            }
        } else {
            for (int o = 0; o < d; ++o) h[o] += b[o];
        }
    }
}
}  // namespace

GemmPath default_gemm_path() { return gemm_own_available() ? GEMM_OWN : GEMM_OPENBLAS; }
GemmPath gemm_path_available(GemmPath path) { return path == GEMM_OWN && !gemm_own_available() ? GEMM_OPENBLAS : path; }

void gemm_prepare(GemmPath path) {
    if (path == GEMM_OPENBLAS && openblas_get_num_threads() != 1) openblas_set_num_threads(1);
}

namespace {
// read during static initialisation: OpenBLAS, a shared library, has run its own constructor by then
const int kBlasThreadsAtStart = openblas_get_num_threads();
}  // namespace

BlasThreadsAtStart::BlasThreadsAtStart() : saved_(openblas_get_num_threads()) {
    if (saved_ != kBlasThreadsAtStart) openblas_set_num_threads(kBlasThreadsAtStart);
}
BlasThreadsAtStart::~BlasThreadsAtStart() {
    if (openblas_get_num_threads() != saved_) openblas_set_num_threads(saved_);
}

std::string gemm_description(GemmPath path) {
    path = gemm_path_available(path);
    if (path == GEMM_OWN)
        return "hinf's own AVX-512 register-blocked kernels (8 x 2 vectors, bias/LeakyReLU fused)";
    if (path == GEMM_EIGEN)
        return "Eigen " + std::to_string(EIGEN_WORLD_VERSION) + "." + std::to_string(EIGEN_MAJOR_VERSION) + "." +
               std::to_string(EIGEN_MINOR_VERSION) + " own products (no BLAS)";
    std::string d = std::string(openblas_get_config()) + ", " + openblas_get_corename() +
                    " kernels, serial per chunk";
    if (const char* ct = std::getenv("OPENBLAS_CORETYPE"))
        d += " (forced by OPENBLAS_CORETYPE=" + std::string(ct) + "; unset it for this CPU's own kernels)";
    return d;
}

namespace {
// offsets of layer l's forward and backward panels in the pack
template <typename T>
void pack_offsets(const MlpShape& sh, int l, std::int64_t* fwd, std::int64_t* bwd) {
    std::int64_t off = 0;
    for (int k = 1; k <= l; ++k) {
        const int din = sh.sizes[k - 1], dout = sh.sizes[k];
        if (k == l) *fwd = off;
        off += gemm_packed_size<T>(din, dout);
        if (k == l) *bwd = off;
        off += gemm_packed_size<T>(dout, din);
    }
}
}  // namespace

std::int64_t mlp_pack_size(const MlpShape& sh, int elem_size) {
    std::int64_t n = 0;
    for (int l = 1; l <= sh.layers(); ++l) {
        const int din = sh.sizes[l - 1], dout = sh.sizes[l];
        n += elem_size == 4 ? gemm_packed_size<float>(din, dout) + gemm_packed_size<float>(dout, din)
                            : gemm_packed_size<double>(din, dout) + gemm_packed_size<double>(dout, din);
    }
    return n;
}

template <typename T>
void mlp_pack_weights(T* pack, const T* theta, const MlpShape& shape) {
    const int L = shape.layers(), NR = gemm_panel_width<T>();
    // one task per (layer, direction, panel); each writes its own panel
    int tasks = 0;
    for (int l = 1; l <= L; ++l) tasks += (shape.sizes[l] + NR - 1) / NR + (shape.sizes[l - 1] + NR - 1) / NR;
#pragma omp parallel for schedule(static) if (tasks > 8)
    for (int t = 0; t < tasks; ++t) {
        int rest = t;
        for (int l = 1; l <= L; ++l) {
            const int din = shape.sizes[l - 1], dout = shape.sizes[l];
            const int pf = (dout + NR - 1) / NR, pbw = (din + NR - 1) / NR;
            const T* W = theta + shape.weight_offset(l);
            std::int64_t of = 0, ob = 0;
            if (rest < pf + pbw) pack_offsets<T>(shape, l, &of, &ob);
            if (rest < pf) {  // W^T: element (i, o) = W[o*din + i]
                gemm_pack_b(pack + of, din, dout, W, 1, din, rest, rest + 1);
                break;
            }
            rest -= pf;
            if (rest < pbw) {  // W: element (o, i) = W[o*din + i]
                gemm_pack_b(pack + ob, dout, din, W, din, 1, rest, rest + 1);
                break;
            }
            rest -= pbw;
        }
    }
}

namespace {

// GEMM_OWN forward: bias and LeakyReLU fused into the products' store
template <typename T>
void forward_own(T* acts, const T* theta, const T* x, int B, const MlpShape& shape, const T* pack) {
    const T a1 = T(shape.slope_positive), a2 = T(shape.slope_negative);
    const T* in = x;
    int ldi = shape.inputs();  // row stride of `in`
    for (int l = 1; l <= shape.layers(); ++l) {
        const int din = shape.sizes[l - 1], dout = shape.sizes[l];
        T* H = acts + shape.act_offset(l, B);
        GemmEpi<T> e;
        e.kind = l < shape.layers() ? EPI_BIAS_LEAKY : EPI_BIAS;
        e.bias = theta + shape.weight_offset(l) + std::int64_t(dout) * din;
        e.a1 = a1;
        e.a2 = a2;
        std::int64_t of = 0, ob = 0;
        pack_offsets<T>(shape, l, &of, &ob);
        // H_l = act(H_{l-1} W_l^T + 1 b_l^T), W_l^T from the pack
        gemm_own_packed(B, dout, din, in, ldi, 1, pack + of, H, shape.act_ld(l), false, e);
        in = H;
        ldi = shape.act_ld(l);
    }
}

// GEMM_OPENBLAS forward: one serial OpenBLAS call per layer, then bias and activation
template <typename T>
void forward_openblas(T* acts, const T* theta, const T* x, int B, const MlpShape& shape) {
    const T a1 = T(shape.slope_positive), a2 = T(shape.slope_negative);
    const T* in = x;
    int ldi = shape.inputs();
    for (int l = 1; l <= shape.layers(); ++l) {
        const int din = shape.sizes[l - 1], dout = shape.sizes[l];
        const T* W = theta + shape.weight_offset(l);
        T* H = acts + shape.act_offset(l, B);
        // H_l = act(H_{l-1} W_l^T + 1 b_l^T)
        gemm(false, true, B, dout, din, in, ldi, W, din, T(0), H, shape.act_ld(l));
        bias_activation(H, shape.act_ld(l), W + std::int64_t(dout) * din, B, dout, l < shape.layers(), a1, a2);
        in = H;
        ldi = shape.act_ld(l);
    }
}

// GEMM_EIGEN forward: Eigen's own products
template <typename T>
void forward_eigen(T* acts, const T* theta, const T* x, int B, const MlpShape& shape) {
    const T a1 = T(shape.slope_positive), a2 = T(shape.slope_negative);
    const T* in = x;
    int ldi = shape.inputs();
    for (int l = 1; l <= shape.layers(); ++l) {
        const int din = shape.sizes[l - 1], dout = shape.sizes[l];
        const T* W = theta + shape.weight_offset(l);
        const T* b = W + std::int64_t(dout) * din;
        T* H = acts + shape.act_offset(l, B);
        const int ldo = shape.act_ld(l);
        MapM<T> Hm(H, B, dout, Eigen::OuterStride<>(ldo));
        // H_l = H_{l-1} W_l^T + 1 b_l^T
        Hm.noalias() = MapCM<T>(in, B, din, Eigen::OuterStride<>(ldi)) *
                       MapCM<T>(W, dout, din, Eigen::OuterStride<>(din)).transpose();
        Hm.rowwise() += MapCV<T>(b, dout).transpose();
        if (l < shape.layers())
            for (int s = 0; s < B; ++s)
                for (int o = 0; o < dout; ++o) {
                    T& h = H[std::int64_t(s) * ldo + o];
                    h = h > T(0) ? a1 * h : a2 * h;
                }
        in = H;
        ldi = ldo;
    }
}

}  // namespace

template <typename T>
void mlp_forward(T* acts, const T* theta, const T* x, int B, const MlpShape& shape, const T* pack) {
    switch (gemm_path_available(shape.gemm)) {
    case GEMM_OWN: {
        std::vector<T> own;  // only when the caller did not pack (tests, one-off evaluations)
        if (!pack) {
            own.resize(mlp_pack_size(shape, sizeof(T)));
            mlp_pack_weights(own.data(), theta, shape);
            pack = own.data();
        }
        forward_own(acts, theta, x, B, shape, pack);
        return;
    }
    case GEMM_OPENBLAS: forward_openblas(acts, theta, x, B, shape); return;
    case GEMM_EIGEN: forward_eigen(acts, theta, x, B, shape); return;
    }
}

namespace {

// dW_l (+)= G_l^T H_{l-1}: dW [dl x din], G [B x dl] (row stride ldg), H [B x din] (row stride ldh).
// tr [din x dl]: the own kernels' scratch for the transposed input layer.
template <typename T>
void backward_weights(GemmPath path, T* dW, int din, int dl, int B, const T* G, int ldg, const T* H, int ldh,
                      bool overwrite, T* tr) {
    if (path == GEMM_OWN) {
        if (2 * din <= gemm_panel_width<T>() && dl >= gemm_panel_width<T>()) {
            // rows narrower than a vector (the input layer): dW^T = H^T G fills the vectors; the same products
            // summed in the same order, so the same bits
            if (!overwrite)
                for (int o = 0; o < dl; ++o)
                    for (int i = 0; i < din; ++i) tr[std::size_t(i) * dl + o] = dW[std::int64_t(o) * din + i];
            gemm_own(din, dl, B, H, 1, ldh, G, ldg, tr, dl, !overwrite, GemmEpi<T>{});
            for (int o = 0; o < dl; ++o)
                for (int i = 0; i < din; ++i) dW[std::int64_t(o) * din + i] = tr[std::size_t(i) * dl + o];
        } else {
            gemm_own(dl, din, B, G, 1, ldg, H, ldh, dW, din, !overwrite, GemmEpi<T>{});
        }
    } else if (path == GEMM_OPENBLAS) {
        gemm(true, false, dl, din, B, G, ldg, H, ldh, overwrite ? T(0) : T(1), dW, din);
    } else {
        MapM<T> dWm(dW, dl, din, Eigen::OuterStride<>(din));
        if (overwrite) dWm.setZero();
        dWm.noalias() += MapCM<T>(G, B, dl, Eigen::OuterStride<>(ldg)).transpose() *
                         MapCM<T>(H, B, din, Eigen::OuterStride<>(ldh));
    }
}

// target [B x din] (row stride ldh) = G_l W_l, times LeakyReLU's slope where Hin (the layer's input, whose sign is
// that of its pre-activation: both slopes positive) is given. W [dl x din]; packed: the own kernels' panel of W.
template <typename T>
void backward_inputs(GemmPath path, T* target, int ldh, int B, int din, int dl, const T* G, int ldg, const T* W,
                     const T* packed, const T* Hin, T a1, T a2) {
    if (path == GEMM_OWN) {
        GemmEpi<T> e;  // the slope fused into the store
        if (Hin) {
            e.kind = EPI_LEAKY_GRAD;
            e.H = Hin;
            e.ldh = ldh;
            e.a1 = a1;
            e.a2 = a2;
        }
        gemm_own_packed(B, din, dl, G, ldg, 1, packed, target, ldh, false, e);
        return;
    }
    if (path == GEMM_OPENBLAS) gemm(false, false, B, din, dl, G, ldg, W, din, T(0), target, ldh);
    else
        MapM<T>(target, B, din, Eigen::OuterStride<>(ldh)).noalias() =
            MapCM<T>(G, B, dl, Eigen::OuterStride<>(ldg)) * MapCM<T>(W, dl, din, Eigen::OuterStride<>(din));
    if (Hin)
        for (int s = 0; s < B; ++s)
            for (int i = 0; i < din; ++i)
                target[std::int64_t(s) * ldh + i] *= Hin[std::int64_t(s) * ldh + i] > T(0) ? a1 : a2;
}

}  // namespace

template <typename T>
void mlp_backward(T* dtheta, T* dx, const T* theta, const T* x, const T* acts, const T* dout_in, int B,
                  const MlpShape& shape, T* scratch, bool overwrite, const T* pack) {
    const GemmPath path = gemm_path_available(shape.gemm);
    const T a1 = T(shape.slope_positive), a2 = T(shape.slope_negative);
    const int L = shape.layers(), wmax = shape.scratch_width();
    std::vector<T> own;  // only when the caller did not pack (tests, one-off evaluations)
    if (path == GEMM_OWN && !pack) {
        own.resize(mlp_pack_size(shape, sizeof(T)));
        mlp_pack_weights(own.data(), theta, shape);
        pack = own.data();
    }
    T* G = scratch;                               // dL/dz_l   [B x D_l]
    T* Gprev = scratch + std::int64_t(B) * wmax;  // dL/dz_{l-1}
    T* tr = scratch + 2 * std::int64_t(B) * wmax;  // [din x dl] transposed dW of a narrow layer (own kernels)
    const T* Gc = dout_in;                        // read in place: no copy of dL/dH_L
    int ldg = shape.outputs();                    // row stride of Gc
    for (int l = L; l >= 1; --l) {
        const int din = shape.sizes[l - 1], dl = shape.sizes[l];
        const T* W = theta + shape.weight_offset(l);
        T* dW = dtheta + shape.weight_offset(l);
        T* db = dW + std::int64_t(dl) * din;
        const T* Hin = (l == 1) ? x : acts + shape.act_offset(l - 1, B);
        const int ldh = (l == 1) ? din : shape.act_ld(l - 1);  // row stride of Hin and of Gprev
        backward_weights(path, dW, din, dl, B, Gc, ldg, Hin, ldh, overwrite, tr);
        // db_l (+)= column sums of G_l, samples in order (a plain loop: a vectorised reduction would peel by
        // address alignment and make the bits depend on where the buffers live)
        if (overwrite) std::fill(db, db + dl, T(0));
        for (int s = 0; s < B; ++s)
            for (int o = 0; o < dl; ++o) db[o] += Gc[std::int64_t(s) * ldg + o];
        if (l == 1 && !dx) break;
        std::int64_t of = 0, ob = 0;
        if (path == GEMM_OWN) pack_offsets<T>(shape, l, &of, &ob);
        // dL/dH_{l-1} = G_l W_l, through LeakyReLU for hidden layers
        backward_inputs(path, (l == 1) ? dx : Gprev, ldh, B, din, dl, Gc, ldg, W, pack + ob, l > 1 ? Hin : nullptr,
                        a1, a2);
        if (l > 1) {
            Gc = Gprev;
            ldg = ldh;
            std::swap(G, Gprev);
        }
    }
}

template <typename T>
void mlp_forward_naive(T* acts, const T* theta, const T* x, int B, const MlpShape& shape) {
    const int L = shape.layers();
    for (int s = 0; s < B; ++s) {
        for (int l = 1; l <= L; ++l) {
            const int din = shape.sizes[l - 1], dout = shape.sizes[l];
            const T* W = theta + shape.weight_offset(l);
            const T* b = W + std::int64_t(dout) * din;
            const T* in = (l == 1) ? x + std::int64_t(s) * din
                                   : acts + shape.act_offset(l - 1, B) + std::int64_t(s) * shape.act_ld(l - 1);
            T* out = acts + shape.act_offset(l, B) + std::int64_t(s) * shape.act_ld(l);
            for (int o = 0; o < dout; ++o) {
                T z = b[o];
                for (int i = 0; i < din; ++i) z += W[std::int64_t(o) * din + i] * in[i];
                if (l < L) z = z > T(0) ? T(shape.slope_positive) * z : T(shape.slope_negative) * z;
                out[o] = z;
            }
        }
    }
}

template <typename T>
void mlp_backward_naive(T* dtheta, T* dx, const T* theta, const T* x, const T* acts, const T* dout_in, int B,
                        const MlpShape& shape) {
    const int L = shape.layers();
    std::vector<T> g, gprev;
    for (int s = 0; s < B; ++s) {
        g.assign(dout_in + std::int64_t(s) * shape.outputs(), dout_in + std::int64_t(s + 1) * shape.outputs());
        for (int l = L; l >= 1; --l) {
            const int din = shape.sizes[l - 1], dl = shape.sizes[l];
            const T* W = theta + shape.weight_offset(l);
            T* dW = dtheta + shape.weight_offset(l);
            T* db = dW + std::int64_t(dl) * din;
            const T* in = (l == 1) ? x + std::int64_t(s) * din
                                   : acts + shape.act_offset(l - 1, B) + std::int64_t(s) * shape.act_ld(l - 1);
            gprev.assign(din, T(0));
            for (int o = 0; o < dl; ++o) {
                db[o] += g[o];
                for (int i = 0; i < din; ++i) {
                    dW[std::int64_t(o) * din + i] += g[o] * in[i];
                    gprev[i] += g[o] * W[std::int64_t(o) * din + i];
                }
            }
            if (l > 1)
                for (int i = 0; i < din; ++i) gprev[i] *= in[i] > T(0) ? T(shape.slope_positive) : T(shape.slope_negative);
            else if (dx)
                for (int i = 0; i < din; ++i) dx[std::int64_t(s) * din + i] = gprev[i];
            g.swap(gprev);
        }
    }
}

#define HINF_INSTANTIATE_MLP(T)                                                                              \
    template void mlp_pack_weights<T>(T*, const T*, const MlpShape&);                                        \
    template void mlp_forward<T>(T*, const T*, const T*, int, const MlpShape&, const T*);                    \
    template void mlp_backward<T>(T*, T*, const T*, const T*, const T*, const T*, int, const MlpShape&, T*, bool, \
                                  const T*);                                                                 \
    template void mlp_forward_naive<T>(T*, const T*, const T*, int, const MlpShape&);                        \
    template void mlp_backward_naive<T>(T*, T*, const T*, const T*, const T*, const T*, int, const MlpShape&);
HINF_INSTANTIATE_MLP(float)
HINF_INSTANTIATE_MLP(double)

}  // namespace hinf::kern
