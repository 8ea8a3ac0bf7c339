// hinf's own register-blocked GEMM for the MLP's chunk-sized products, with the elementwise work that
// follows each product fused into the store (bias, LeakyReLU, LeakyReLU's derivative), and its naive
// twin. AVX-512 only (compile-time: built when the compiler targets AVX-512F, e.g. HINF_NATIVE on an
// AVX-512 machine); elsewhere gemm_own_available() is false and mlp.cpp uses OpenBLAS.
// Not the choice of kernels (mlp.hpp GemmPath) and not the threading (the caller runs one chunk).
//
// Shape legend: C [m x n] row-major with row stride ldc; A [m x k] addressed as A[i*a_rs + p*a_cs]
// (a_rs = k, a_cs = 1: row-major A;  a_rs = 1, a_cs = lda: A given transposed); Bm [k x n] row-major,
// row stride ldb. Every C entry is one sum over p = 0..k-1 in order, so the bits do not depend on
// addresses, alignment or the thread count.
#pragma once
#include <cstdint>

namespace hinf::kern {

enum GemmEpilogue {
    EPI_NONE = 0,        // C = acc
    EPI_BIAS = 1,        // C = acc + bias[j]
    EPI_BIAS_LEAKY = 2,  // C = LeakyReLU(acc + bias[j]) with slopes a1 (> 0), a2 (<= 0)
    EPI_LEAKY_GRAD = 3,  // C = acc * (H[i*ldh + j] > 0 ? a1 : a2)
};

template <typename T>
struct GemmEpi {
    GemmEpilogue kind = EPI_NONE;
    const T* bias = nullptr;  // [n]
    const T* H = nullptr;     // [m x n], row stride ldh (EPI_LEAKY_GRAD)
    int ldh = 0;
    T a1 = T(1), a2 = T(0);
};

/// True when this build has the AVX-512 kernels (gemm_own is callable).
bool gemm_own_available();

/// C = epilogue(A Bm) (accumulate = false) or C = epilogue(C + A Bm) (accumulate = true).
template <typename T>
void gemm_own(int m, int n, int k, const T* A, int a_rs, int a_cs, const T* Bm, int ldb, T* C, int ldc,
              bool accumulate, const GemmEpi<T>& epi);

/// Columns per panel of a packed Bm (2 vectors: 32 floats, 16 doubles).
template <typename T>
int gemm_panel_width();
/// Floats a packed k x n Bm takes: ceil(n / panel width) panels of k x panel width.
template <typename T>
std::int64_t gemm_packed_size(int k, int n);
/// Packs Bm (element (p, j) at Bm[p*b_rs + j*b_cs]) into panels, zero-padded. Panels [first, last)
/// only (-1: all), so that callers can split the packing over threads.
template <typename T>
void gemm_pack_b(T* packed, int k, int n, const T* Bm, int b_rs, int b_cs, int first = 0, int last = -1);
/// gemm_own with Bm given packed by gemm_pack_b (no packing inside).
template <typename T>
void gemm_own_packed(int m, int n, int k, const T* A, int a_rs, int a_cs, const T* packed, T* C, int ldc,
                     bool accumulate, const GemmEpi<T>& epi);

/// Naive twin: three plain loops, the same definition.
template <typename T>
void gemm_own_naive(int m, int n, int k, const T* A, int a_rs, int a_cs, const T* Bm, int ldb, T* C, int ldc,
                    bool accumulate, const GemmEpi<T>& epi);

}  // namespace hinf::kern
