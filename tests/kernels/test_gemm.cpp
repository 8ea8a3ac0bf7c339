// hinf's own GEMM kernels: every epilogue, accumulate or not, A plain or transposed, edge tiles in
// both directions, against the naive twin; the bits do not depend on where the buffers live.
#include <catch2/catch.hpp>
#include <random>

#include "gemm.hpp"
#include "helpers.hpp"

using namespace hinf::kern;

template <typename T>
static void check_gemm(int m, int n, int k, bool trans_a, bool accumulate, GemmEpilogue kind, double tol) {
    std::mt19937 gen(m * 1000003 + n * 1009 + k);
    std::uniform_real_distribution<double> u(-1, 1);
    const int ldc = n + 3, ldb = n + 5;  // strides wider than the rows
    std::vector<T> A(std::size_t(m) * k), Bm(std::size_t(k) * ldb), bias(n), H(std::size_t(m) * n), C0(std::size_t(m) * ldc);
    for (auto* v : {&A, &Bm, &bias, &H, &C0})
        for (auto& x : *v) x = T(u(gen));
    GemmEpi<T> e;
    e.kind = kind;
    e.bias = bias.data();
    e.H = H.data();
    e.ldh = n;
    e.a1 = T(0.9);
    e.a2 = T(0.05);
    const int a_rs = trans_a ? 1 : k, a_cs = trans_a ? m : 1;
    std::vector<T> C = C0, Cref = C0;
    gemm_own(m, n, k, A.data(), a_rs, a_cs, Bm.data(), ldb, C.data(), ldc, accumulate, e);
    gemm_own_naive(m, n, k, A.data(), a_rs, a_cs, Bm.data(), ldb, Cref.data(), ldc, accumulate, e);
    CHECK(hinf::test::max_rel_diff(C, Cref, 0.05) < tol);  // |C| ~ sqrt(k): floor below that
    // padding between rows untouched
    for (int i = 0; i < m; ++i)
        for (int j = n; j < ldc; ++j) CHECK(C[std::size_t(i) * ldc + j] == C0[std::size_t(i) * ldc + j]);
}

TEST_CASE("own GEMM matches its naive twin", "[kernel][gemm]") {
    const GemmEpilogue kinds[] = {EPI_NONE, EPI_BIAS, EPI_BIAS_LEAKY, EPI_LEAKY_GRAD};
    const int shapes[][3] = {{1, 1, 1}, {7, 5, 3}, {8, 32, 6}, {13, 33, 17}, {100, 21, 32}, {100, 128, 256}, {37, 6, 100}};
    for (auto& s : shapes)
        for (GemmEpilogue kind : kinds)
            for (int t = 0; t < 2; ++t)
                for (int acc = 0; acc < 2; ++acc) {
                    check_gemm<float>(s[0], s[1], s[2], t, acc, kind, 1e-4);
                    check_gemm<double>(s[0], s[1], s[2], t, acc, kind, 1e-12);
                }
}

TEST_CASE("own GEMM bits do not depend on buffer alignment", "[kernel][gemm]") {
    const int m = 19, n = 45, k = 70;
    std::mt19937 gen(7);
    std::uniform_real_distribution<float> u(-1, 1);
    std::vector<float> A(m * k + 16), Bm(k * n + 16), C1(m * n + 16), C2(m * n + 16);
    for (auto& x : A) x = u(gen);
    for (auto& x : Bm) x = u(gen);
    gemm_own(m, n, k, A.data(), k, 1, Bm.data(), n, C1.data(), n, false, GemmEpi<float>{});
    // same values at shifted addresses
    std::vector<float> A2(A.size() + 3), B2(Bm.size() + 5);
    std::copy(A.begin(), A.end(), A2.begin() + 3);
    std::copy(Bm.begin(), Bm.end(), B2.begin() + 5);
    gemm_own(m, n, k, A2.data() + 3, k, 1, B2.data() + 5, n, C2.data() + 1, n, false, GemmEpi<float>{});
    for (int i = 0; i < m * n; ++i) REQUIRE(C1[i] == C2[i + 1]);
}

TEST_CASE("packed Bm read through strides gives the same bits as packing inside", "[kernel][gemm]") {
    // Bm^T stored row-major (as the MLP's weights are for the forward), packed with b_rs = 1, b_cs = k
    const int m = 21, n = 70, k = 37;
    std::mt19937 gen(11);
    std::uniform_real_distribution<double> u(-1, 1);
    std::vector<double> A(m * k), Bt(n * k), Bm(k * n), C1(m * n), C2(m * n);
    for (auto& x : A) x = u(gen);
    for (auto& x : Bt) x = u(gen);
    for (int p = 0; p < k; ++p)
        for (int j = 0; j < n; ++j) Bm[p * n + j] = Bt[j * k + p];
    std::vector<double> packed(gemm_packed_size<double>(k, n));
    gemm_pack_b(packed.data(), k, n, Bt.data(), 1, k);
    GemmEpi<double> e;
    gemm_own(m, n, k, A.data(), k, 1, Bm.data(), n, C1.data(), n, false, e);
    gemm_own_packed(m, n, k, A.data(), k, 1, packed.data(), C2.data(), n, false, e);
    for (int i = 0; i < m * n; ++i) REQUIRE(C1[i] == C2[i]);
}
