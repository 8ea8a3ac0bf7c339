// Batched multilayer perceptron with LeakyReLU hidden layers and a linear output layer:
// forward and backward on a chunk of samples, plus naive twins used as the reference in tests.
// Not the training loop (train_step.hpp) and not what the outputs mean (head.hpp).
//
// Shape legend:  B = samples in the chunk,  L = layers,  D[0] = inputs,  D[l] = width of layer l,
//                D[L] = outputs.  Parameters are one flat array: for l = 1..L, W_l [D[l] x D[l-1]]
//                row-major, then b_l [D[l]].  Activations: for l = 1..L, H_l [B x D[l]] row-major
//                (H_L is the network output, pre-activation).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace hinf::kern {

// Which GEMM kernels the fast forward/backward use (docs/method.md section 11). GEMM_OWN: hinf's
// register-blocked AVX-512 kernels with fused epilogues (gemm.hpp; the default where built);
// GEMM_OPENBLAS: OpenBLAS called directly, serially, once per product (the default without AVX-512);
// GEMM_EIGEN: Eigen's own products. All run one chunk on the calling thread (the caller splits chunks
// over OpenMP threads), so the bits do not depend on the thread count. A field of MlpShape, so it
// travels with the network it computes (no process-wide state). `hinf bench --gemm` measures each.
enum GemmPath { GEMM_OPENBLAS = 0, GEMM_EIGEN = 1, GEMM_OWN = 2 };
/// GEMM_OWN where gemm_own_available(), else GEMM_OPENBLAS.
GemmPath default_gemm_path();
/// The path that runs when `path` is asked for: GEMM_OWN where it is not built runs GEMM_OPENBLAS.
GemmPath gemm_path_available(GemmPath path);
/// e.g. "OpenBLAS 0.3.21 SkylakeX kernels (serial per chunk)"; names an OPENBLAS_CORETYPE override.
std::string gemm_description(GemmPath path);
/// Makes OpenBLAS run each call on the calling thread. Call outside parallel regions before a
/// parallel loop of fast-kernel calls (step_gradient and network_eval do); cheap when already set.
void gemm_prepare(GemmPath path);
/// While it lives, OpenBLAS runs at the thread count it had when the process started (its default, or
/// OPENBLAS_NUM_THREADS); the count before is restored after. For library code that calls BLAS/LAPACK (SDPA): its
/// answer then does not depend on whether gemm_prepare ran earlier in the process (threaded reductions round
/// differently).
class BlasThreadsAtStart {
public:
    BlasThreadsAtStart();
    ~BlasThreadsAtStart();
    BlasThreadsAtStart(const BlasThreadsAtStart&) = delete;
    BlasThreadsAtStart& operator=(const BlasThreadsAtStart&) = delete;

private:
    int saved_;
};

struct MlpShape {
    std::vector<int> sizes;      // D[0..L]
    double slope_positive = 1.0; // LeakyReLU alpha_1 (input > 0)
    double slope_negative = 0.01;// LeakyReLU alpha_2 (input <= 0)
    GemmPath gemm = default_gemm_path();  // the GEMM kernels forward/backward use

    int layers() const { return static_cast<int>(sizes.size()) - 1; }
    int inputs() const { return sizes.front(); }
    int outputs() const { return sizes.back(); }
    int max_width() const;
    /// Row stride (elements) of H_l in the activation buffer: D[l], padded by 16 elements for the
    /// hidden layers whose width is a multiple of 64 (rows 1 KB apart in f32 map to a quarter of L1's
    /// sets; see docs/method.md section 11). The output layer H_L is never padded. Padding changes no
    /// result: every product is the same sum in the same order.
    int act_ld(int l) const;
    /// Row stride of mlp_backward's scratch: max over l of act_ld(l).
    int scratch_width() const;
    /// Elements of mlp_backward's scratch for B samples: 2 x B x scratch_width, plus max over l of D[l-1] x D[l]
    /// for the own kernels' transposed dW of a layer narrower than a vector (no allocation inside the backward).
    std::int64_t scratch_size(int B) const;
    std::int64_t param_count() const;
    /// Offset of W_l (l = 1..L) in the flat parameter array; b_l follows W_l.
    std::int64_t weight_offset(int l) const;
    /// Activation elements per sample (sum of act_ld(1..L)).
    std::int64_t act_per_sample() const;
    /// Offset of H_l in a chunk's activation buffer with B samples.
    std::int64_t act_offset(int l, int B) const;
};

// GEMM_OWN's weights, packed once per weight update (not per chunk) into the own kernels' panels
// (gemm_pack_b): per layer W_l^T [D[l-1] x D[l]] for the forward, then W_l [D[l] x D[l-1]] for the
// backward. pack [mlp_pack_size]. Splits the packing over OpenMP threads when called outside a
// parallel region.
std::int64_t mlp_pack_size(const MlpShape& shape, int elem_size);
template <typename T>
void mlp_pack_weights(T* pack, const T* theta, const MlpShape& shape);

// acts [B x act_per_sample] (layer-major: H_1 for all B with row stride act_ld(1), then H_2, ...), theta [param_count],
// x [B x D0].  Output H_L at acts + act_offset(L, B). pack: mlp_pack_weights(theta) or null (then
// packed here when GEMM_OWN needs it).
template <typename T>
void mlp_forward(T* acts, const T* theta, const T* x, int B, const MlpShape& shape, const T* pack = nullptr);

// Accumulates dL/dtheta into dtheta (caller zeroes it), or with overwrite = true writes it (no zeroing
// needed). dout [B x D_L] = dL/dH_L. dx [B x D0] (may be null) receives dL/dx. scratch [shape.scratch_size(B)].
// pack: as for mlp_forward.
template <typename T>
void mlp_backward(T* dtheta, T* dx, const T* theta, const T* x, const T* acts, const T* dout, int B,
                  const MlpShape& shape, T* scratch, bool overwrite = false, const T* pack = nullptr);

// Naive twins: plain loops, one sample at a time; the reference for the fast versions.
template <typename T>
void mlp_forward_naive(T* acts, const T* theta, const T* x, int B, const MlpShape& shape);
template <typename T>
void mlp_backward_naive(T* dtheta, T* dx, const T* theta, const T* x, const T* acts, const T* dout, int B,
                        const MlpShape& shape);

}  // namespace hinf::kern
