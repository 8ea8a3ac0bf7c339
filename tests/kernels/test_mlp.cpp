// MLP kernels: the fast forward/backward agree with their naive twins for several shapes and both
// precisions.
#include <catch2/catch.hpp>
#include <random>

#include "helpers.hpp"
#include "mlp.hpp"
#include "train_step.hpp"

using namespace hinf::kern;

template <typename T>
static void check_against_naive(GemmPath path, const std::vector<int>& sizes, int B, double tol) {
    MlpShape sh;
    sh.gemm = path;
    sh.sizes = sizes;
    sh.slope_positive = 0.9;
    sh.slope_negative = 0.05;
    std::mt19937 gen(12345);
    std::uniform_real_distribution<double> u(-1, 1);
    std::vector<T> theta(sh.param_count()), x(std::size_t(B) * sh.inputs()), dout(std::size_t(B) * sh.outputs());
    for (auto& v : theta) v = T(u(gen));
    for (auto& v : x) v = T(u(gen));
    for (auto& v : dout) v = T(u(gen));
    std::vector<T> acts(B * sh.act_per_sample()), acts_ref(acts.size());
    mlp_forward(acts.data(), theta.data(), x.data(), B, sh);
    mlp_forward_naive(acts_ref.data(), theta.data(), x.data(), B, sh);
    CHECK(hinf::test::max_rel_diff(acts, acts_ref, 1e-3) < tol);
    std::vector<T> g(theta.size(), T(0)), g_ref(theta.size(), T(0)), dx(x.size()), dx_ref(x.size());
    std::vector<T> scratch(sh.scratch_size(B));
    mlp_backward(g.data(), dx.data(), theta.data(), x.data(), acts.data(), dout.data(), B, sh, scratch.data());
    mlp_backward_naive(g_ref.data(), dx_ref.data(), theta.data(), x.data(), acts_ref.data(), dout.data(), B, sh);
    // float gradients sum B * 256 products of O(1) terms: entries below 1e-2 carry absolute rounding errors of a
    // few 1e-6 whatever the kernel (2.1e-3 relative at a 1e-3 floor with OpenBLAS's AVX-512 kernels), so they are
    // compared absolutely from 1e-2 down; a wrong index or a missing term still differs by O(1)
    const double floor = sizeof(T) == sizeof(float) ? 1e-2 : 1e-3;
    CHECK(hinf::test::max_rel_diff(g, g_ref, floor) < tol);
    CHECK(hinf::test::max_rel_diff(dx, dx_ref, floor) < tol);
}

TEST_CASE("mlp forward/backward match the naive twins", "[kernel][mlp]") {
    for (GemmPath path : {GEMM_OWN, GEMM_OPENBLAS, GEMM_EIGEN}) {
        INFO("GEMM path " << int(gemm_path_available(path)));
        check_against_naive<double>(path, {6, 256, 128, 32, 6}, 37, 1e-10);
        check_against_naive<double>(path, {3, 5, 7, 21}, 13, 1e-10);
        check_against_naive<float>(path, {6, 256, 128, 32, 21}, 50, 2e-3);
        check_against_naive<float>(path, {2, 9, 1}, 4, 1e-4);
    }
}

TEST_CASE("backward with overwrite equals zeroing then accumulating", "[kernel][mlp]") {
    MlpShape sh;
    sh.sizes = {3, 40, 17, 5};
    std::mt19937 gen(3);
    std::uniform_real_distribution<float> u(-1, 1);
    const int B = 23;
    std::vector<float> theta(sh.param_count()), x(B * 3), dout(B * 5);
    for (auto* v : {&theta, &x, &dout})
        for (auto& e : *v) e = u(gen);
    for (GemmPath path : {GEMM_OWN, GEMM_OPENBLAS, GEMM_EIGEN}) {
        sh.gemm = path;
        std::vector<float> acts(B * sh.act_per_sample()), scratch(sh.scratch_size(B));
        mlp_forward(acts.data(), theta.data(), x.data(), B, sh);
        std::vector<float> g1(theta.size(), 0.f), g2(theta.size(), 123.f);
        mlp_backward(g1.data(), (float*)nullptr, theta.data(), x.data(), acts.data(), dout.data(), B, sh, scratch.data());
        mlp_backward(g2.data(), (float*)nullptr, theta.data(), x.data(), acts.data(), dout.data(), B, sh, scratch.data(),
                     true);
        for (std::size_t i = 0; i < g1.size(); ++i) REQUIRE(g1[i] == g2[i]);
    }
}

TEST_CASE("backward accumulates into the caller's gradient", "[kernel][mlp]") {
    for (GemmPath path : {GEMM_OWN, GEMM_OPENBLAS, GEMM_EIGEN}) {
    MlpShape sh;
    sh.gemm = path;
    sh.sizes = {2, 4, 3};
    std::vector<double> theta(sh.param_count(), 0.3), x = {0.5, -1.0, 2.0, 0.1}, dout(6, 1.0);
    std::vector<double> acts(2 * sh.act_per_sample()), scratch(sh.scratch_size(2));
    mlp_forward(acts.data(), theta.data(), x.data(), 2, sh);
    std::vector<double> g1(theta.size(), 0.0), g2(theta.size(), 0.0);
    mlp_backward(g1.data(), (double*)nullptr, theta.data(), x.data(), acts.data(), dout.data(), 2, sh, scratch.data());
    mlp_backward(g2.data(), (double*)nullptr, theta.data(), x.data(), acts.data(), dout.data(), 2, sh, scratch.data());
    mlp_backward(g2.data(), (double*)nullptr, theta.data(), x.data(), acts.data(), dout.data(), 2, sh, scratch.data());
    for (std::size_t i = 0; i < g1.size(); ++i) CHECK(g2[i] == Approx(2 * g1[i]));
    }
}

TEST_CASE("activation rows are padded off 1 KB strides, the output layer never", "[kernel][mlp]") {
    MlpShape sh;
    sh.sizes = {6, 256, 128, 32, 64};
    CHECK(sh.act_ld(1) == 272);
    CHECK(sh.act_ld(2) == 144);
    CHECK(sh.act_ld(3) == 32);
    CHECK(sh.act_ld(4) == 64);  // H_L is read as [B x D_L] by the heads
    CHECK(sh.scratch_width() == 272);
    CHECK(sh.act_per_sample() == 272 + 144 + 32 + 64);
    CHECK(sh.act_offset(3, 10) == (272 + 144) * 10);
}

TEST_CASE("the step's workspace starts every buffer and every chunk on a cache line", "[kernel][mlp]") {
    StepConfig cfg;
    cfg.shape.sizes = {6, 256, 128, 32, 6};
    cfg.chunk = 100;
    CHECK(step_acts_stride(cfg) % 16 == 0);
    CHECK(step_acts_stride(cfg) >= cfg.chunk * cfg.shape.act_per_sample());
    CHECK(step_partial_stride(cfg.shape) % 16 == 0);
    CHECK(step_partial_stride(cfg.shape) >= cfg.shape.param_count());
    for (std::size_t n : {1, 37, 100000}) {
        LineVector<float> v(n);
        LineVector<double> w(n);
        CHECK(reinterpret_cast<std::uintptr_t>(v.data()) % 64 == 0);
        CHECK(reinterpret_cast<std::uintptr_t>(w.data()) % 64 == 0);
    }
}
