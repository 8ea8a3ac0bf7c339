// The delay-LMI assembly on a scalar H-infinity filtering problem whose optimum is known independently:
// no delay, no noise, no measurement (Q0 = K = 0), e = alpha = 0, so the filter sees nothing and
// x-hat stays 0. Then (34) reduces, by hand, to a 2x2 condition whose optimum a brute-force search finds.
#include <catch2/catch.hpp>

#include <cmath>

#include "lmi/delay_lmi.hpp"

using namespace hinf::lmi;
using Eigen::MatrixXd;

TEST_CASE("delay LMI: scalar filtering problem with an independently known optimum", "[lmi]") {
    const double a = -3.0, b = 1.0;
    DelayVertex v;
    v.A0 = MatrixXd::Constant(1, 1, a);
    v.A1 = v.C0 = v.C1 = MatrixXd::Zero(1, 1);
    v.B = MatrixXd::Constant(1, 1, b);
    v.Q0 = v.Q1 = v.J0 = v.J1 = v.K = MatrixXd::Zero(1, 1);
    DelayLmiSpec s;
    s.vertices = {v};
    s.G = MatrixXd::Identity(1, 1);
    s.tau2 = 1.0;
    s.tau_bar = 0.0;
    s.margin = 1e-8;
    const DelayLmiResult r = delay_lmi_solve(s);
    REQUIRE(r.ok());
    for (const auto& c : delay_lmi_verify(s, r.point)) {
        INFO(c.name);
        CHECK(c.max_eigenvalue < 0);
    }

    // By hand: with Q, R -> 0 the condition is Sym(P(Abar + I/2)) + Gbar'Gbar + 2 g^-1 P Bbar Bbar' P < 0,
    // Abar = a I, Bbar = [b; 0], Gbar = [1 -1], P = [p1 p2; p2 p2]. The congruence xi = T z, T = [1 0; -1 1]
    // makes T'PT = diag(s, p) (s = p1 - p2, p = p2), Gbar T = [2 -1], T'P Bbar = b [s; p]:
    //   N0 + (2 b^2 / g) w w' < 0,  N0 = [2a's + 4, -2; -2, 2a'p + 1],  w = [s; p],  a' = a + 1/2,
    // i.e. N0 < 0 and g > 2 b^2 w' (-N0)^-1 w. The optimum is the infimum of that over s, p > 0.
    const double ap = a + 0.5;
    auto g_of = [&](double sv, double pv) -> double {
        MatrixXd N0(2, 2);
        N0 << 2 * ap * sv + 4, -2, -2, 2 * ap * pv + 1;
        Eigen::SelfAdjointEigenSolver<MatrixXd> es(N0);
        if (es.eigenvalues().maxCoeff() >= 0) return INFINITY;
        Eigen::Vector2d w(sv, pv);
        return 2 * b * b * w.dot((-N0).inverse() * w);
    };
    double best = INFINITY, bs = 1, bp = 1;
    for (int i = 0; i <= 400; ++i)
        for (int j = 0; j <= 400; ++j) {
            const double sv = std::pow(10.0, -2 + 4.0 * i / 400), pv = std::pow(10.0, -2 + 4.0 * j / 400);
            const double gv = g_of(sv, pv);
            if (gv < best) best = gv, bs = sv, bp = pv;
        }
    for (double span = 0.05; span > 1e-7; span *= 0.5)  // refine around the grid optimum
        for (int i = -10; i <= 10; ++i)
            for (int j = -10; j <= 10; ++j) {
                const double sv = bs * (1 + span * i / 10), pv = bp * (1 + span * j / 10);
                const double gv = g_of(sv, pv);
                if (gv < best) best = gv, bs = sv, bp = pv;
            }
    INFO("brute force gamma^2 = " << best << " at s = " << bs << ", p = " << bp << "; SDP " << r.objective);
    CHECK(r.objective == Approx(best).epsilon(1e-4));
    // and it is above the unstructured (full-P) bound 2 b^2 / a'^2 of e = x = b / (s - a') v
    CHECK(r.objective >= 2 * b * b / (ap * ap) * (1 - 1e-9));

    // With P = [P1 -P2; -P2 P2] the same congruence gives xi'P xi = x'(P1 - P2)x + e'P2 e, e = x here:
    // N = 2a' diag(s, p) + diag(0, 1) + (2 b^2/g) w w', feasible as s -> 0 iff 2a'p + 1 + 2 b^2 p^2 / g < 0,
    // so the infimum is the unstructured bound 2 b^2 / a'^2 itself (approached as s -> 0).
    s.p_structure = DELAY_P_ERROR;
    const DelayLmiResult e = delay_lmi_solve(s);
    REQUIRE(e.ok());
    CHECK(e.objective == Approx(2 * b * b / (ap * ap)).epsilon(2e-3));
}
