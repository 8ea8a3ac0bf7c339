// The Kalman-form gain head of discrete-time systems (kernels/gain.hpp gain_kalman_forward / _backward, docs/method.md
// section 16.16): K = F P H'(H P H' + diag(dy)^2)^-1 by its definition; its backward equals central differences; the
// correction A H = P H' W^-1 H has its eigenvalues in [0, 1) however steep H is; and the minibatch gradient with this
// head equals central differences, its naive twin and itself on 1 and 2 threads.
#include <omp.h>

#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>
#include <vector>

#include "gain.hpp"
#include "gain_fd.hpp"
#include "random.hpp"

using namespace hinf::kern;

namespace {
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

GainSpec kalman_spec(int n, int m) {
    GainSpec g;
    g.enabled = true;
    g.kalman = true;
    g.m = m;
    g.kalman_scale = 0.7;
    g.eps = 1e-2;
    for (int a = 0; a < n; ++a) g.dx.push_back(0.5 + 0.4 * a);
    for (int j = 0; j < m; ++j) g.dy.push_back(0.8 + 0.3 * j);
    return g;
}

// P = c D (M M' + eps I) D, M = I + tril(o), from the packing's definition
RowMat p_of(const std::vector<double>& o, const GainSpec& g, int n) {
    RowMat M = RowMat::Identity(n, n), D = RowMat::Zero(n, n);
    int k = 0;
    for (int a = 0; a < n; ++a)
        for (int b = 0; b <= a; ++b) M(a, b) += o[k++];
    for (int a = 0; a < n; ++a) D(a, a) = g.dx[a];
    return g.kalman_scale * D * (M * M.transpose() + g.eps * RowMat::Identity(n, n)) * D;
}
}  // namespace

TEST_CASE("Kalman-form head: K = F P H'(H P H' + R)^-1 and its gradient equals central differences",
          "[kernel][gain][kalman]") {
    for (int m : {1, 2, 3}) {
        INFO("outputs " << m);
        const int n = 3, np = n * (n + 1) / 2;
        const GainSpec g = kalman_spec(n, m);
        std::vector<double> o(np), F(n * n), H(m * n), gK(n * m);
        rng_normal(o.data(), np, 3, RNG_STREAM_SAMPLES, m, 0);
        rng_normal(F.data(), n * n, 3, RNG_STREAM_SAMPLES, m, 1);
        rng_normal(H.data(), m * n, 3, RNG_STREAM_SAMPLES, m, 2);
        rng_normal(gK.data(), n * m, 3, RNG_STREAM_SAMPLES, m, 3);
        for (double& x : o) x *= 0.5;
        std::vector<double> K(n * m), A(n * m);
        gain_kalman_forward(K.data(), A.data(), o.data(), F.data(), H.data(), g, n, m);
        // by the definition, in Eigen
        const RowMat P = p_of(o, g, n);
        const RowMat Fm = Eigen::Map<const RowMat>(F.data(), n, n), Hm = Eigen::Map<const RowMat>(H.data(), m, n);
        RowMat R = RowMat::Zero(m, m);
        for (int j = 0; j < m; ++j) R(j, j) = g.dy[j] * g.dy[j];
        const RowMat Aref = P * Hm.transpose() * (Hm * P * Hm.transpose() + R).inverse();
        const RowMat Kref = Fm * Aref;
        for (int a = 0; a < n; ++a)
            for (int j = 0; j < m; ++j) {
                CHECK(K[a * m + j] == Approx(Kref(a, j)).epsilon(1e-12).margin(1e-14));
                CHECK(A[a * m + j] == Approx(Aref(a, j)).epsilon(1e-12).margin(1e-14));
            }
        // d(gK . K)/do
        std::vector<double> d_o(np);
        gain_kalman_backward(d_o.data(), gK.data(), o.data(), F.data(), H.data(), g, n, m);
        const double h = 1e-6;
        for (int k = 0; k < np; ++k) {
            std::vector<double> op = o, om = o, Kp(n * m), Km(n * m);
            op[k] += h;
            om[k] -= h;
            gain_kalman_forward(Kp.data(), static_cast<double*>(nullptr), op.data(), F.data(), H.data(), g, n, m);
            gain_kalman_forward(Km.data(), static_cast<double*>(nullptr), om.data(), F.data(), H.data(), g, n, m);
            double lp = 0, lm = 0;
            for (int e = 0; e < n * m; ++e) {
                lp += gK[e] * Kp[e];
                lm += gK[e] * Km[e];
            }
            CHECK(d_o[k] == Approx((lp - lm) / (2 * h)).epsilon(1e-6).margin(1e-9));
        }
        // float network outputs: the same arithmetic on the rounded values
        std::vector<float> of(o.begin(), o.end()), d_of(np);
        gain_kalman_backward(d_of.data(), gK.data(), of.data(), F.data(), H.data(), g, n, m);
        for (int k = 0; k < np; ++k) CHECK(d_of[k] == Approx(d_o[k]).epsilon(1e-4).margin(1e-6));
    }
}

TEST_CASE("Kalman-form head: the correction A H cannot over-correct however steep the sensor",
          "[kernel][gain][kalman]") {
    // A H = P H' W^-1 H is similar to P^1/2 H' W^-1 H P^1/2 (symmetric, 0 <= . < I): eigenvalues in [0, 1), so the
    // error map F (I - A H) of a steep sensor stays F's contraction or expansion, never the over-correction
    // |1 - K h| > 1 of a gain that does not divide by the slope (docs/method.md section 16.16)
    const int n = 3;
    for (int trial = 0; trial < 40; ++trial) {
        const int m = 1 + trial % 3, np = n * (n + 1) / 2;
        const GainSpec g = kalman_spec(n, m);
        std::vector<double> o(np), F(n * n, 0.0), H(m * n), K(n * m), A(n * m);
        rng_normal(o.data(), np, 11, RNG_STREAM_SAMPLES, trial, 0);
        rng_normal(H.data(), m * n, 11, RNG_STREAM_SAMPLES, trial, 1);
        const double steep = std::pow(10.0, trial % 8 - 2);  // 1e-2 ... 1e5
        for (double& x : H) x *= steep;
        for (int a = 0; a < n; ++a) F[a * n + a] = 1.0;
        gain_kalman_forward(K.data(), A.data(), o.data(), F.data(), H.data(), g, n, m);
        const RowMat AH = Eigen::Map<const RowMat>(A.data(), n, m) * Eigen::Map<const RowMat>(H.data(), m, n);
        const Eigen::VectorXcd ev = Eigen::EigenSolver<RowMat>(AH).eigenvalues();
        for (int k = 0; k < n; ++k) {
            INFO("trial " << trial << " slope scale " << steep << " eigenvalue " << ev[k]);
            CHECK(std::fabs(ev[k].imag()) < 1e-9);
            CHECK(ev[k].real() > -1e-9);
            CHECK(ev[k].real() < 1.0);
        }
    }
}

TEST_CASE("Kalman-form head: the minibatch gradient equals central differences and its naive twin",
          "[kernel][gain][kalman][grad][determinism]") {
    const int n = 3, nv = 2, m = 2, N = 11, np = n * (n + 1) / 2;
    for (int G : {1, 2}) {
        INFO("errors per estimate " << G);
        StepConfig sc;
        sc.shape.sizes = {n, 7, 5, np};
        sc.shape.gemm = GEMM_EIGEN;
        sc.head.n = n;
        sc.chunk = 4;
        sc.gain = kalman_spec(n, m);
        sc.gain.xt0 = {1.0, -0.5, 0.3};
        sc.gain.storage_scale = 1.3;
        sc.gain.h2_weight = 0.2;
        sc.gain.group = G;
        sc.gain.loss.rho = 2.5;
        sc.gain.loss.margin = 0.5;
        sc.gain.loss.horizon = 40.0;
        sc.gain.loss.h2_reference = 3.0;
        sc.gain.loss.discrete = true;
        const std::int64_t P = sc.shape.param_count() + sc.gain.storage_params(n);
        std::vector<double> theta(P), xt(N * n), dA(N * n), B(N * n * nv), dC(N * m), q(N), z(N * n);
        std::vector<double> t(N, 0.0), Hx(N * m * n), Fx(N * n * n);
        rng_normal(theta.data(), P, 6, RNG_STREAM_INIT, 0, 0);
        for (double& x : theta) x *= 0.3;
        rng_normal(xt.data(), N * n, 6, RNG_STREAM_SAMPLES, 0, 0);
        rng_normal(dA.data(), N * n, 6, RNG_STREAM_SAMPLES, 1, 0);
        rng_normal(B.data(), N * n * nv, 6, RNG_STREAM_SAMPLES, 2, 0);
        rng_normal(dC.data(), N * m, 6, RNG_STREAM_SAMPLES, 3, 0);
        rng_normal(z.data(), N * n, 6, RNG_STREAM_SAMPLES, 4, 0);
        rng_normal(Hx.data(), N * m * n, 6, RNG_STREAM_SAMPLES, 5, 0);
        rng_normal(Fx.data(), N * n * n, 6, RNG_STREAM_SAMPLES, 6, 0);
        for (double& x : B) x *= 0.3;
        for (int i = 0; i < N; ++i) {
            q[i] = 0.2 * (xt[i * n] * xt[i * n] + xt[i * n + 1] * xt[i * n + 1]);
            for (int a = 0; a < n; ++a) Fx[i * n * n + a * n + a] += 1.0;
            const int lead = i - i % G;  // a group's samples share their leader's estimate and Jacobians
            for (int a = 0; a < n; ++a) z[i * n + a] = z[lead * n + a];
            for (int e = 0; e < m * n; ++e) Hx[i * m * n + e] = Hx[lead * m * n + e];
            for (int e = 0; e < n * n; ++e) Fx[i * n * n + e] = Fx[lead * n * n + e];
        }
        HjieSystemView view{n, nv, m, xt.data(), dA.data(), B.data(), dC.data(), q.data(), t.data(), Hx.data(),
                            Fx.data()};
        std::vector<std::int64_t> idx = G == 1 ? std::vector<std::int64_t>{3, 0, 7, 1, 9, 10, 4, 2, 5}
                                               : std::vector<std::int64_t>{2, 3, 0, 1, 8, 9, 4, 5};
        const int M = int(idx.size());
        StepWorkspace<double> ws;
        std::vector<double> grad(P), grad1(P), naive(P);
        const StepLoss L = gain_step_gradient(grad.data(), theta.data(), view, z.data(), idx.data(), M, sc, ws);
        REQUIRE(L.hinge > 0);
        omp_set_num_threads(1);
        StepWorkspace<double> ws1;
        gain_step_gradient(grad1.data(), theta.data(), view, z.data(), idx.data(), M, sc, ws1);
        omp_set_num_threads(2);
        CHECK(grad1 == grad);
        const StepLoss Ln = gain_step_gradient_naive(naive.data(), theta.data(), view, z.data(), idx.data(), M, sc);
        CHECK(L.loss == Approx(Ln.loss).epsilon(1e-12));
        for (std::int64_t k = 0; k < P; ++k) CHECK(grad[k] == Approx(naive[k]).epsilon(1e-9).margin(1e-12));
        CHECK(hinf::test::check_gain_gradient_fd(grad, theta, view, z.data(), idx.data(), M, sc) > 20);
        // the evaluation path gives the training path's K
        std::vector<double> K(N * n * m), A(N * n * m);
        const std::vector<double> Ktrain(ws.K.begin(), ws.K.begin() + (M / G) * n * m);
        gain_network_eval(K.data(), theta.data(), z.data(), Hx.data(), t.data(), N, sc, ws, Fx.data(), A.data());
        for (int r = 0; r < M / G; ++r)
            for (int e = 0; e < n * m; ++e)
                CHECK(K[idx[r * G] * n * m + e] == Approx(Ktrain[r * n * m + e]).epsilon(1e-12));
        // K = F A at every estimate
        for (int i = 0; i < N; ++i) {
            const RowMat FA = Eigen::Map<const RowMat>(Fx.data() + i * n * n, n, n) *
                           Eigen::Map<const RowMat>(A.data() + i * n * m, n, m);
            for (int e = 0; e < n * m; ++e) CHECK(K[i * n * m + e] == Approx(FA.data()[e]).epsilon(1e-12).margin(1e-14));
        }
    }
}
