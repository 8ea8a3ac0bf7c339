// Seed 002's LMIs: the expanded blocks (34)/(45) against the theorem forms (27)/(38) and the un-Schured
// (32)/(42), printed Gamma entries typed from the paper, Theta_j against Lbar' P Lbar < beta I, and the
// designs for example (47) verified by eigenvalues of every block.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "helpers.hpp"
#include "lmi/delay_lmi.hpp"
#include "lmi/delay_run.hpp"

using namespace hinf::lmi;
using Eigen::MatrixXd;

namespace {

DelayConfig example_config(const std::string& file) {
    return delay_config_read(hinf::ConfigDoc::from_file(hinf::test::source_path("runs/" + file)));
}

MatrixXd rand_mat(std::mt19937& g, int r, int c) {
    std::normal_distribution<double> N(0, 1);
    MatrixXd M(r, c);
    for (int i = 0; i < r; ++i)
        for (int j = 0; j < c; ++j) M(i, j) = N(g);
    return M;
}
MatrixXd rand_spd(std::mt19937& g, int n) {
    MatrixXd A = rand_mat(g, n, n);
    return A * A.transpose() + 0.5 * MatrixXd::Identity(n, n);
}

DelayLmiPoint random_point(std::mt19937& g, int n, int l, int m) {
    DelayLmiPoint p;
    p.P1 = rand_spd(g, n);
    p.P2 = rand_spd(g, n);
    p.Q1 = rand_spd(g, n);
    p.Q2 = rand_mat(g, n, n);
    p.Q3 = rand_spd(g, n);
    p.R1 = rand_spd(g, n);
    p.R2 = rand_mat(g, n, n);
    p.R3 = rand_spd(g, n);
    std::uniform_real_distribution<double> U(0.5, 3.0);
    for (int j = 0; j < m; ++j) {
        p.beta.push_back(U(g));
        p.Y.push_back(rand_mat(g, n, l));
    }
    p.gamma2 = U(g) * 3;
    return p;
}

double max_eig(const MatrixXd& M) {
    Eigen::SelfAdjointEigenSolver<MatrixXd> es(0.5 * (M + M.transpose()));
    return es.eigenvalues().maxCoeff();
}

}  // namespace

TEST_CASE("delay LMI: expanded (34)/(45) equals the theorem form (27)/(38) with L_j = P2^-1 Y_j", "[lmi]") {
    const unsigned seed = 20160322;
    INFO("random seed " << seed);
    std::mt19937 g(seed);
    for (const char* file : {"delay_hinf.toml", "delay_h2hinf.toml"}) {
        for (int variant = 0; variant < 4; ++variant) {
            DelayConfig c = example_config(file);
            c.spec.sigma_placement = variant % 2 ? DELAY_SIGMA_STATE : DELAY_SIGMA_THEOREM;
            c.spec.p_structure = variant / 2 ? DELAY_P_ERROR : DELAY_P_PAPER;
            c.spec.e1 = 0.3, c.spec.e2 = 0.2, c.spec.e3 = 0.4, c.spec.e4 = 0.1;  // make the sigma term visible
            const DelayLmiPoint p = random_point(g, 2, 1, 3);
            const auto L = delay_lmi_gains(p);
            for (int i = 0; i < 3; ++i)
                for (int j = 0; j < 3; ++j)
                    for (int k = 0; k < 3; ++k) {
                        const MatrixXd a = delay_lmi_pi2(c.spec, p, i, j, k);
                        const MatrixXd b = delay_lmi_pi1(c.spec, delay_lmi_full_P(p, c.spec.p_structure), delay_lmi_full_Q(p),
                                                         delay_lmi_full_R(p), L, p.beta,
                                                         c.spec.design == DELAY_DESIGN_HINF ? p.gamma2 : c.spec.gamma2,
                                                         i, j, k);
                        REQUIRE(a.rows() == b.rows());
                        CHECK((a - b).cwiseAbs().maxCoeff() <= 1e-9 * (1 + b.cwiseAbs().maxCoeff()));
                    }
        }
    }
}

TEST_CASE("delay LMI: the Schur complement of (27)/(38) is (32)/(42)", "[lmi]") {
    std::mt19937 g(7);
    for (const char* file : {"delay_hinf.toml", "delay_h2hinf.toml"}) {
        DelayConfig c = example_config(file);
        const DelayLmiPoint p = random_point(g, 2, 1, 3);
        const auto L = delay_lmi_gains(p);
        const MatrixXd P = delay_lmi_full_P(p, c.spec.p_structure), Q = delay_lmi_full_Q(p), R = delay_lmi_full_R(p);
        const double g2 = c.spec.design == DELAY_DESIGN_HINF ? p.gamma2 : c.spec.gamma2;
        for (int i = 0; i < 3; ++i) {
            const int j = (i + 1) % 3, k = (i + 2) % 3;
            const MatrixXd M = delay_lmi_pi1(c.spec, P, Q, R, L, p.beta, g2, i, j, k);
            const int a = 12;  // eta = [xi, xi_t, integral]: 6n = 12 rows; the rest is block-diagonal
            const MatrixXd X = M.topRightCorner(a, M.cols() - a);
            const MatrixXd D = M.bottomRightCorner(M.rows() - a, M.cols() - a);
            const MatrixXd schur = M.topLeftCorner(a, a) - X * D.inverse() * X.transpose();
            const MatrixXd cond = delay_lmi_condition(c.spec, P, Q, R, L, p.beta, g2, i, j, k);
            CHECK((schur - cond).cwiseAbs().maxCoeff() <= 1e-8 * (1 + cond.cwiseAbs().maxCoeff()));
        }
    }
}

TEST_CASE("delay LMI: printed Gamma entries of (34) appear where the paper puts them", "[lmi]") {
    std::mt19937 g(11);
    DelayConfig c = example_config("delay_hinf.toml");
    c.spec.sigma_placement = DELAY_SIGMA_THEOREM;
    const DelayLmiPoint p = random_point(g, 2, 1, 3);
    const int i = 2, j = 0, k = 1, n = 2;
    const auto &vi = c.spec.vertices[i], &vj = c.spec.vertices[j], &vk = c.spec.vertices[k];
    const MatrixXd& Y = p.Y[j];
    const MatrixXd G = c.spec.G, I = MatrixXd::Identity(2, 2);
    const double t2 = c.spec.tau2 * c.spec.tau2, tb = c.spec.tau_bar;
    const double sigma = 0.5 * (std::pow(c.spec.e1, 2) + std::pow(c.spec.e3, 2)) + std::pow(c.spec.e2, 2) +
                         std::pow(c.spec.e4, 2);
    const double bs = p.beta[j] + p.beta[k];
    const MatrixXd M = delay_lmi_pi2(c.spec, p, i, j, k);
    // Remark 5, typed from the paper
    const MatrixXd G11 = p.P1 * vi.A0 + vi.A0.transpose() * p.P1 + Y * vi.Q0 + vi.Q0.transpose() * Y.transpose() +
                         G.transpose() * G + p.P1 + p.Q1 + t2 * p.R1 + bs * sigma * I;
    const MatrixXd G12 = vi.A0.transpose() * p.P2 + p.P2 * vj.A0 + vi.Q0.transpose() * Y.transpose() - Y * vk.Q0 -
                         G.transpose() * G + p.P2 + p.Q2 + t2 * p.R2;
    const MatrixXd G22 = p.P2 * vj.A0 - Y * vk.Q0 + vj.A0.transpose() * p.P2 - vk.Q0.transpose() * Y.transpose() +
                         G.transpose() * G + p.P2 + p.Q3 + t2 * p.R3 + bs * sigma * I;
    const MatrixXd G13 = p.P1 * vi.A1 + Y * vi.Q1, G14 = p.P2 * vj.A1 - Y * vk.Q1, G23 = p.P2 * vi.A1 + Y * vi.Q1;
    const MatrixXd G33 = -(1 - tb) * p.Q1 + bs * sigma * I, G34 = -(1 - tb) * p.Q2;
    const MatrixXd G17 = vi.C0.transpose() * p.P1 + vi.J0.transpose() * Y.transpose();
    const MatrixXd G18 = vi.C0.transpose() * p.P2 + vi.J0.transpose() * Y.transpose();
    const MatrixXd G37 = vi.C1.transpose() * p.P1 + vi.J1.transpose() * Y.transpose();
    const MatrixXd G19 = p.P1 * vi.B + Y * vi.K, G29 = p.P2 * vi.B + Y * vi.K;
    // Gamma44 as derived (the print has a stray (e2^2 + e4^2) factor: docs/method_lmi.md, typo T1)
    const MatrixXd G44 = -(1 - tb) * p.Q3 + bs * sigma * I;
    auto blk = [&](int r, int cc, int rows, int cols) { return MatrixXd(M.block(r, cc, rows, cols)); };
    const double tol = 1e-9;
    CHECK((blk(0, 0, n, n) - G11).norm() < tol * (1 + G11.norm()));
    CHECK((blk(0, n, n, n) - G12).norm() < tol * (1 + G12.norm()));
    CHECK((blk(n, n, n, n) - G22).norm() < tol * (1 + G22.norm()));
    CHECK((blk(0, 2 * n, n, n) - G13).norm() < tol * (1 + G13.norm()));
    CHECK((blk(0, 3 * n, n, n) - G14).norm() < tol * (1 + G14.norm()));
    CHECK((blk(n, 2 * n, n, n) - G23).norm() < tol * (1 + G23.norm()));
    CHECK((blk(2 * n, 2 * n, n, n) - G33).norm() < tol * (1 + G33.norm()));
    CHECK((blk(2 * n, 3 * n, n, n) - G34).norm() < tol * (1 + G34.norm()));
    CHECK((blk(3 * n, 3 * n, n, n) - G44).norm() < tol * (1 + G44.norm()));
    // columns of (1,2): [0 0 | G17 G18 | G19 | P1 Yj | P1 Yk]  (integral block, D~'P, P~B, P~Lj, P~Lk)
    CHECK((blk(0, 6 * n, n, n) - G17).norm() < tol * (1 + G17.norm()));
    CHECK((blk(0, 7 * n, n, n) - G18).norm() < tol * (1 + G18.norm()));
    CHECK((blk(2 * n, 6 * n, n, n) - G37).norm() < tol * (1 + G37.norm()));
    CHECK((blk(0, 8 * n, n, 1) - G19).norm() < tol * (1 + G19.norm()));
    CHECK((blk(n, 8 * n, n, 1) - G29).norm() < tol * (1 + G29.norm()));
    CHECK(blk(n, 6 * n, n, 2 * n).norm() == 0.0);  // x-hat rows of D~'P are zero
    CHECK((blk(0, 8 * n + 1, n, n) - p.P1).norm() < tol);
    CHECK((blk(0, 8 * n + 1 + n, n, 1) - Y).norm() < tol);
    CHECK((blk(n, 8 * n + 1, n, n) - p.P2).norm() < tol);
    // (2,2): -tau2^2 R, -P/2, -gamma^2/2 I, -gamma^2/alpha I (four times)
    CHECK((blk(4 * n, 4 * n, 2 * n, 2 * n) + t2 * delay_lmi_full_R(p)).norm() < tol * 100);
    CHECK((blk(6 * n, 6 * n, 2 * n, 2 * n) + 0.5 * delay_lmi_full_P(p)).norm() < tol * 100);
    CHECK(M(8 * n, 8 * n) == Approx(-p.gamma2 / 2));
    CHECK(M(8 * n + 1, 8 * n + 1) == Approx(-p.gamma2 / c.spec.alpha));
    CHECK(M.rows() == 8 * n + 1 + 2 * (n + 1));
}

TEST_CASE("delay LMI: Theta_j < 0 exactly when Lbar_j' P Lbar_j < beta_j I", "[lmi]") {
    std::mt19937 g(5);
    DelayConfig c = example_config("delay_hinf.toml");
    int agree = 0, both_signs = 0;
    for (int t = 0; t < 40; ++t) {
        c.spec.p_structure = t % 2 ? DELAY_P_ERROR : DELAY_P_PAPER;
        DelayLmiPoint p = random_point(g, 2, 1, 3);
        p.P1 = p.P2 + rand_spd(g, 2);  // P > 0 needs P1 - P2 > 0
        p.beta[0] = 0.5 + 12.0 * t / 40;
        const MatrixXd P = delay_lmi_full_P(p, c.spec.p_structure);
        const MatrixXd Lj = delay_lmi_gains(p)[0];
        MatrixXd Lbar = MatrixXd::Zero(4, 3);
        Lbar.topLeftCorner(2, 2).setIdentity();
        Lbar.bottomRightCorner(2, 1) = Lj;
        const bool direct = max_eig(Lbar.transpose() * P * Lbar - p.beta[0] * MatrixXd::Identity(3, 3)) < 0;
        const bool schur = max_eig(delay_lmi_theta(c.spec, p, 0)) < 0;
        agree += direct == schur;
        both_signs += direct;
    }
    CHECK(agree == 40);
    CHECK(both_signs > 0);
    CHECK(both_signs < 40);
}

TEST_CASE("delay LMI: Design 1 solves and every assembled block is negative definite at the solution", "[lmi]") {
    DelayConfig c = example_config("delay_hinf.toml");
    const DelayLmiResult r = delay_lmi_solve(c.spec, c.sdp);
    REQUIRE(r.sdp.status == SDP_STATUS_OPTIMAL);
    REQUIRE(r.ok());
    int blocks = 0;
    for (const auto& b : delay_lmi_blocks(c.spec, r.point)) {
        INFO(b.name);
        CHECK(max_eig(b.value) < 0);
        ++blocks;
    }
    CHECK(blocks == 27 + 3 + 3 + 3);
    CHECK(r.objective == Approx(r.point.gamma2));
    CHECK(r.objective > 0);
    // the theorem's own form (27) with L_j = P2^-1 Y_j is negative definite too
    for (int i = 0; i < 3; ++i)
        CHECK(max_eig(delay_lmi_pi1(c.spec, delay_lmi_full_P(r.point), delay_lmi_full_Q(r.point),
                                    delay_lmi_full_R(r.point), r.gains, r.point.beta, r.point.gamma2, i, (i + 1) % 3,
                                    (i + 2) % 3)) < 0);
}

TEST_CASE("delay LMI: Design 2 solves, J2 is objective (46), and (45) implies (34) (Remark 8)", "[lmi]") {
    DelayConfig c = example_config("delay_h2hinf.toml");
    const DelayLmiResult r = delay_lmi_solve(c.spec, c.sdp);
    REQUIRE(r.ok());
    for (const auto& b : delay_lmi_blocks(c.spec, r.point)) {
        INFO(b.name);
        CHECK(max_eig(b.value) < 0);
    }
    // (46) with M = diag{I, 0}, N = diag{I / sqrt(e), 0}, L = diag{tau2 I / sqrt(2), 0} (sec. 5), tau2 = 1
    const double j2 = r.point.P1.trace() + r.point.Q1.trace() / std::exp(1.0) + r.point.R1.trace() / 2.0;
    CHECK(r.objective == Approx(j2).epsilon(1e-9));
    CHECK(c.spec.gamma2 == Approx(4.16 * 4.16));
    DelayLmiSpec hinf_spec = c.spec;
    hinf_spec.design = DELAY_DESIGN_HINF;
    DelayLmiPoint p = r.point;
    p.gamma2 = c.spec.gamma2;
    for (const auto& b : delay_lmi_blocks(hinf_spec, p)) {
        INFO(b.name);
        CHECK(max_eig(b.value) < 0);
    }
}
