// The SDP binding on problems with answers known by hand: scalar and 2-state bounded-real lemmas
// (H-infinity norms), and an infeasible LMI. Each returned point is checked by eigenvalues here.
#include <catch2/catch.hpp>

#include <cmath>
#include <complex>

#include "lmi/sdp.hpp"

using hinf::lmi::SdpBlock;
using hinf::lmi::SdpProblem;
using hinf::lmi::sdp_solve;
using Eigen::MatrixXd;

namespace {

double max_eigenvalue(const MatrixXd& M) {
    Eigen::SelfAdjointEigenSolver<MatrixXd> es(0.5 * (M + M.transpose()));
    return es.eigenvalues().maxCoeff();
}

// Bounded-real lemma for xdot = A x + B v, z = C x:  min g2  s.t.  [A'P + PA + C'C, PB; B'P, -g2 I] < 0, P > 0.
// Variables: the upper triangle of P (n(n+1)/2), then g2. Blocks are posed as  -X - eps I >= 0.
SdpProblem brl_problem(const MatrixXd& A, const MatrixXd& B, const MatrixXd& C, double eps) {
    const int n = static_cast<int>(A.rows()), nv = static_cast<int>(B.cols());
    const int np = n * (n + 1) / 2;
    SdpProblem p;
    p.num_vars = np + 1;
    p.cost.assign(p.num_vars, 0.0);
    p.cost[np] = 1.0;
    SdpBlock lmi, pos;
    lmi.name = "brl";
    pos.name = "P";
    lmi.constant = MatrixXd::Zero(n + nv, n + nv);
    lmi.constant.topLeftCorner(n, n) = -C.transpose() * C;
    lmi.constant -= eps * MatrixXd::Identity(n + nv, n + nv);
    pos.constant = -eps * MatrixXd::Identity(n, n);
    int idx = 0;
    for (int a = 0; a < n; ++a)
        for (int b = a; b < n; ++b, ++idx) {
            MatrixXd E = MatrixXd::Zero(n, n);
            E(a, b) = E(b, a) = 1.0;
            MatrixXd F = MatrixXd::Zero(n + nv, n + nv);
            F.topLeftCorner(n, n) = A.transpose() * E + E * A;
            F.topRightCorner(n, nv) = E * B;
            F.bottomLeftCorner(nv, n) = B.transpose() * E;
            lmi.terms.emplace_back(idx, -F);
            pos.terms.emplace_back(idx, E);
        }
    MatrixXd Fg = MatrixXd::Zero(n + nv, n + nv);
    Fg.bottomRightCorner(nv, nv) = -MatrixXd::Identity(nv, nv);
    lmi.terms.emplace_back(np, -Fg);
    p.blocks = {lmi, pos};
    return p;
}

}  // namespace

TEST_CASE("SDP: scalar bounded-real lemma gives (cb/a)^2", "[lmi][sdp]") {
    // xdot = a x + b v, z = c x: ||G||_inf = |c b / a| (peak at omega = 0), by hand.
    const double a = -2.0, b = 3.0, c = 0.5, eps = 1e-7;
    SdpProblem p = brl_problem(MatrixXd::Constant(1, 1, a), MatrixXd::Constant(1, 1, b), MatrixXd::Constant(1, 1, c), eps);
    auto r = sdp_solve(p);
    REQUIRE(r.status == hinf::lmi::SDP_STATUS_OPTIMAL);
    CHECK(r.x[1] == Approx(std::pow(c * b / a, 2)).epsilon(1e-4));
    for (const auto& blk : p.blocks) CHECK(max_eigenvalue(-hinf::lmi::sdp_block_value(blk, r.x)) < 0);  // block >= 0
}

TEST_CASE("SDP: 2-state bounded-real lemma matches a frequency sweep of |G(jw)|", "[lmi][sdp]") {
    MatrixXd A(2, 2), B(2, 1), C(1, 2);
    A << 0, 1, -2, -0.4;  // lightly damped: a resonance peak well above the DC gain
    B << 0, 1;
    C << 1, 0;
    double peak = 0;
    for (int i = 0; i <= 200000; ++i) {  // |1 / (2 - w^2 + 0.4 j w)| on a fine grid
        const double w = 1e-4 * i;
        peak = std::max(peak, 1.0 / std::abs(std::complex<double>(2 - w * w, 0.4 * w)));
    }
    SdpProblem p = brl_problem(A, B, C, 1e-7);
    auto r = sdp_solve(p);
    REQUIRE(r.status == hinf::lmi::SDP_STATUS_OPTIMAL);
    CHECK(std::sqrt(r.x[3]) == Approx(peak).epsilon(1e-3));
    for (const auto& blk : p.blocks) CHECK(max_eigenvalue(-hinf::lmi::sdp_block_value(blk, r.x)) < 0);
}

TEST_CASE("SDP: contradictory LMIs are reported infeasible, not solved", "[lmi][sdp]") {
    // x >= 1 and -x >= 1
    SdpProblem p;
    p.num_vars = 1;
    p.cost = {1.0};
    SdpBlock a, b;
    a.name = "x>=1";
    a.constant = MatrixXd::Constant(1, 1, -1.0);
    a.terms.emplace_back(0, MatrixXd::Constant(1, 1, 1.0));
    b.name = "-x>=1";
    b.constant = MatrixXd::Constant(1, 1, -1.0);
    b.terms.emplace_back(0, MatrixXd::Constant(1, 1, -1.0));
    p.blocks = {a, b};
    auto r = sdp_solve(p);
    CHECK(r.status != hinf::lmi::SDP_STATUS_OPTIMAL);
    CHECK(r.status == hinf::lmi::SDP_STATUS_INFEASIBLE);
}

TEST_CASE("SDP: an objective unbounded below is reported unbounded", "[lmi][sdp]") {
    // min x  s.t.  1 - x >= 0
    SdpProblem p;
    p.num_vars = 1;
    p.cost = {1.0};
    SdpBlock a;
    a.name = "x<=1";
    a.constant = MatrixXd::Constant(1, 1, 1.0);
    a.terms.emplace_back(0, MatrixXd::Constant(1, 1, -1.0));
    p.blocks = {a};
    auto r = sdp_solve(p);
    CHECK(r.status == hinf::lmi::SDP_STATUS_UNBOUNDED);
}
