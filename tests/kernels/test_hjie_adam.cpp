// HJIE terms and output gradients against a hand-computed case; Adam against a hand-computed step;
// the quadratic head's invariants.
#include <catch2/catch.hpp>
#include <cmath>

#include "adam.hpp"
#include "head.hpp"
#include "hjie.hpp"

using namespace hinf::kern;

TEST_CASE("HJIE terms of eq. (16) on a hand-computed case", "[kernel][hjie]") {
    // n = 2, nv = 1, m = 1: x~ = (1, 2), Q = I -> q = 5; dA = (-1, 0.5); B = (0, 1); dC = 3; rho = 0.5
    // p = (2, -1): p^T dA = -2.5; |B^T p|^2 / (4 rho) = 1 / 2 = 0.5; -rho |dC|^2 = -4.5;  eps = 5 - 2.5 + 0.5 - 4.5 = -1.5
    double xt[2] = {1, 2}, dA[2] = {-1, 0.5}, B[2] = {0, 1}, dC[1] = {3}, q[1] = {5}, p[2] = {2, -1};
    HjieSystemView s{2, 1, 1, xt, dA, B, dC, q};
    double t[4];
    hjie_terms(t, p, s, 0, 0.5);
    CHECK(t[0] == 5.0);
    CHECK(t[1] == -2.5);
    CHECK(t[2] == 0.5);
    CHECK(t[3] == -4.5);
    HjieParams hp;
    hp.rho = 0.5;
    HjieSampleValue v = hjie_sample_forward(p, nullptr, s, 0, hp, HJIE_OBJECTIVE_PAPER);
    CHECK(v.residual == -1.5);
    CHECK(v.abs_sum == 12.5);
    CHECK(v.hinge == 2.25);
    // d(eps^2)/dp = 2 eps (dA + B B^T p / (2 rho)) = -3 * ((-1, 0.5) + (0, -1)) = (3, 1.5)
    double gp[2];
    double work[64];  // >= hjie_backward_workspace(n)
    hjie_sample_backward(gp, nullptr, p, nullptr, s, 0, hp, HJIE_OBJECTIVE_PAPER, 1.0, 0.0, work);
    CHECK(gp[0] == Approx(3.0));
    CHECK(gp[1] == Approx(1.5));
}

TEST_CASE("two coupled residuals of seed 001 eqs. (19)-(20) on a hand-computed case", "[kernel][hjie][mixed]") {
    // the case above with r^2 = 0.5: terms [5, -2.5, 0.5, -4.5]
    // eps1 = 5 - 2.5 + 0.5 - 4.5 = -1.5;  eps2 = 5 - 2.5 + |B^T p|^2/(2 r^2) - 2 r^2 |dC|^2 = 5 - 2.5 + 1 - 9 = -5.5
    // S1 = 5 + 2.5 + 0.5 + 4.5 = 12.5;  S2 = 5 + 2.5 + 1 + 9 = 17.5;  hinge = 2.25 + 30.25 = 32.5
    double xt[2] = {1, 2}, dA[2] = {-1, 0.5}, B[2] = {0, 1}, dC[1] = {3}, q[1] = {5}, p[2] = {2, -1};
    HjieSystemView s{2, 1, 1, xt, dA, B, dC, q};
    HjieParams hp;
    hp.rho = 0.5;
    hp.game = HJIE_GAME_MIXED;
    HjieSampleValue v = hjie_sample_forward(p, nullptr, s, 0, hp, HJIE_OBJECTIVE_PAPER);
    CHECK(v.residual == -1.5);
    CHECK(v.residual2 == -5.5);
    CHECK(v.abs_sum == 12.5);
    CHECK(v.abs_sum2 == 17.5);
    CHECK(v.hinge == 32.5);
    // d/dp (eps1^2 + eps2^2) = 2 eps1 (dA + B B^T p/(2 r^2)) + 2 eps2 (dA + B B^T p/r^2)
    //   = -3 ((-1, 0.5) + (0, -1)) - 11 ((-1, 0.5) + (0, -2)) = (3, 1.5) + (11, 16.5) = (14, 18)
    double gp[2];
    double work[64];  // >= hjie_backward_workspace(n)
    hjie_sample_backward(gp, nullptr, p, nullptr, s, 0, hp, HJIE_OBJECTIVE_PAPER, 1.0, 0.0, work);
    CHECK(gp[0] == Approx(14.0));
    CHECK(gp[1] == Approx(18.0));
    // the one-residual game is unchanged by the second residual's machinery
    hp.game = HJIE_GAME_HINF;
    HjieSampleValue v1 = hjie_sample_forward(p, nullptr, s, 0, hp, HJIE_OBJECTIVE_PAPER);
    CHECK(v1.hinge == 2.25);
    CHECK(v1.residual2 == 0.0);
}

TEST_CASE("an inactive second hinge leaves the dissipative loss and gradient bit-identical", "[kernel][hjie][mixed]") {
    // the hand case with margin 0.2: eps1/S1 + m = -0.12 + 0.2 > 0 (active), eps2/S2 + m = -5.5/17.5 + 0.2 < 0
    double xt[2] = {1, 2}, dA[2] = {-1, 0.5}, B[2] = {0, 1}, dC[1] = {3}, q[1] = {5}, p[2] = {2, -1};
    double P[4] = {1.5, 0.25, 0.25, 0.75};
    HjieSystemView s{2, 1, 1, xt, dA, B, dC, q};
    HjieParams hinf_p, mixed_p;
    hinf_p.rho = mixed_p.rho = 0.5;
    hinf_p.margin = mixed_p.margin = 0.2;
    mixed_p.game = HJIE_GAME_MIXED;
    HjieSampleValue a = hjie_sample_forward(p, P, s, 0, hinf_p, HJIE_OBJECTIVE_DISSIPATIVE);
    HjieSampleValue b = hjie_sample_forward(p, P, s, 0, mixed_p, HJIE_OBJECTIVE_DISSIPATIVE);
    REQUIRE(a.hinge > 0);
    REQUIRE(b.residual2 / b.abs_sum2 + 0.2 < 0);
    CHECK(a.hinge == b.hinge);
    CHECK(a.h2 == b.h2);
    double ga[2], gb[2], gPa[4], gPb[4];
    double work[64];  // >= hjie_backward_workspace(n)
    hjie_sample_backward(ga, gPa, p, P, s, 0, hinf_p, HJIE_OBJECTIVE_DISSIPATIVE, 0.7, 1.9, work);
    hjie_sample_backward(gb, gPb, p, P, s, 0, mixed_p, HJIE_OBJECTIVE_DISSIPATIVE, 0.7, 1.9, work);
    for (int k = 0; k < 2; ++k) CHECK(ga[k] == gb[k]);
    for (int k = 0; k < 4; ++k) CHECK(gPa[k] == gPb[k]);
}

TEST_CASE("mixed dissipative per-sample gradient matches central differences in p and P", "[kernel][hjie][mixed]") {
    // nv = n = 3 (a square g as in seed 001); margin large enough that both hinges are active
    double xt[3] = {0.3, -1.2, 0.8}, dA[3] = {0.5, 0.1, -0.7};
    double B[9] = {0.2, 1.0, -0.4, 0.3, 0.9, 0.1, -0.5, 0.0, 0.7};
    double dC[2] = {1.1, -0.6}, q[1] = {0.05};
    HjieSystemView s{3, 3, 2, xt, dA, B, dC, q};
    HjieParams hp;
    hp.rho = 0.3;
    hp.margin = 0.6;
    hp.horizon = 3.0;
    hp.h2_reference = 2.0;
    hp.game = HJIE_GAME_MIXED;
    double p[3] = {0.4, -0.9, 0.7};
    double P[9] = {1.0, 0.2, -0.1, 0.2, 0.8, 0.3, -0.1, 0.3, 1.5};
    auto total = [&](const double* pp, const double* PP) {
        HjieSampleValue v = hjie_sample_forward(pp, PP, s, 0, hp, HJIE_OBJECTIVE_DISSIPATIVE);
        return 0.7 * v.hinge + 1.9 * v.h2;
    };
    HjieSampleValue v0 = hjie_sample_forward(p, P, s, 0, hp, HJIE_OBJECTIVE_DISSIPATIVE);
    REQUIRE(v0.residual / v0.abs_sum + hp.margin > 0);
    REQUIRE(v0.residual2 / v0.abs_sum2 + hp.margin > 0);
    double gp[3], gP[9];
    double work[64];  // >= hjie_backward_workspace(n)
    hjie_sample_backward(gp, gP, p, P, s, 0, hp, HJIE_OBJECTIVE_DISSIPATIVE, 0.7, 1.9, work);
    const double h = 1e-6;
    for (int a = 0; a < 3; ++a) {
        double pp[3] = {p[0], p[1], p[2]}, pm[3] = {p[0], p[1], p[2]};
        pp[a] += h;
        pm[a] -= h;
        CHECK(gp[a] == Approx((total(pp, P) - total(pm, P)) / (2 * h)).epsilon(1e-6));
    }
    for (int a = 0; a < 9; ++a) {
        double Pp[9], Pm[9];
        for (int k = 0; k < 9; ++k) Pp[k] = Pm[k] = P[k];
        Pp[a] += h;
        Pm[a] -= h;
        CHECK(gP[a] == Approx((total(p, Pp) - total(p, Pm)) / (2 * h)).epsilon(1e-6).margin(1e-9));
    }
}

TEST_CASE("dissipative per-sample gradient matches central differences in p and P", "[kernel][hjie]") {
    double xt[3] = {0.3, -1.2, 0.8}, dA[3] = {0.5, 0.1, -0.7}, B[6] = {0.2, 1.0, -0.4, 0.3, 0.9, 0.1};
    double dC[2] = {1.1, -0.6}, q[1] = {0.05};
    HjieSystemView s{3, 2, 2, xt, dA, B, dC, q};
    HjieParams hp;
    hp.rho = 0.3;
    hp.margin = 0.5;
    hp.horizon = 3.0;
    hp.h2_reference = 2.0;
    double p[3] = {0.4, -0.9, 0.7};
    double P[9] = {1.0, 0.2, -0.1, 0.2, 0.8, 0.3, -0.1, 0.3, 1.5};
    auto total = [&](const double* pp, const double* PP) {
        HjieSampleValue v = hjie_sample_forward(pp, PP, s, 0, hp, HJIE_OBJECTIVE_DISSIPATIVE);
        return 0.7 * v.hinge + 1.9 * v.h2;
    };
    REQUIRE(hjie_sample_forward(p, P, s, 0, hp, HJIE_OBJECTIVE_DISSIPATIVE).hinge > 0);
    double gp[3], gP[9];
    double work[64];  // >= hjie_backward_workspace(n)
    hjie_sample_backward(gp, gP, p, P, s, 0, hp, HJIE_OBJECTIVE_DISSIPATIVE, 0.7, 1.9, work);
    const double h = 1e-6;
    for (int a = 0; a < 3; ++a) {
        double pp[3] = {p[0], p[1], p[2]}, pm[3] = {p[0], p[1], p[2]};
        pp[a] += h;
        pm[a] -= h;
        CHECK(gp[a] == Approx((total(pp, P) - total(pm, P)) / (2 * h)).epsilon(1e-6));
    }
    for (int a = 0; a < 9; ++a) {
        double Pp[9], Pm[9];
        for (int k = 0; k < 9; ++k) Pp[k] = Pm[k] = P[k];
        Pp[a] += h;
        Pm[a] -= h;
        CHECK(gP[a] == Approx((total(p, Pp) - total(p, Pm)) / (2 * h)).epsilon(1e-6).margin(1e-9));
    }
}

TEST_CASE("Adam step of eqs. (14)-(15) by hand", "[kernel][adam]") {
    // theta = 1, g = 0.5, k = 1: m = 0.05, v = 0.00025, m^ = 0.5, v^ = 0.25,
    // theta = 1 - 0.001 * 0.5 / sqrt(0.25 + 1e-7)
    double theta = 1.0, m = 0.0, v = 0.0, g = 0.5;
    AdamParams ap;
    adam_update(&theta, &m, &v, &g, 1, 1, ap);
    CHECK(m == Approx(0.05));
    CHECK(v == Approx(0.00025));
    CHECK(theta == Approx(1.0 - 0.001 * 0.5 / std::sqrt(0.25 + 1e-7)).epsilon(1e-14));
    // second step, g = -1: m = 0.9*0.05 - 0.1 = -0.055, v = 0.999*0.00025 + 0.001 = 0.00124975
    double g2 = -1.0, before = theta;
    adam_update(&theta, &m, &v, &g2, 1, 2, ap);
    double mh = -0.055 / (1 - 0.81), vh = 0.00124975 / (1 - 0.999 * 0.999);
    CHECK(theta == Approx(before - 0.001 * mh / std::sqrt(vh + 1e-7)).epsilon(1e-12));
}

TEST_CASE("Adam matches its naive twin", "[kernel][adam]") {
    std::vector<float> th(20000), m(20000, 0.f), v(20000, 0.f), g(20000), th2, m2, v2;
    for (int i = 0; i < 20000; ++i) {
        th[i] = 0.001f * float(i % 97);
        g[i] = std::sin(0.01f * float(i));
    }
    th2 = th;
    m2 = m;
    v2 = v;
    AdamParams ap;
    for (int k = 1; k <= 3; ++k) {
        adam_update(th.data(), m.data(), v.data(), g.data(), 20000, k, ap);
        adam_update_naive(th2.data(), m2.data(), v2.data(), g.data(), 20000, k, ap);
    }
    for (int i = 0; i < 20000; i += 97) CHECK(th[i] == Approx(th2[i]).epsilon(1e-5));
}

TEST_CASE("quadratic head gives p^T x~ > 0 and P symmetric positive definite", "[kernel][head]") {
    HeadParams hp;
    hp.kind = HEAD_QUADRATIC;
    hp.n = 3;
    hp.scale = 0.06;
    hp.eps = 0.01;
    double o[6] = {-1.0, 2.0, -3.0, 0.5, 0.0, -1.0};  // M = I + tril(o) is singular-ish, P stays >= c eps I
    double xt[3] = {1.0, -2.0, 0.5}, p[3], P[9];
    double hw[2 * 4 * 4];
    head_forward(p, P, o, xt, hp, hw);
    double px = p[0] * xt[0] + p[1] * xt[1] + p[2] * xt[2];
    CHECK(px > 0);
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) CHECK(P[a * 3 + b] == P[b * 3 + a]);
    CHECK(px >= hp.scale * hp.eps * (1 + 4 + 0.25) * (1 - 1e-12));
}

// 33+ states (a 40-state Lorenz-96): the head's n x n temporaries live in the caller's workspace, so any n works;
// dL/do from head_backward matches central differences of L = w^T p + <G, P> through head_forward
TEST_CASE("quadratic head for 40 states: backward matches central differences", "[kernel][head]") {
    const int n = 40, O = head_outputs(HEAD_QUADRATIC, n);
    HeadParams hp;
    hp.kind = HEAD_QUADRATIC;
    hp.n = n;
    hp.scale = 0.1;
    std::vector<double> o(O), xt(n), w(n), G(n * n), p(n), P(n * n), d_o(O);
    std::vector<double> work(head_workspace(HEAD_QUADRATIC, n));
    for (int k = 0; k < O; ++k) o[k] = 0.05 * std::sin(1.3 * k);
    for (int a = 0; a < n; ++a) {
        xt[a] = std::cos(0.7 * a);
        w[a] = 0.3 * std::sin(0.4 * a + 1);
    }
    for (int k = 0; k < n * n; ++k) G[k] = 0.01 * std::cos(0.11 * k);
    auto loss = [&](const std::vector<double>& oo) {
        head_forward(p.data(), P.data(), oo.data(), xt.data(), hp, work.data());
        double L = 0;
        for (int a = 0; a < n; ++a) L += w[a] * p[a];
        for (int k = 0; k < n * n; ++k) L += G[k] * P[k];
        return L;
    };
    loss(o);
    head_backward(d_o.data(), w.data(), G.data(), o.data(), xt.data(), hp, work.data());
    for (int k = 0; k < O; k += 37) {
        std::vector<double> op = o, om = o;
        op[k] += 1e-6;
        om[k] -= 1e-6;
        CHECK(d_o[k] == Approx((loss(op) - loss(om)) / 2e-6).epsilon(1e-5).margin(1e-8));
    }
}
