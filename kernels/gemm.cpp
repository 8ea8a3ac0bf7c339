// Register-blocked AVX-512 GEMM with fused epilogues, and its naive twin (see gemm.hpp).
// Blocking: C is walked in column panels of NR = 2 vectors; the k x NR panel of Bm (at most
// 256 x 32 floats = 32 KB) stays in L1 while MR = 8 rows of A at a time are broadcast against it,
// 16 accumulators in registers. Bm is read in place (gemm_own) or from panels packed once by the
// caller (gemm_own_packed: the MLP's weights). No zeroing pass: accumulators start at 0 or at C.
#include "gemm.hpp"

#include <algorithm>
#include <cstdint>
#include <vector>

#if defined(__AVX512F__)
#include <immintrin.h>
#endif

namespace hinf::kern {

namespace {
template <typename T>
inline T epilogue_scalar(T acc, int i, int j, const GemmEpi<T>& e) {
    switch (e.kind) {
        case EPI_BIAS: return acc + e.bias[j];
        case EPI_BIAS_LEAKY: {
            const T z = acc + e.bias[j];
            return z > T(0) ? e.a1 * z : e.a2 * z;
        }
        case EPI_LEAKY_GRAD: return acc * (e.H[std::int64_t(i) * e.ldh + j] > T(0) ? e.a1 : e.a2);
        default: return acc;
    }
}
}  // namespace

template <typename T>
void gemm_own_naive(int m, int n, int k, const T* A, int a_rs, int a_cs, const T* Bm, int ldb, T* C, int ldc,
                    bool accumulate, const GemmEpi<T>& epi) {
    for (int i = 0; i < m; ++i)
        for (int j = 0; j < n; ++j) {
            T acc = accumulate ? C[std::int64_t(i) * ldc + j] : T(0);
            for (int p = 0; p < k; ++p)
                acc += A[std::int64_t(i) * a_rs + std::int64_t(p) * a_cs] * Bm[std::int64_t(p) * ldb + j];
            C[std::int64_t(i) * ldc + j] = epilogue_scalar(acc, i, j, epi);
        }
}

#if defined(__AVX512F__)

bool gemm_own_available() { return true; }

namespace {

template <typename T>
struct Vec;
template <>
struct Vec<float> {
    using R = __m512;
    using M = __mmask16;
    static constexpr int W = 16;
    static R zero() { return _mm512_setzero_ps(); }
    static R set1(float x) { return _mm512_set1_ps(x); }
    static R load(M m, const float* p) { return _mm512_maskz_loadu_ps(m, p); }
    static void store(float* p, M m, R v) { _mm512_mask_storeu_ps(p, m, v); }
    static R fma(R a, R b, R c) { return _mm512_fmadd_ps(a, b, c); }
    static R add(R a, R b) { return _mm512_add_ps(a, b); }
    static R mul(R a, R b) { return _mm512_mul_ps(a, b); }
    static M gt0(R a) { return _mm512_cmp_ps_mask(a, _mm512_setzero_ps(), _CMP_GT_OQ); }
    static R blend(M m, R if_false, R if_true) { return _mm512_mask_blend_ps(m, if_false, if_true); }
    static M mask(int cnt) { return cnt >= W ? M(0xFFFF) : M((1u << cnt) - 1u); }
};
template <>
struct Vec<double> {
    using R = __m512d;
    using M = __mmask8;
    static constexpr int W = 8;
    static R zero() { return _mm512_setzero_pd(); }
    static R set1(double x) { return _mm512_set1_pd(x); }
    static R load(M m, const double* p) { return _mm512_maskz_loadu_pd(m, p); }
    static void store(double* p, M m, R v) { _mm512_mask_storeu_pd(p, m, v); }
    static R fma(R a, R b, R c) { return _mm512_fmadd_pd(a, b, c); }
    static R add(R a, R b) { return _mm512_add_pd(a, b); }
    static R mul(R a, R b) { return _mm512_mul_pd(a, b); }
    static M gt0(R a) { return _mm512_cmp_pd_mask(a, _mm512_setzero_pd(), _CMP_GT_OQ); }
    static R blend(M m, R if_false, R if_true) { return _mm512_mask_blend_pd(m, if_false, if_true); }
    static M mask(int cnt) { return cnt >= W ? M(0xFF) : M((1u << cnt) - 1u); }
};

#ifndef HINF_GEMM_MR
#define HINF_GEMM_MR 8
#define HINF_GEMM_NV 2
#endif
constexpr int kMR = HINF_GEMM_MR;  // rows of A per micro-tile
constexpr int kNV = HINF_GEMM_NV;  // vectors of C per row of a micro-tile

// C[i0..i0+MR) x [j0..j0+NV*W) with the last vector masked by `last`; pb: the packed panel
// [k x kNV*W] of Bm's columns j0...
template <typename T, int MR, int NV>
inline void micro(int k, const T* A, int a_rs, int a_cs, const T* pb, int ldb, T* C, int ldc, bool accumulate,
                  const GemmEpi<T>& e, int i0, int j0, typename Vec<T>::M last) {
    using V = Vec<T>;
    using R = typename V::R;
    using Mk = typename V::M;
    constexpr int W = V::W;
    Mk mk[NV];
    _Pragma("GCC unroll 16")
    for (int v = 0; v < NV; ++v) mk[v] = v == NV - 1 ? last : V::mask(W);
    R acc[MR][NV];
    _Pragma("GCC unroll 16")
    for (int r = 0; r < MR; ++r)
        _Pragma("GCC unroll 16")
        for (int v = 0; v < NV; ++v)
            acc[r][v] = accumulate ? V::load(mk[v], C + std::int64_t(i0 + r) * ldc + j0 + v * W) : V::zero();
    const T* a = A + std::int64_t(i0) * a_rs;
    const T* b = pb;
    for (int p = 0; p < k; ++p) {
        R bv[NV];
        _Pragma("GCC unroll 16")
        for (int v = 0; v < NV; ++v) bv[v] = V::load(mk[v], b + v * W);
        _Pragma("GCC unroll 16")
        for (int r = 0; r < MR; ++r) {
            const R av = V::set1(a[std::int64_t(r) * a_rs]);
            _Pragma("GCC unroll 16")
            for (int v = 0; v < NV; ++v) acc[r][v] = V::fma(av, bv[v], acc[r][v]);
        }
        a += a_cs;
        b += ldb;
    }
    const R a1 = V::set1(e.a1), a2 = V::set1(e.a2);
    _Pragma("GCC unroll 16")
    for (int r = 0; r < MR; ++r)
        _Pragma("GCC unroll 16")
        for (int v = 0; v < NV; ++v) {
            R z = acc[r][v];
            const int j = j0 + v * W;
            if (e.kind == EPI_BIAS || e.kind == EPI_BIAS_LEAKY) z = V::add(z, V::load(mk[v], e.bias + j));
            if (e.kind == EPI_BIAS_LEAKY) z = V::blend(V::gt0(z), V::mul(a2, z), V::mul(a1, z));
            if (e.kind == EPI_LEAKY_GRAD) {
                const R h = V::load(mk[v], e.H + std::int64_t(i0 + r) * e.ldh + j);
                z = V::mul(z, V::blend(V::gt0(h), a2, a1));
            }
            V::store(C + std::int64_t(i0 + r) * ldc + j, mk[v], z);
        }
}

// micro-tile with nv (1..NV) vectors per row
template <typename T, int MR, int NV>
inline void micro_nv(int nv, int k, const T* A, int a_rs, int a_cs, const T* pb, int ldb, T* C, int ldc,
                     bool accumulate, const GemmEpi<T>& e, int i0, int j0, typename Vec<T>::M last) {
    if constexpr (NV > 1) {
        if (nv < NV) return micro_nv<T, MR, NV - 1>(nv, k, A, a_rs, a_cs, pb, ldb, C, ldc, accumulate, e, i0, j0, last);
    }
    micro<T, MR, NV>(k, A, a_rs, a_cs, pb, ldb, C, ldc, accumulate, e, i0, j0, last);
}

// the last rem (1..MR) rows
template <typename T, int MR>
inline void micro_tail(int rem, int nv, int k, const T* A, int a_rs, int a_cs, const T* pb, int ldb, T* C, int ldc,
                       bool accumulate, const GemmEpi<T>& e, int i0, int j0, typename Vec<T>::M last) {
    if constexpr (MR > 1) {
        if (rem < MR)
            return micro_tail<T, MR - 1>(rem, nv, k, A, a_rs, a_cs, pb, ldb, C, ldc, accumulate, e, i0, j0, last);
    }
    micro_nv<T, MR, kNV>(nv, k, A, a_rs, a_cs, pb, ldb, C, ldc, accumulate, e, i0, j0, last);
}

}  // namespace

template <typename T>
int gemm_panel_width() {
    return kNV * Vec<T>::W;
}

namespace {
// C's column panels; panel(j0) gives the k x NR block of Bm for columns j0.. and its row stride
template <typename T, typename Panel>
void drive(int m, int n, int k, const T* A, int a_rs, int a_cs, Panel panel, T* C, int ldc, bool accumulate,
           const GemmEpi<T>& epi) {
    using V = Vec<T>;
    constexpr int W = V::W, NR = kNV * W;
    for (int j0 = 0; j0 < n; j0 += NR) {
        const int nc = std::min(NR, n - j0);
        const int nv = (nc + W - 1) / W;
        const typename V::M last = V::mask(nc - (nv - 1) * W);
        int ldb = 0;
        const T* pb = panel(j0, &ldb);
        int i0 = 0;
        for (; i0 + kMR <= m; i0 += kMR)
            micro_nv<T, kMR, kNV>(nv, k, A, a_rs, a_cs, pb, ldb, C, ldc, accumulate, epi, i0, j0, last);
        if (i0 < m)
            micro_tail<T, kMR - 1>(m - i0, nv, k, A, a_rs, a_cs, pb, ldb, C, ldc, accumulate, epi, i0, j0, last);
    }
}
}  // namespace

template <typename T>
void gemm_own_packed(int m, int n, int k, const T* A, int a_rs, int a_cs, const T* packed, T* C, int ldc,
                     bool accumulate, const GemmEpi<T>& epi) {
    constexpr int NR = kNV * Vec<T>::W;
    drive(m, n, k, A, a_rs, a_cs,
          [&](int j0, int* ldb) {
              *ldb = NR;
              return packed + std::int64_t(j0 / NR) * k * NR;
          },
          C, ldc, accumulate, epi);
}

template <typename T>
void gemm_own(int m, int n, int k, const T* A, int a_rs, int a_cs, const T* Bm, int ldb, T* C, int ldc,
              bool accumulate, const GemmEpi<T>& epi) {
    // Bm read in place, row by row (the last vector masked); measured faster than packing it per call
    drive(m, n, k, A, a_rs, a_cs,
          [&](int j0, int* ld) {
              *ld = ldb;
              return Bm + j0;
          },
          C, ldc, accumulate, epi);
}

#else  // no AVX-512: the own kernels are not built; mlp.cpp routes to OpenBLAS

bool gemm_own_available() { return false; }

template <typename T>
int gemm_panel_width() {
    return 64 / int(sizeof(T)) * 2;
}

template <typename T>
void gemm_own_packed(int m, int n, int k, const T* A, int a_rs, int a_cs, const T* packed, T* C, int ldc,
                     bool accumulate, const GemmEpi<T>& epi) {
    // reference only (this build routes the MLP to OpenBLAS): Bm unpacked, then the very loops of gemm_own, so both
    // give the same bits (two copies of the loop may be contracted into FMAs differently)
    const int NR = gemm_panel_width<T>();
    std::vector<T> Bm(std::size_t(k) * n);
    for (int p = 0; p < k; ++p)
        for (int j = 0; j < n; ++j)
            Bm[std::size_t(p) * n + j] = packed[std::int64_t(j / NR) * k * NR + std::int64_t(p) * NR + j % NR];
    gemm_own_naive(m, n, k, A, a_rs, a_cs, Bm.data(), n, C, ldc, accumulate, epi);
}

template <typename T>
void gemm_own(int m, int n, int k, const T* A, int a_rs, int a_cs, const T* Bm, int ldb, T* C, int ldc,
              bool accumulate, const GemmEpi<T>& epi) {
    gemm_own_naive(m, n, k, A, a_rs, a_cs, Bm, ldb, C, ldc, accumulate, epi);
}

#endif

template <typename T>
std::int64_t gemm_packed_size(int k, int n) {
    const int NR = gemm_panel_width<T>();
    return std::int64_t((n + NR - 1) / NR) * k * NR;
}

template <typename T>
void gemm_pack_b(T* packed, int k, int n, const T* Bm, int b_rs, int b_cs, int first, int last) {
    const int NR = gemm_panel_width<T>();
    const int panels = (n + NR - 1) / NR;
    if (last < 0 || last > panels) last = panels;
    for (int jb = first; jb < last; ++jb) {
        const int j0 = jb * NR, nc = std::min(NR, n - j0);
        T* dst = packed + std::int64_t(jb) * k * NR;
        for (int p = 0; p < k; ++p, dst += NR) {
            const T* src = Bm + std::int64_t(p) * b_rs + std::int64_t(j0) * b_cs;
            for (int c = 0; c < nc; ++c) dst[c] = src[std::int64_t(c) * b_cs];
            for (int c = nc; c < NR; ++c) dst[c] = T(0);
        }
    }
}

template int gemm_panel_width<float>();
template int gemm_panel_width<double>();
template std::int64_t gemm_packed_size<float>(int, int);
template std::int64_t gemm_packed_size<double>(int, int);
template void gemm_pack_b<float>(float*, int, int, const float*, int, int, int, int);
template void gemm_pack_b<double>(double*, int, int, const double*, int, int, int, int);
template void gemm_own_packed<float>(int, int, int, const float*, int, int, const float*, float*, int, bool,
                                     const GemmEpi<float>&);
template void gemm_own_packed<double>(int, int, int, const double*, int, int, const double*, double*, int, bool,
                                      const GemmEpi<double>&);
template void gemm_own<float>(int, int, int, const float*, int, int, const float*, int, float*, int, bool,
                              const GemmEpi<float>&);
template void gemm_own<double>(int, int, int, const double*, int, int, const double*, int, double*, int, bool,
                               const GemmEpi<double>&);
template void gemm_own_naive<float>(int, int, int, const float*, int, int, const float*, int, float*, int, bool,
                                    const GemmEpi<float>&);
template void gemm_own_naive<double>(int, int, int, const double*, int, int, const double*, int, double*, int, bool,
                                     const GemmEpi<double>&);

}  // namespace hinf::kern
