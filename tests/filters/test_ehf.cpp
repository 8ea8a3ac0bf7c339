// The extended H-infinity filter (filters/ehf.hpp) on a linear system, where it is the a priori H-infinity filter
// of the Euler-sampled game: its covariance follows the game's Riccati recursion written here in information form
// (independently of the filter's square-root form), and the exact worst-case gain of its error system over the
// horizon -- a time-varying linear map from (v, n) to x~, its largest singular value by power iteration -- is
// below rho, as the game promises; the worst-case search reaches it and never exceeds it. Below the level the
// system allows, the filter counts the steps where it drops the -Q / rho term, and hinf compare says so in one line.
#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>

#include "eval/worst.hpp"
#include "filters/ehf.hpp"
#include "filters/ekf.hpp"
#include "helpers.hpp"
#include "hinf/error.hpp"

using namespace hinf;

namespace {

using Mat = Eigen::MatrixXd;

RunConfig oscillator(double rho) {
    // p' = w, w' = -a p - b w + v, y = p + n: a damped oscillator (1 rad/s, damping ratio 0.2), the velocity
    // unmeasured; its game from P0 = I over 5 s has a filter of level 2, none of level 1 (the Riccati recursion
    // loses definiteness at step 123)
    const double w0 = 1.0, zeta = 0.2;
    return load_run_config(ConfigDoc::from_text(
        "[system]\nkind = \"expr\"\nstates = [\"p\", \"w\"]\nunits = [\"m\", \"m/s\"]\ndisturbances = 1\n"
        "measurements = 1\nparameters = { a = " + std::to_string(w0 * w0) + ", b = " + std::to_string(2 * zeta * w0) +
            " }\nf = [\"w\", \"-a*p - b*w\"]\ng = [[\"0\"], [\"1\"]]\nh = [\"p\"]\n[filter]\nQ = [1.0, 1.0]\n"
            "x0 = [0.0, 0.0]\nxhat0 = [0.0, 0.0]\ndt = 0.01\nt_final = 5.0\nrho = " + std::to_string(rho) +
            "\n[online]\ndisturbance_std = 1.0\nnoise_std = 1.0\n",
        "oscillator.toml"));
}

// max over w of sum_k e_k'Q e_k / sum_k |w_k|^2 for e_{k+1} = Phi_k e_k + Gam_k w_k, e_0 = 0, scored e_0 ... e_{K-1}:
// power iteration on G'QG (G the map w -> e), the adjoint run backwards. Two states, two inputs (v, n): fixed-size.
using M2 = Eigen::Matrix2d;
using V2 = Eigen::Vector2d;
double exact_ltv_gain(const std::vector<M2>& Phi, const std::vector<M2>& Gam, const M2& Q, int iterations) {
    const std::size_t K = Phi.size();
    std::vector<V2> w(K, V2::Ones()), e(K);
    for (std::size_t k = 0; k < K; ++k) w[k][0] += 0.001 * double(k % 7);  // not orthogonal to the top one
    double lambda = 0;
    for (int it = 0; it < iterations; ++it) {
        V2 x = V2::Zero();
        for (std::size_t k = 0; k < K; ++k) {
            e[k] = x;
            x = Phi[k] * x + Gam[k] * w[k];
        }
        V2 g = V2::Zero();
        double ww = 0, eqe = 0;
        for (std::size_t k = K; k-- > 0;) {
            ww += w[k].squaredNorm();
            eqe += e[k].dot(Q * e[k]);
            w[k] = Gam[k].transpose() * g;  // g = sum_{j > k} (Phi_{j-1} ... Phi_{k+1})' Q e_j
            g = Q * e[k] + Phi[k].transpose() * g;
        }
        lambda = eqe / ww;
        double norm = 0;
        for (const V2& wk : w) norm += wk.squaredNorm();
        for (V2& wk : w) wk /= std::sqrt(norm);
    }
    return lambda;
}

}  // namespace

TEST_CASE("extended H-infinity filter on a linear system: the game's recursion and its bound", "[filters][ehf]") {
    const double rho = 2.0;
    RunConfig cfg = oscillator(rho);
    const double dt = cfg.dt, a = 1.0, b = 0.4;
    Mat F(2, 2), G(2, 1), H(1, 2), Q = Mat::Identity(2, 2);
    F << 1, dt, -dt * a, 1 - dt * b;
    G << 0, dt;
    H << 1, 0;
    std::unique_ptr<OnlineFilter> f = make_ehf(filter_model(cfg), cfg.Q, cfg.rho);
    FilterStart start;
    start.xhat0 = {0.0, 0.0};
    start.P0 = {1.0, 0.0, 0.0, 1.0};
    f->reset(start);
    const std::int64_t K = cfg.steps_until();
    Mat P = Mat::Identity(2, 2);
    std::vector<M2> Phi, Gam;
    double worst_rel = 0;
    for (std::int64_t k = 0; k < K; ++k) {
        const double y = std::sin(0.37 * double(k));  // the covariance does not depend on y here
        FilterInput in;
        in.y = &y;
        in.t = dt * double(k);
        in.step = k;
        REQUIRE(f->step(in) == FILTER_OK);
        // information form: P+ = (P^-1 + dt (H'H - Q / rho))^-1, P_{k+1} = F P+ F' + G G' / dt
        const Mat Pu = (P.inverse() + dt * (H.transpose() * H - Q / rho)).inverse();
        REQUIRE(Pu.llt().info() == Eigen::Success);
        P = F * Pu * F.transpose() + G * G.transpose() / dt;
        const Eigen::Map<const Eigen::Matrix2d> Pf(f->covariance());
        worst_rel = std::max(worst_rel, (Pf - P).cwiseAbs().maxCoeff() / P.cwiseAbs().maxCoeff());
        // the error system: x~u = (I - dt P+ H'H) x~ - dt P+ H' n, x~_{k+1} = F x~u + G v
        Phi.push_back(F * (Mat::Identity(2, 2) - dt * Pu * H.transpose() * H));
        M2 gk;
        gk << G, -dt * F * Pu * H.transpose();
        Gam.push_back(gk);
    }
    CHECK(ehf_level_steps_held(*f) == 0);
    INFO("largest relative difference of the covariances " << worst_rel);
    CHECK(worst_rel < 1e-10);
    const double exact = exact_ltv_gain(Phi, Gam, Q, 300);
    CHECK(std::abs(exact - exact_ltv_gain(Phi, Gam, Q, 200)) < 1e-6 * exact);  // converged
    INFO("exact worst-case gain over the horizon " << exact << " at rho = " << rho);
    CHECK(exact <= rho);
    CHECK(exact >= 0.5 * rho);  // the level binds: the bound is not far above what the filter does
    // the search runs the filter itself (P0 from the config: the initial error is zero, so P0 = 0)
    WorstOptions opt;
    opt.random_starts = 2;
    opt.scenario_starts = {"nominal"};
    opt.evals = 150;
    opt.quiet = true;
    opt.cross_starts = false;
    std::unique_ptr<OnlineFilter> g = make_ehf(filter_model(cfg), cfg.Q, cfg.rho);
    WorstResult r = worst_search(cfg, {g.get()}, {}, opt);
    INFO("found by the search " << r.filters[0].worst.ratio);
    CHECK(r.filters[0].worst.ratio <= rho);
    CHECK(r.filters[0].worst.ratio >= 0.2 * rho);
}

TEST_CASE("extended H-infinity filter at a level that does not bind is the EKF of a system in units of its noise "
          "from dt P0", "[filters][ehf]") {
    // noise_std = disturbance_std = 1: the game's weights are the statistics over dt, so at rho -> infinity the
    // filter is the EKF with every covariance over dt: started from P0, it is the EKF started from dt P0 (ehf.hpp)
    RunConfig cfg = oscillator(1e12);
    std::unique_ptr<OnlineFilter> h = make_ehf(filter_model(cfg), cfg.Q, cfg.rho), e = make_ekf(filter_model(cfg));
    FilterStart start;
    start.xhat0 = {0.5, -0.3};
    start.P0 = {0.25, 0.0, 0.0, 0.09};
    h->reset(start);
    for (double& p : start.P0) p *= cfg.dt;
    e->reset(start);
    double worst = 0;
    for (std::int64_t k = 0; k < 300; ++k) {
        const double y = std::sin(0.37 * double(k)) + 0.2;
        FilterInput in;
        in.y = &y;
        in.t = cfg.dt * double(k);
        in.step = k;
        REQUIRE(h->step(in) == FILTER_OK);
        REQUIRE(e->step(in) == FILTER_OK);
        for (int i = 0; i < 2; ++i) {
            worst = std::max(worst, std::abs(h->estimate()[i] - e->estimate()[i]));
            worst = std::max(worst, std::abs(h->filtered()[i] - e->filtered()[i]));
        }
    }
    INFO("largest difference of the estimates " << worst);
    CHECK(worst < 1e-9);
    CHECK(ehf_level_steps_held(*h) == 0);
}

TEST_CASE("extended H-infinity filter below the system's level: Kalman steps counted and a clear refusal",
          "[filters][ehf]") {
    RunConfig cfg = oscillator(0.5);
    std::unique_ptr<OnlineFilter> f = make_ehf(filter_model(cfg), cfg.Q, cfg.rho);
    FilterStart start;
    start.xhat0 = {0.5, 0.0};
    start.P0 = {1.0, 0.0, 0.0, 1.0};
    f->reset(start);
    for (std::int64_t k = 0; k < 200; ++k) {
        const double y = 0.0;
        FilterInput in;
        in.y = &y;
        in.t = cfg.dt * double(k);
        in.step = k;
        REQUIRE(f->step(in) == FILTER_OK);
    }
    CHECK(ehf_level_steps_held(*f) > 0);
    CHECK(std::isfinite(f->estimate()[0]));
    CHECK(std::abs(f->estimate()[0]) < 0.5);  // the Kalman steps still pull the estimate towards y = 0
    CHECK_THROWS_AS(make_ehf(filter_model(cfg), cfg.Q, 0.0), Error);
    CHECK_THROWS_AS(make_ehf(filter_model(cfg), {1.0}, 1.0), Error);
}

TEST_CASE("hinf compare --filters ehf says where its level failed and is silent where it holds", "[filters][ehf][cli]") {
    hinf::test::TempDir d("cli-ehf");
    const std::string vdp = std::string(HINF_SOURCE_DIR) + "/runs/vanderpol.toml";
    const std::string note = "ehf: no filter of level rho = 0.5 along the estimate";
    auto low = hinf::test::run_hinf("compare " + vdp + " --set filter.rho=0.5 --filters ehf --runs 2 --until 3 --quiet "
                                    "--out " + (d / "low"));
    INFO(low.output);
    REQUIRE(low.status == 0);
    CHECK(low.output.find(note) != std::string::npos);
    auto high = hinf::test::run_hinf("compare " + vdp + " --set filter.rho=5 --filters ehf --runs 2 --until 3 --quiet "
                                     "--out " + (d / "high"));
    INFO(high.output);
    REQUIRE(high.status == 0);
    CHECK(high.output.find("ehf: no filter of level") == std::string::npos);
}
