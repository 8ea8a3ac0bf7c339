// The gain variant's kernels (docs/method.md section 14): the closed-form sup over v, n of the dissipation
// inequality equals a brute-force maximisation; analytic gradients of the per-sample loss, the storage and the
// gain head equal central differences in double; the minibatch gradient equals central differences through the
// network and is bit-identical for 1 and 2 threads; S is positive definite by construction.
#include <omp.h>

#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>
#include <random>
#include <vector>

#include "gain.hpp"
#include "gain_fd.hpp"
#include "random.hpp"

using namespace hinf::kern;

namespace {

// one random sample of the problem: n = 3, nv = 2, m = 2 (m < n)
struct Case {
    int n = 3, nv = 2, m = 2;
    std::vector<double> xt, dA, B, dC, q, K, S, xt0;
    HjieSystemView view() const { return {n, nv, m, xt.data(), dA.data(), B.data(), dC.data(), q.data()}; }
};

Case make_case(unsigned seed) {
    std::mt19937 g(seed);
    std::normal_distribution<double> N(0.0, 1.0);
    Case c;
    auto fill = [&](std::vector<double>& v, int k) {
        v.resize(k);
        for (double& x : v) x = N(g);
    };
    fill(c.xt, c.n);
    fill(c.dA, c.n);
    fill(c.B, c.n * c.nv);
    fill(c.dC, c.m);
    fill(c.K, c.n * c.m);
    fill(c.xt0, c.n);
    c.q = {0.3 * (c.xt[0] * c.xt[0] + c.xt[1] * c.xt[1] + c.xt[2] * c.xt[2])};
    std::vector<double> L;
    fill(L, c.n * c.n);
    c.S.assign(c.n * c.n, 0.0);
    for (int a = 0; a < c.n; ++a)
        for (int b = 0; b < c.n; ++b) {
            for (int k = 0; k < c.n; ++k) c.S[a * c.n + b] += 0.3 * L[a * c.n + k] * L[b * c.n + k];
            if (a == b) c.S[a * c.n + b] += 0.1;
        }
    return c;
}

// x~'Q x~ + dV/dt - rho |v|^2 - rho |n|^2 with V = x~'S x~, x~' = dA - K dC + B v - K n
double hamiltonian(const Case& c, const double* v, const double* nn, double rho) {
    const int n = c.n;
    double h = c.q[0];
    std::vector<double> xdot(n);
    for (int a = 0; a < n; ++a) {
        double t = c.dA[a];
        for (int j = 0; j < c.m; ++j) t -= c.K[a * c.m + j] * (c.dC[j] + nn[j]);
        for (int j = 0; j < c.nv; ++j) t += c.B[a * c.nv + j] * v[j];
        xdot[a] = t;
    }
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) h += 2.0 * c.xt[a] * c.S[a * n + b] * xdot[b];
    for (int j = 0; j < c.nv; ++j) h -= rho * v[j] * v[j];
    for (int j = 0; j < c.m; ++j) h -= rho * nn[j] * nn[j];
    return h;
}

}  // namespace

TEST_CASE("gain variant: the closed-form sup over v, n equals a brute-force maximisation", "[kernel][gain]") {
    for (unsigned seed = 1; seed <= 5; ++seed) {
        Case c = make_case(seed);
        INFO("seed " << seed);
        const double rho = 0.7;
        GainLossParams gp;
        gp.rho = rho;
        const double closed = gain_sample_forward(c.K.data(), c.S.data(), c.view(), 0, gp).residual;
        // brute force: gradient ascent on the concave quadratic in w = (v, n) from zero, independent of the formula
        std::vector<double> w(c.nv + c.m, 0.0);
        const double h = 1e-6;
        for (int it = 0; it < 20000; ++it) {
            std::vector<double> grad(w.size());
            for (std::size_t k = 0; k < w.size(); ++k) {
                std::vector<double> wp = w, wm = w;
                wp[k] += h;
                wm[k] -= h;
                grad[k] = (hamiltonian(c, wp.data(), wp.data() + c.nv, rho) -
                           hamiltonian(c, wm.data(), wm.data() + c.nv, rho)) / (2 * h);
            }
            for (std::size_t k = 0; k < w.size(); ++k) w[k] += 0.2 / rho * grad[k];
        }
        const double brute = hamiltonian(c, w.data(), w.data() + c.nv, rho);
        CHECK(brute == Approx(closed).epsilon(1e-8));
        // and no random (v, n) exceeds it
        std::mt19937 g(seed);
        std::normal_distribution<double> N(0.0, 3.0);
        for (int k = 0; k < 1000; ++k) {
            std::vector<double> r(c.nv + c.m);
            for (double& x : r) x = N(g);
            CHECK(hamiltonian(c, r.data(), r.data() + c.nv, rho) <= closed + 1e-12);
        }
    }
}

TEST_CASE("gain variant: the closed-form sup is convex in K for a fixed S, continuous and discrete",
          "[kernel][gain][ensemble]") {
    // docs/method.md 16.15: gains that keep the inequality with one storage S keep it on average, so the mean gain
    // of an ensemble with a common storage keeps it too; a mutation that made H concave in K fails here
    std::mt19937 g(11);
    std::normal_distribution<double> N(0.0, 1.0);
    for (const bool discrete : {false, true})
        for (unsigned seed = 1; seed <= 20; ++seed) {
            Case c = make_case(seed);
            GainLossParams gp;
            gp.rho = discrete ? 200.0 : 0.7;  // discrete: rho above |[B -K]'S[B -K]|, where the sup over (v, n) is finite
            gp.discrete = discrete;
            std::vector<double> K1 = c.K, K2(c.K.size()), Km(c.K.size());
            for (std::size_t j = 0; j < K2.size(); ++j) {
                K2[j] = 2.0 * N(g);
                Km[j] = 0.5 * (K1[j] + K2[j]);
            }
            const double h1 = gain_sample_forward(K1.data(), c.S.data(), c.view(), 0, gp).residual;
            const double h2 = gain_sample_forward(K2.data(), c.S.data(), c.view(), 0, gp).residual;
            const double hm = gain_sample_forward(Km.data(), c.S.data(), c.view(), 0, gp).residual;
            INFO((discrete ? "discrete" : "continuous") << ", seed " << seed << ": " << h1 << ", " << h2 << ", mean K "
                                                        << hm);
            REQUIRE(std::isfinite(h1 + h2));
            CHECK(hm <= 0.5 * (h1 + h2) + 1e-12 * (std::abs(h1) + std::abs(h2)));
            CHECK(hm < 0.5 * (h1 + h2));  // strictly: |K's|^2 / rho is strictly convex along K2 - K1 here
        }
}

TEST_CASE("gain variant: per-sample loss gradient equals central differences", "[kernel][gain][grad]") {
  // the sampled-data cap measured in the error scales D (the default) and in the storage's metric S
  // (objective.step_cap = "storage": the cap then has a gradient with respect to S too)
  for (const bool in_storage : {false, true}) {
    INFO("cap in the storage's metric: " << in_storage);
    int capped = 0;
    for (unsigned seed = 1; seed <= 6; ++seed) {
        Case c = make_case(seed);
        GainLossParams gp;
        gp.rho = 0.7;
        gp.margin = 2.0;  // the hinge is active for every seed
        gp.horizon = 3.0;
        gp.h2_reference = 2.5;
        gp.xt0 = c.xt0.data();
        gp.initial_weight = 0.7;
        const double dx[3] = {1.0, 0.5, 2.0};
        gp.dx = dx;
        gp.dt = 0.3;  // the sampled-data cap is active for some seeds
        gp.cap_in_storage = in_storage;
        gp.kappa = 1e9;
        const double uncapped = gain_sample_forward(c.K.data(), c.S.data(), c.view(), 0, gp).hinge;
        gp.kappa = 0.2;
        if (gain_sample_forward(c.K.data(), c.S.data(), c.view(), 0, gp).hinge != uncapped) ++capped;
        const double dh = 0.8, dh2 = 0.3;
        auto L = [&](const Case& cc) {
            GainSampleValue v = gain_sample_forward(cc.K.data(), cc.S.data(), cc.view(), 0, gp);
            return dh * v.hinge + dh2 * v.h2;
        };
        REQUIRE(gain_sample_forward(c.K.data(), c.S.data(), c.view(), 0, gp).hinge > 0);
        std::vector<double> gK(c.n * c.m), gS(c.n * c.n, 0.0);
        gain_sample_backward(gK.data(), gS.data(), c.K.data(), c.S.data(), c.view(), 0, gp, dh, dh2);
        const double h = 1e-6;
        for (int k = 0; k < c.n * c.m; ++k) {
            Case p = c, m = c;
            p.K[k] += h;
            m.K[k] -= h;
            CHECK(gK[k] == Approx((L(p) - L(m)) / (2 * h)).epsilon(1e-6).margin(1e-9));
        }
        for (int k = 0; k < c.n * c.n; ++k) {
            Case p = c, m = c;
            p.S[k] += h;
            m.S[k] -= h;
            CHECK(gS[k] == Approx((L(p) - L(m)) / (2 * h)).epsilon(1e-6).margin(1e-9));
        }
    }
    CHECK(capped > 0);
  }
}

TEST_CASE("gain variant: storage S is positive definite, storage and head gradients equal central differences",
          "[kernel][gain][grad]") {
    const int n = 4, m = 2, ns = n * (n + 1) / 2;
    std::mt19937 g(3);
    std::normal_distribution<double> N(0.0, 1.0);
    std::vector<double> s(ns), d = {2.0, 0.5, 1.0, 3.0}, dy = {0.7, 1.3}, gS(n * n), o(n * m), gK(n * m);
    for (double& x : s) x = 2.0 * N(g);
    for (double& x : gS) x = N(g);
    for (double& x : o) x = N(g);
    for (double& x : gK) x = N(g);
    const double c = 1.7, eps = 1e-3;
    std::vector<double> S(n * n);
    storage_forward(S.data(), s.data(), d.data(), n, c, eps);
    Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>> Sm(S.data());
    CHECK((Sm - Sm.transpose()).norm() == 0.0);
    CHECK(Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d>(Sm).eigenvalues().minCoeff() > 0);
    auto Ls = [&](const std::vector<double>& ss) {
        std::vector<double> SS(n * n);
        storage_forward(SS.data(), ss.data(), d.data(), n, c, eps);
        double t = 0;
        for (int k = 0; k < n * n; ++k) t += gS[k] * SS[k];
        return t;
    };
    std::vector<double> ds(ns);
    storage_backward(ds.data(), gS.data(), s.data(), d.data(), n, c);
    const double h = 1e-6;
    for (int k = 0; k < ns; ++k) {
        std::vector<double> p = s, mm = s;
        p[k] += h;
        mm[k] -= h;
        CHECK(ds[k] == Approx((Ls(p) - Ls(mm)) / (2 * h)).epsilon(1e-6));
    }
    std::vector<double> d_o(n * m), K(n * m);
    gain_head_backward(d_o.data(), gK.data(), d.data(), dy.data(), n, m, 0.4);
    gain_head_forward(K.data(), o.data(), d.data(), dy.data(), n, m, 0.4);
    for (int k = 0; k < n * m; ++k) {
        const int a = k / m, j = k % m;
        CHECK(K[k] == Approx(0.4 * d[a] * o[k] / dy[j]));
        CHECK(d_o[k] == Approx(0.4 * d[a] * gK[k] / dy[j]));
    }
}

namespace {
StepConfig small_gain_config(int n, int m) {
    StepConfig sc;
    sc.shape.sizes = {n, 7, 5, n * m};
    sc.shape.gemm = GEMM_EIGEN;
    sc.head.n = n;
    sc.chunk = 4;
    sc.gain.enabled = true;
    sc.gain.m = m;
    sc.gain.dx = {1.5, 0.7, 2.0};
    sc.gain.dy = {0.9, 1.1};
    sc.gain.xt0 = {1.0, -0.5, 0.3};
    sc.gain.rate = 0.8;
    sc.gain.storage_scale = 1.3;
    sc.gain.eps = 1e-2;
    sc.gain.h2_weight = 0.2;
    sc.gain.loss.rho = 0.6;
    sc.gain.loss.margin = 0.5;
    sc.gain.loss.horizon = 4.0;
    sc.gain.loss.h2_reference = 3.0;
    sc.gain.loss.initial_weight = 0.5;
    sc.gain.loss.dt = 0.2;
    sc.gain.loss.kappa = 0.3;
    return sc;
}

// the missile's paper-size gain network (6 states, 6 outputs, 6-256-128-32-36, chunks of 100, the default GEMM path)
// with its scales; the loss's settings are each test's own
StepConfig paper_gain_config() {
    const int n = 6, m = 6;
    StepConfig sc;
    sc.shape.sizes = {n, 256, 128, 32, n * m};
    sc.head.n = n;
    sc.chunk = 100;
    sc.gain.enabled = true;
    sc.gain.m = m;
    sc.gain.dx = {1e4, 6e3, 9e3, 300, 320, 410};
    sc.gain.dy = {2e3, 1e3, 1.5e3, 80, 60, 90};
    sc.gain.xt0 = {1e4, 6e3, 9e3, 300, -300, 400};
    sc.gain.rate = 0.14;
    sc.gain.storage_scale = 2.5;
    return sc;
}
}  // namespace

TEST_CASE("gain variant: graded knots run from 0 to the span with the last interval the ratio times the first",
          "[kernel][gain]") {
    GainSpec g;
    g.knot_span = 20.0;
    for (const int J : {1, 2, 5, 40}) {
        for (const double r : {1.0, 1.5, 30.0, 1e4}) {
            INFO("J " << J << " ratio " << r);
            g.knots = J;
            g.knot_ratio = r;
            CHECK(g.knot_time(0) == 0.0);
            CHECK(g.knot_time(J) == 20.0);
            for (int j = 0; j < J; ++j) CHECK(g.knot_time(j + 1) > g.knot_time(j));
            if (J > 1) {
                const double first = g.knot_time(1), last = 20.0 - g.knot_time(J - 1);
                CHECK(last / first == Approx(r).epsilon(1e-9));
                for (int j = 1; j + 1 < J; ++j)  // geometric: each interval the same factor times the one before
                    CHECK((g.knot_time(j + 1) - g.knot_time(j)) / (g.knot_time(j) - g.knot_time(j - 1)) ==
                          Approx(std::pow(r, 1.0 / (J - 1))).epsilon(1e-9));
            }
            if (r == 1.0)
                for (int j = 0; j <= J; ++j) CHECK(g.knot_time(j) == Approx(20.0 * j / J).epsilon(1e-15));
        }
    }
}

TEST_CASE("gain variant: minibatch gradient equals central differences, 1 and 2 threads bit-identical",
          "[kernel][gain][grad][determinism]") {
  // knots = 0: constant storage and the rate head; knots = 3: S(t) on knots (samples before, between, on and after
  // them) and the Riccati-form head K = rho S(t)^-1 (Hx' + D^-1 o diag(dy))
  // masked: the gain's structural zeros (network.gain_structure, docs/method.md 16.17) on two of the six entries
  // ratio 4: graded knots (network.knot_ratio; t_j = 0, 0.286, 0.857, 2)
  // in_storage: the sampled-data cap in the storage's metric (objective.step_cap = "storage"), through S(t)'s knots
  struct KnotCase {
    int knots;
    bool masked;
    double ratio;
    bool in_storage;
  };
  for (const auto& [knots, masked, ratio, in_storage] :
       std::vector<KnotCase>{{0, false, 1.0, false}, {3, false, 1.0, false}, {0, true, 1.0, false},
                             {3, true, 1.0, false}, {3, false, 4.0, false}, {0, false, 1.0, true},
                             {3, false, 1.0, true}}) {
    INFO("knots " << knots << " masked " << masked << " ratio " << ratio << " cap in the storage " << in_storage);
    const int n = 3, nv = 2, m = 2, N = 11;
    StepConfig sc = small_gain_config(n, m);
    sc.gain.loss.cap_in_storage = in_storage;
    if (masked) sc.gain.mask = {1, 0, 0, 1, 1, 1};
    sc.gain.knots = knots;
    sc.gain.knot_span = 2.0;
    sc.gain.knot_ratio = ratio;
    const std::int64_t P = sc.shape.param_count() + sc.gain.storage_params(n);
    std::vector<double> theta(P), xt(N * n), dA(N * n), B(N * n * nv), dC(N * m), q(N), z(N * n);
    rng_normal(theta.data(), P, 5, RNG_STREAM_INIT, 0, 0);
    for (double& x : theta) x *= 0.4;
    rng_normal(xt.data(), N * n, 5, RNG_STREAM_SAMPLES, 0, 0);
    rng_normal(dA.data(), N * n, 5, RNG_STREAM_SAMPLES, 1, 0);
    rng_normal(B.data(), N * n * nv, 5, RNG_STREAM_SAMPLES, 2, 0);
    rng_normal(dC.data(), N * m, 5, RNG_STREAM_SAMPLES, 3, 0);
    rng_normal(z.data(), N * n, 5, RNG_STREAM_SAMPLES, 4, 0);
    for (int i = 0; i < N; ++i) q[i] = 0.2 * (xt[i * n] * xt[i * n] + xt[i * n + 1] * xt[i * n + 1]);
    std::vector<double> t(N), Hx(N * m * n);
    for (int i = 0; i < N; ++i) t[i] = 0.23 * i;  // 0 ... 2.3: the first knot, between knots, after the span
    rng_normal(Hx.data(), N * m * n, 5, RNG_STREAM_SAMPLES, 5, 0);
    HjieSystemView view{n, nv, m, xt.data(), dA.data(), B.data(), dC.data(), q.data(), t.data(), Hx.data()};
    std::vector<std::int64_t> idx = {3, 0, 7, 1, 9, 10, 4, 2, 5};
    const int M = int(idx.size());
    StepWorkspace<double> ws;
    std::vector<double> grad(P), grad1(P);
    StepLoss L = gain_step_gradient(grad.data(), theta.data(), view, z.data(), idx.data(), M, sc, ws);
    REQUIRE(L.hinge > 0);
    omp_set_num_threads(1);
    StepWorkspace<double> ws1;
    gain_step_gradient(grad1.data(), theta.data(), view, z.data(), idx.data(), M, sc, ws1);
    omp_set_num_threads(2);
    CHECK(grad1 == grad);
    CHECK(hinf::test::check_gain_gradient_fd(grad, theta, view, z.data(), idx.data(), M, sc) > 20);
    if (in_storage) {  // the cap is active on this minibatch (else its gradient would not be checked)
        StepConfig open = sc;
        open.gain.loss.kappa = 1e9;
        StepWorkspace<double> wso;
        std::vector<double> go(P);
        CHECK(gain_step_gradient(go.data(), theta.data(), view, z.data(), idx.data(), M, open, wso).hinge < L.hinge);
    }
    // the evaluation path gives the same K as the training path's head
    std::vector<double> K(N * n * m), S(n * n), Sd(n * n), S2(n * n);
    const std::vector<double> Ktrain(ws.K.begin(), ws.K.begin() + M * n * m);  // K of minibatch row s = sample idx[s]
    gain_network_eval(K.data(), theta.data(), z.data(), Hx.data(), t.data(), N, sc, ws);
    for (int s = 0; s < M; ++s)  // ws.K is the head's K; the gain the filter runs has the mask's zeros
        for (int e = 0; e < n * m; ++e) {
            if (masked && sc.gain.mask[e] == 0.0) {
                CHECK(K[idx[s] * n * m + e] == 0.0);
                CHECK(Ktrain[s * n * m + e] != 0.0);
            } else {
                CHECK(K[idx[s] * n * m + e] == Approx(Ktrain[s * n * m + e]).epsilon(1e-12));
            }
        }
    if (knots == 0) {
        gain_storage_eval(S.data(), Sd.data(), theta.data(), 0.0, sc);
        storage_forward(S2.data(), theta.data() + sc.shape.param_count(), sc.gain.dx.data(), n, sc.gain.storage_scale,
                        sc.gain.eps);
        CHECK(S == S2);
    } else {  // S(t) positive definite, dS/dt its time derivative
        for (int i = 0; i < N; ++i) {
            gain_storage_eval(S.data(), Sd.data(), theta.data(), t[i], sc);
            // dS/dt by central differences of S(t) away from knots
            double from_knot = 1.0;
            for (int j = 0; j <= knots; ++j) from_knot = std::min(from_knot, std::fabs(t[i] - sc.gain.knot_time(j)));
            if (from_knot > 0.01 && t[i] < 1.99) {
                std::vector<double> Sp(n * n), Sm(n * n);
                gain_storage_eval(Sp.data(), static_cast<double*>(nullptr), theta.data(), t[i] + 1e-6, sc);
                gain_storage_eval(Sm.data(), static_cast<double*>(nullptr), theta.data(), t[i] - 1e-6, sc);
                for (int e = 0; e < n * n; ++e) CHECK(Sd[e] == Approx((Sp[e] - Sm[e]) / 2e-6).epsilon(1e-5).margin(1e-8));
            }
            Eigen::Map<const Eigen::Matrix<double, -1, -1, Eigen::RowMajor>> Se(S.data(), n, n);
            CHECK(Se.llt().info() == Eigen::Success);
        }
    }
  }
}

TEST_CASE("gain variant, time-varying storage: on a linear system the Riccati head and the H-infinity Riccati "
          "equation make the inequality an equality (method.md section 16.7)",
          "[kernel][gain]") {
    // x' = A x + B v, y = H x + n: with K = rho S^-1 H' and dS/dt = -(S A + A'S + Q + S B B'S / rho - rho H'H),
    // x~'Q x~ + x~'Sdot x~ + 2 s'(A - K H) x~ + |B's|^2/rho + |K's|^2/rho = 0 for every x~ (s = S x~)
    using Mat = Eigen::Matrix<double, -1, -1, Eigen::RowMajor>;
    const int n = 3, nv = 2, m = 2;
    const double rho = 0.7;
    Mat A(n, n), B(n, nv), Hm(m, n), Q = Mat::Identity(n, n) * 0.4, L(n, n);
    A << -0.5, 1.0, 0.0, -2.0, -0.3, 0.4, 0.1, 0.0, -1.0;
    B << 1.0, 0.0, 0.3, 1.0, 0.0, 0.5;
    Hm << 1.0, 0.0, 0.2, 0.0, 0.0, 1.0;
    L << 1.2, 0.0, 0.0, 0.3, 0.8, 0.0, -0.4, 0.2, 1.5;
    const Mat S = L * L.transpose();
    const Mat K = rho * S.llt().solve(Hm.transpose());
    const Mat Sdot = -(S * A + A.transpose() * S + Q + S * B * B.transpose() * S / rho - rho * Hm.transpose() * Hm);
    std::mt19937 g(3);
    std::normal_distribution<double> N(0.0, 1.0);
    for (int trial = 0; trial < 20; ++trial) {
        Eigen::VectorXd xt(n);
        for (int a = 0; a < n; ++a) xt[a] = N(g);
        const Eigen::VectorXd dA = A * xt, dC = Hm * xt;
        const double q = xt.dot(Q * xt);
        Mat Bc = B;
        HjieSystemView v{n, nv, m, xt.data(), dA.data(), Bc.data(), dC.data(), &q};
        GainLossParams lp;
        lp.rho = rho;
        const GainSampleValue val = gain_sample_forward(K.data(), S.data(), v, 0, lp, Sdot.data());
        CHECK(std::fabs(val.residual) < 1e-10 * val.abs_sum);
        // and any other gain does worse: the Riccati head is the minimiser over K for the linearised output
        Mat K2 = K;
        K2(trial % n, trial % m) += 0.05;
        CHECK(gain_sample_forward(K2.data(), S.data(), v, 0, lp, Sdot.data()).residual >= val.residual - 1e-12);
    }
}

TEST_CASE("gain variant: the minibatch gradient equals its naive twin at the paper's size", "[kernel][gain][naive]") {
    // 6 states, 6 outputs, the 6-256-128-32-36 network, M = 800 of N = 2000 in chunks of 100, the default GEMM path:
    // the fast path's chunking, kept S(t)/Cholesky/M(t), row-wise solves and chunk-ordered sums against plain loops
    const int n = 6, nv = 1, m = 6, N = 2000, M = 800;
    // group > 1: errors per estimate (samples idx[r G .. r G + G - 1] share z, t and Hx; one network row each)
    // masked: the missile's structural zeros (two positions see only their own output; docs/method.md 16.17)
    struct Case {
        int knots;
        bool discrete, output_scale;
        int group;
        bool masked = false;
        double ratio = 1.0;  // network.knot_ratio: graded knots
        int angles = 0;      // network.angle_inputs: that many states seen as (cos, sin), the input n + angles wide
    };
    for (const Case cs : {Case{0, false, false, 1}, Case{0, true, false, 1}, Case{35, false, false, 1},
                          Case{35, false, true, 1}, Case{0, false, false, 4}, Case{0, true, false, 4},
                          Case{35, false, true, 4}, Case{35, false, true, 4, true}, Case{0, true, false, 1, true},
                          Case{35, false, true, 4, false, 30.0}, Case{0, false, false, 1, false, 1.0, 1},
                          Case{35, false, true, 4, false, 1.0, 2}}) {
        INFO("knots " << cs.knots << " discrete " << cs.discrete << " per-state scale " << cs.output_scale << " group "
                      << cs.group << " masked " << cs.masked << " ratio " << cs.ratio << " angles " << cs.angles);
        StepConfig sc = paper_gain_config();
        const int D0 = n + cs.angles;
        sc.shape.sizes.front() = D0;
        sc.gain.loss.rho = 0.03;
        sc.gain.loss.margin = 0.02;
        sc.gain.loss.horizon = 70.0;
        sc.gain.loss.h2_reference = 7.0;
        sc.gain.loss.initial_weight = cs.knots > 0 ? 1.0 : 0.0;
        sc.gain.loss.dt = 0.01;
        sc.gain.loss.discrete = cs.discrete;
        sc.gain.knots = cs.knots;
        sc.gain.knot_span = 70.0;
        sc.gain.knot_ratio = cs.ratio;
        sc.gain.group = cs.group;
        if (cs.masked) {
            sc.gain.mask.assign(n * m, 1.0);
            for (int a = 0; a < n; ++a)
                for (int j = 0; j < m; ++j)
                    if (a != j && (a < 2 || j < 2)) sc.gain.mask[a * m + j] = 0.0;
            for (int a = 0; a < n; ++a)  // the storage: no entry between the components {x1}, {x2}, {x3, v}
                for (int b = 0; b <= a; ++b) sc.gain.smask.push_back(a == b || (a >= 2 && b >= 2) ? 1.0 : 0.0);
        }
        if (cs.output_scale) {
            sc.gain.sdx = {3e3, 2e3, 4e3, 150, 200, 170};
            sc.gain.corr.resize(n * m);
            for (int e = 0; e < n * m; ++e) sc.gain.corr[e] = 0.5 + 0.01 * e;
        }
        const std::int64_t P = sc.shape.param_count() + sc.gain.storage_params(n);
        std::vector<double> theta(P), xt(N * n), dA(N * n), B(N * n * nv), dC(N * m), q(N), z(N * D0), t(N);
        std::vector<double> Hx(N * m * n);
        rng_normal(theta.data(), P, 9, RNG_STREAM_INIT, 0, 0);
        for (std::int64_t k = 0; k < P; ++k) theta[k] *= k < sc.shape.param_count() ? 0.05 : 0.3;
        rng_normal(xt.data(), N * n, 9, RNG_STREAM_SAMPLES, 0, 0);
        rng_normal(dA.data(), N * n, 9, RNG_STREAM_SAMPLES, 1, 0);
        rng_normal(B.data(), N * n * nv, 9, RNG_STREAM_SAMPLES, 2, 0);
        rng_normal(dC.data(), N * m, 9, RNG_STREAM_SAMPLES, 3, 0);
        rng_normal(z.data(), N * D0, 9, RNG_STREAM_SAMPLES, 4, 0);
        rng_normal(Hx.data(), N * m * n, 9, RNG_STREAM_SAMPLES, 5, 0);
        for (int i = 0; i < N; ++i) {
            for (int a = 0; a < n; ++a) {
                xt[i * n + a] *= sc.gain.dx[a] * 1e-3;
                dA[i * n + a] *= sc.gain.dx[a] * 1e-3;
            }
            for (int j = 0; j < m; ++j) dC[i * m + j] *= sc.gain.dy[j] * 1e-3;
            double qq = 0;
            for (int a = 0; a < n; ++a) qq += 1e-5 * xt[i * n + a] * xt[i * n + a];
            q[i] = qq;
            t[i] = 77.0 * i / N;  // every knot interval, and past the span
        }
        const int G = cs.group;
        for (int i = 0; i < N; ++i) {  // a group's samples share their leader's estimate and time
            const int lead = i - i % G;
            for (int a = 0; a < D0; ++a) z[i * D0 + a] = z[lead * D0 + a];
            for (int e = 0; e < m * n; ++e) Hx[i * m * n + e] = Hx[lead * m * n + e];
            t[i] = t[lead];
        }
        HjieSystemView view{n, nv, m, xt.data(), dA.data(), B.data(), dC.data(), q.data(), t.data(), Hx.data()};
        std::vector<std::int64_t> idx(M);
        for (int s = 0; s < M; ++s) idx[s] = ((s / G) * 7919LL) % (N / G) * G + s % G;
        auto relative = [](const auto& a, const auto& b, std::int64_t from, std::int64_t to) {
            double d = 0, r = 0;
            for (std::int64_t k = from; k < to; ++k) {
                d += (double(a[k]) - double(b[k])) * (double(a[k]) - double(b[k]));
                r += double(b[k]) * double(b[k]);
            }
            return std::sqrt(d / std::max(r, 1e-300));
        };
        const std::int64_t Pm = sc.shape.param_count();
        {  // double: equal to rounding
            StepWorkspace<double> ws;
            std::vector<double> fast(P), naive(P);
            const StepLoss Lf = gain_step_gradient(fast.data(), theta.data(), view, z.data(), idx.data(), M, sc, ws);
            const StepLoss Ln = gain_step_gradient_naive(naive.data(), theta.data(), view, z.data(), idx.data(), M, sc);
            REQUIRE(Lf.hinge > 0);
            CHECK(Lf.loss == Approx(Ln.loss).epsilon(1e-12));
            CHECK(Lf.h2 == Approx(Ln.h2).epsilon(1e-12));
            CHECK(relative(fast, naive, 0, Pm) < 1e-10);
            CHECK(relative(fast, naive, Pm, P) < 1e-10);
            const int np = n * (n + 1) / 2;
            for (std::int64_t k = Pm; k < P && cs.masked; ++k)  // the held storage entries get no gradient
                if (sc.gain.smask[(k - Pm) % np] == 0.0) CHECK(fast[k] == 0.0);
        }
        {  // float (the default precision): the same up to single-precision sums in another order
            std::vector<float> th(theta.begin(), theta.end()), fast(P), naive(P);
            StepWorkspace<float> ws;
            const StepLoss Lf = gain_step_gradient(fast.data(), th.data(), view, z.data(), idx.data(), M, sc, ws);
            const StepLoss Ln = gain_step_gradient_naive(naive.data(), th.data(), view, z.data(), idx.data(), M, sc);
            CHECK(Lf.loss == Approx(Ln.loss).epsilon(1e-5));
            CHECK(relative(fast, naive, 0, Pm) < 1e-4);
            CHECK(relative(fast, naive, Pm, P) < 1e-4);
        }
    }
}

TEST_CASE("PackedWeights: panels packed once give the bits of packing at each call, a copy packs its own, stale() "
          "packs a changed theta", "[kernel][gain][pack]") {
    // the frozen network's and the on-line retrainer's evaluation (src/net/network.cpp, src/train/online_retrain.cpp):
    // a paper-size f32 network on the default GEMM path (the own kernels where built: their panels; elsewhere none)
    const int n = 6, m = 6, N = 5;
    const StepConfig sc = paper_gain_config();
    const std::int64_t P = sc.shape.param_count() + sc.gain.storage_params(n);
    std::vector<double> theta_d(P), z(N * n);
    rng_normal(theta_d.data(), P, 11, RNG_STREAM_INIT, 0, 0);
    rng_normal(z.data(), N * n, 11, RNG_STREAM_SAMPLES, 0, 0);
    std::vector<float> theta(P), changed(P);
    for (std::int64_t k = 0; k < P; ++k) {
        theta[k] = float(0.05 * theta_d[k]);
        changed[k] = float(0.06 * theta_d[k]);
    }
    auto eval = [&](const std::vector<float>& th, const float* pack) {
        StepWorkspace<float> ws;
        std::vector<double> K(N * n * m);
        gain_network_eval(K.data(), th.data(), z.data(), nullptr, nullptr, N, sc, ws, nullptr, nullptr, pack);
        return K;
    };
    const std::vector<double> K = eval(theta, nullptr), K_changed = eval(changed, nullptr);  // packed inside each call
    REQUIRE(K != K_changed);
    PackedWeights<float> packed;
    const float* first = packed.get(theta.data(), sc.shape);
    CHECK(eval(theta, first) == K);
    CHECK(packed.get(theta.data(), sc.shape) == first);  // not packed again
    PackedWeights<float> copy = packed;  // its own panels: a pointer into the original's would dangle once it goes
    const float* own = copy.get(theta.data(), sc.shape);
    packed = PackedWeights<float>();
    CHECK(eval(theta, own) == K);
    if (first != nullptr) CHECK(own != first);
    copy.stale();  // theta changed (a retraining): the next get packs it
    CHECK(eval(changed, copy.get(changed.data(), sc.shape)) == K_changed);
}
