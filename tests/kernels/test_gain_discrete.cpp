// The gain variant's discrete-time kernel (docs/method.md section 16.8): the closed-form sup over w = (v, n) of the
// one-step inequality equals a brute-force maximisation and no random w exceeds it; where rho I - G'S G is not
// positive definite the sup is unbounded (shown along the top eigenvector) and the loss pushes back; the analytic
// gradients equal central differences in double in both regimes; gain_sample_forward dispatches on the flag.
#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>
#include <random>
#include <vector>

#include "gain.hpp"
#include "gain_discrete.hpp"

using namespace hinf::kern;

namespace {

// one random sample: n = 3, nv = 2, m = 2 (m < n)
struct DiscreteCase {
    int n = 3, nv = 2, m = 2;
    std::vector<double> xt, dA, B, dC, q, K, S, xt0;
    HjieSystemView view() const { return {n, nv, m, xt.data(), dA.data(), B.data(), dC.data(), q.data()}; }
};

DiscreteCase make_discrete_case(unsigned seed) {
    std::mt19937 g(seed);
    std::normal_distribution<double> N(0.0, 1.0);
    DiscreteCase c;
    auto fill = [&](std::vector<double>& v, int k, double s) {
        v.resize(k);
        for (double& x : v) x = s * N(g);
    };
    fill(c.xt, c.n, 1.0);
    fill(c.dA, c.n, 1.0);
    fill(c.B, c.n * c.nv, 0.5);
    fill(c.dC, c.m, 1.0);
    fill(c.K, c.n * c.m, 0.5);
    fill(c.xt0, c.n, 1.0);
    c.q = {0.3 * (c.xt[0] * c.xt[0] + c.xt[1] * c.xt[1] + c.xt[2] * c.xt[2])};
    std::vector<double> L;
    fill(L, c.n * c.n, 1.0);
    c.S.assign(c.n * c.n, 0.0);
    for (int a = 0; a < c.n; ++a)
        for (int b = 0; b < c.n; ++b) {
            for (int k = 0; k < c.n; ++k) c.S[a * c.n + b] += 0.3 * L[a * c.n + k] * L[b * c.n + k];
            if (a == b) c.S[a * c.n + b] += 0.1;
        }
    return c;
}

// x~'Q x~ + V(x~_{k+1}) - V(x~_k) - rho |w|^2 with V = x~'S x~, x~_{k+1} = dA - K (dC + n) + B v, w = (v, n)
double one_step(const DiscreteCase& c, const double* w, double rho) {
    const int n = c.n;
    std::vector<double> next(n);
    for (int a = 0; a < n; ++a) {
        double t = c.dA[a];
        for (int j = 0; j < c.m; ++j) t -= c.K[a * c.m + j] * (c.dC[j] + w[c.nv + j]);
        for (int j = 0; j < c.nv; ++j) t += c.B[a * c.nv + j] * w[j];
        next[a] = t;
    }
    double h = c.q[0];
    for (int a = 0; a < n; ++a)
        for (int b = 0; b < n; ++b) h += c.S[a * n + b] * (next[a] * next[b] - c.xt[a] * c.xt[b]);
    for (int j = 0; j < c.nv + c.m; ++j) h -= rho * w[j] * w[j];
    return h;
}

// lambda_max(G'S G), G = [B, -K]
double lambda_max(const DiscreteCase& c) {
    const int p = c.nv + c.m;
    Eigen::MatrixXd G(c.n, p), S(c.n, c.n);
    for (int a = 0; a < c.n; ++a) {
        for (int j = 0; j < c.nv; ++j) G(a, j) = c.B[a * c.nv + j];
        for (int j = 0; j < c.m; ++j) G(a, c.nv + j) = -c.K[a * c.m + j];
        for (int b = 0; b < c.n; ++b) S(a, b) = c.S[a * c.n + b];
    }
    Eigen::MatrixXd Gh = G.transpose() * S * G;
    return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(Gh).eigenvalues().maxCoeff();
}

}  // namespace

TEST_CASE("gain variant, discrete time: the closed-form sup over w equals a brute-force maximisation",
          "[kernel][gain][discrete]") {
    for (unsigned seed = 1; seed <= 6; ++seed) {
        DiscreteCase c = make_discrete_case(seed);
        INFO("seed " << seed);
        const double rho = 1.5 * lambda_max(c) + 0.1;  // concave
        GainLossParams gp;
        gp.rho = rho;
        gp.discrete = true;
        const GainSampleValue v = gain_discrete_sample_forward(c.K.data(), c.S.data(), c.view(), 0, gp);
        REQUIRE(std::isfinite(v.residual));
        // brute force: gradient ascent on the concave quadratic from zero, central differences only
        const int p = c.nv + c.m;
        std::vector<double> w(p, 0.0);
        const double h = 1e-6, step = 0.25 / rho;
        for (int it = 0; it < 40000; ++it) {
            std::vector<double> grad(p);
            for (int k = 0; k < p; ++k) {
                std::vector<double> wp = w, wm = w;
                wp[k] += h;
                wm[k] -= h;
                grad[k] = (one_step(c, wp.data(), rho) - one_step(c, wm.data(), rho)) / (2 * h);
            }
            for (int k = 0; k < p; ++k) w[k] += step * grad[k];
        }
        CHECK(one_step(c, w.data(), rho) == Approx(v.residual).epsilon(1e-8));
        // no random w exceeds it
        std::mt19937 g(seed);
        std::normal_distribution<double> N(0.0, 3.0);
        for (int k = 0; k < 1000; ++k) {
            std::vector<double> r(p);
            for (double& x : r) x = N(g);
            CHECK(one_step(c, r.data(), rho) <= v.residual + 1e-10 * std::fabs(v.residual) + 1e-12);
        }
        // the scale: S_i = |q| + x~'S x~ + e'S e + T >= |H_i|
        CHECK(v.abs_sum >= std::fabs(v.residual));
        // the flag dispatches gain_sample_forward here
        const GainSampleValue d = gain_sample_forward(c.K.data(), c.S.data(), c.view(), 0, gp);
        CHECK(d.residual == v.residual);
        CHECK(d.hinge == v.hinge);
        CHECK(d.h2 == v.h2);
    }
}

TEST_CASE("gain variant, discrete time: not concave in w, the sup is unbounded and the loss pushes back",
          "[kernel][gain][discrete]") {
    DiscreteCase c = make_discrete_case(3);
    const double lmax = lambda_max(c);
    GainLossParams gp;
    gp.rho = 0.8 * lmax;
    gp.discrete = true;
    const GainSampleValue v = gain_discrete_sample_forward(c.K.data(), c.S.data(), c.view(), 0, gp);
    CHECK(std::isinf(v.residual));
    const double expected = (1 + gp.margin) * (1 + gp.margin) + std::pow(lmax / gp.rho - (1 - gp.margin), 2);
    CHECK(v.hinge == Approx(expected).epsilon(1e-10));
    // along the top eigenvector of G'S G the one-step value grows without bound
    const int p = c.nv + c.m;
    Eigen::MatrixXd G(c.n, p), S(c.n, c.n);
    for (int a = 0; a < c.n; ++a) {
        for (int j = 0; j < c.nv; ++j) G(a, j) = c.B[a * c.nv + j];
        for (int j = 0; j < c.m; ++j) G(a, c.nv + j) = -c.K[a * c.m + j];
        for (int b = 0; b < c.n; ++b) S(a, b) = c.S[a * c.n + b];
    }
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(G.transpose() * S * G);
    Eigen::VectorXd top = eig.eigenvectors().col(p - 1);
    double last = -INFINITY;
    for (double s : {1e1, 1e2, 1e3}) {
        std::vector<double> w(p);
        for (int j = 0; j < p; ++j) w[j] = s * top[j];
        const double val = std::max(one_step(c, w.data(), gp.rho), [&] {
            for (int j = 0; j < p; ++j) w[j] = -w[j];
            return one_step(c, w.data(), gp.rho);
        }());
        CHECK(val > last);
        last = val;
    }
    CHECK(last > 1e4);
}

TEST_CASE("gain variant, discrete time: per-sample loss gradient equals central differences",
          "[kernel][gain][discrete][grad]") {
    for (unsigned seed = 1; seed <= 6; ++seed) {
        for (double rho_factor : {1.5, 0.99, 0.7}) {  // concave with margin; concave inside the margin; not concave
            DiscreteCase c = make_discrete_case(seed);
            INFO("seed " << seed << " rho / lambda_max " << rho_factor);
            GainLossParams gp;
            gp.discrete = true;
            gp.rho = rho_factor * lambda_max(c);
            gp.margin = rho_factor > 1.2 ? 2.0 : 0.05;  // the relative hinge is active where concave
            gp.horizon = 3.0;
            gp.h2_reference = 2.5;
            gp.xt0 = c.xt0.data();
            gp.initial_weight = 0.7;
            gp.disturbance_intensity = 0.6;
            gp.noise_intensity = 1.3;
            const double dh = 0.8, dh2 = 0.3;
            auto L = [&](const DiscreteCase& cc) {
                GainSampleValue v = gain_discrete_sample_forward(cc.K.data(), cc.S.data(), cc.view(), 0, gp);
                return dh * v.hinge + dh2 * v.h2;
            };
            REQUIRE(gain_discrete_sample_forward(c.K.data(), c.S.data(), c.view(), 0, gp).hinge > 0);
            std::vector<double> gK(c.n * c.m), gS(c.n * c.n, 0.0);
            gain_sample_backward(gK.data(), gS.data(), c.K.data(), c.S.data(), c.view(), 0, gp, dh, dh2);
            const double h = 1e-6;
            for (int k = 0; k < c.n * c.m; ++k) {
                DiscreteCase p = c, m = c;
                p.K[k] += h;
                m.K[k] -= h;
                CHECK(gK[k] == Approx((L(p) - L(m)) / (2 * h)).epsilon(1e-5).margin(1e-8));
            }
            for (int k = 0; k < c.n * c.n; ++k) {
                DiscreteCase p = c, m = c;
                p.S[k] += h;
                m.S[k] -= h;
                CHECK(gS[k] == Approx((L(p) - L(m)) / (2 * h)).epsilon(1e-5).margin(1e-8));
            }
        }
    }
}
