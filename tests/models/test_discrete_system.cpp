// Discrete-time expression systems ([system] time = "discrete"): the shared step is the map itself (no Euler),
// the truth equals f iterated by hand, the step index k, exact Jacobians, the EKF on a linear discrete system
// equals the Kalman filter's closed form, and the refusals of the continuous-time-only parts.
#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>

#include "config/run_config.hpp"
#include "filters/ekf.hpp"
#include "filters/pf.hpp"
#include "filters/ukf.hpp"
#include "helpers.hpp"
#include "hinf/config.hpp"
#include "hinf/error.hpp"
#include "models/system.hpp"
#include "sim/truth.hpp"

using namespace hinf;

namespace {

// The univariate nonstationary growth model (Kitagawa 1996; Särkkä's EKF/UKF toolbox): k in f, a nonlinear h.
const char* kUngm = R"toml([system]
kind = "expr"
time = "discrete"
states = ["x"]
disturbances = 1
measurements = 1
f = ["0.5*x + 25*x/(1 + x^2) + 8*cos(1.2*k)"]
g = [["1"]]
h = ["x^2/20"]
[filter]
x0 = [0.1]
xhat0 = [0.1]
dt = 0.5
t_final = 20
[online]
disturbance_std = 1
noise_std = 1
)toml";

// x_{k+1} = F x_k + G w_k, y_k = H x_k + v_k with n = 2, nv = 1, m = 1
const char* kLinear = R"toml([system]
kind = "expr"
time = "discrete"
states = ["a", "b"]
disturbances = 1
measurements = 1
f = ["0.9*a + 0.2*b", "-0.3*a + 0.8*b"]
g = [["0.5"], ["1"]]
h = ["a + 0.5*b"]
[filter]
x0 = [1, -1]
xhat0 = [0, 0]
dt = 0.1
t_final = 30
[online]
disturbance_std = 0.7
noise_std = 0.4
)toml";

RunConfig config_of(const std::string& text, const std::vector<std::string>& sets = {}) {
    ConfigDoc doc = ConfigDoc::from_text(text, "test.toml");
    for (const auto& s : sets) doc.set(s);
    return load_run_config(std::move(doc));
}

double ungm_f(double x, std::int64_t k) { return 0.5 * x + 25 * x / (1 + x * x) + 8 * std::cos(1.2 * double(k)); }

}  // namespace

TEST_CASE("discrete system: the shared step is the map, k is the step index, Jacobians exact", "[models][discrete]") {
    RunConfig cfg = config_of(kUngm);
    const System& sys = *cfg.system;
    REQUIRE(sys.discrete_time());
    CHECK(std::string(system_time_name(sys)) == "discrete");
    for (std::int64_t k : {0, 1, 7, 39}) {
        const double x = 1.3 - 0.2 * double(k), v = 0.25, t = cfg.time_of(k);
        double next = 0;
        system_advance(sys, &next, &x, &v, t, cfg.dt);
        CHECK(next == Approx(ungm_f(x, k) + v).epsilon(1e-13));
        system_advance(sys, &next, &x, nullptr, t, cfg.dt);
        CHECK(next == Approx(ungm_f(x, k)).epsilon(1e-13));
        double F = 0, G = 0, H = 0;
        system_advance_jacobian(sys, &F, &G, &x, t, cfg.dt);
        const double h = 1e-6;
        CHECK(F == Approx((ungm_f(x + h, k) - ungm_f(x - h, k)) / (2 * h)).epsilon(1e-7));
        CHECK(G == 1.0);
        sys.measurement_jacobian(&H, &x, t);
        CHECK(H == Approx(x / 10).epsilon(1e-13));
    }
    // a continuous system keeps forward Euler
    RunConfig cont = config_of(kUngm, {"system.time=\"continuous\"", "system.f=[\"-x\"]"});
    REQUIRE(!cont.system->discrete_time());
    const double x = 2.0;
    double next = 0;
    system_advance(*cont.system, &next, &x, nullptr, 0.0, cont.dt);
    CHECK(next == 2.0 - cont.dt * 2.0);
}

TEST_CASE("discrete system: the truth equals f iterated by hand with the drawn signals", "[models][discrete][truth]") {
    RunConfig cfg = config_of(kUngm);
    const std::int64_t K = cfg.steps_until();
    REQUIRE(K == 40);
    TruthRun tr = truth_simulate(cfg, scenario_named("nominal"), 3, K);
    double x = 0.1;
    for (std::int64_t k = 0; k < K; ++k) {
        INFO("step " << k);
        CHECK(tr.x[k] == Approx(x).epsilon(1e-12).margin(1e-12));
        CHECK(tr.y[k] == Approx(x * x / 20 + tr.n[k]).epsilon(1e-12).margin(1e-12));
        CHECK(tr.energy[k] == Approx(tr.v[k] * tr.v[k] + tr.n[k] * tr.n[k]));
        x = ungm_f(x, k) + tr.v[k];  // x_{k+1} = f(x_k, k) + w_k: no dt anywhere
    }
    // the noise is per step: its spread does not depend on dt
    RunConfig fine = config_of(kUngm, {"filter.dt=0.01", "filter.t_final=0.4"});
    TruthRun tf = truth_simulate(fine, scenario_named("nominal"), 3, 40);
    for (std::int64_t k = 0; k < 40; ++k) CHECK(tf.v[k] == tr.v[k]);
}

TEST_CASE("discrete system: EKF and UKF equal the Kalman filter's closed form on a linear system", "[models][discrete][kalman]") {
    RunConfig cfg = config_of(kLinear);
    const std::int64_t K = cfg.steps_until();
    TruthRun tr = truth_simulate(cfg, scenario_named("nominal"), 0, K);
    FilterModel model = filter_model(cfg);
    FilterStart start;
    start.xhat0 = cfg.xhat0;
    start.P0 = {2.0, 0.0, 0.0, 2.0};
    auto ekf = make_ekf(model), ukf = make_ukf(model);
    ekf->reset(start);
    ukf->reset(start);
    // the textbook Kalman filter (Kalman 1960) for x_{k+1} = F x + G w: Q = sv^2 G G', R = sn^2
    Eigen::Matrix2d F, P = 2.0 * Eigen::Matrix2d::Identity();
    F << 0.9, 0.2, -0.3, 0.8;
    Eigen::Vector2d G(0.5, 1.0), x(0, 0);
    Eigen::RowVector2d H(1.0, 0.5);
    const double q = 0.7 * 0.7, r = 0.4 * 0.4;
    double worst = 0;
    for (std::int64_t k = 0; k < K; ++k) {
        FilterInput in{&tr.y[k], cfg.time_of(k), k, nullptr};
        REQUIRE(ekf->step(in) == FILTER_OK);
        REQUIRE(ukf->step(in) == FILTER_OK);
        const double S = (H * P * H.transpose())(0, 0) + r;
        const Eigen::Vector2d Kg = P * H.transpose() / S;
        x = x + Kg * (tr.y[k] - H * x);
        P = P - Kg * S * Kg.transpose();
        x = F * x;
        P = F * P * F.transpose() + q * G * G.transpose();
        for (int i = 0; i < 2; ++i) {
            worst = std::max(worst, std::fabs(ekf->estimate()[i] - x[i]) / std::max(std::fabs(x[i]), 1e-3));
            worst = std::max(worst, std::fabs(ukf->estimate()[i] - x[i]) / std::max(std::fabs(x[i]), 1e-3));
            for (int j = 0; j < 2; ++j)
                worst = std::max(worst, std::fabs(ekf->covariance()[i * 2 + j] - P(i, j)) / std::max(std::fabs(P(i, j)), 1e-6));
        }
    }
    INFO("worst relative difference " << worst);
    CHECK(worst < 1e-10);
}

TEST_CASE("discrete system: bad keys and continuous-time-only parts give one line", "[models][discrete][errors]") {
    auto message = [](const std::string& text, const std::vector<std::string>& sets) {
        try {
            config_of(text, sets);
        } catch (const Error& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    CHECK(message(kUngm, {"system.time=\"discret\""}).find("is not one of") != std::string::npos);
    CHECK(message(kUngm, {"system.states=[\"k\"]"}).find("the step index of a discrete system") != std::string::npos);
    // k is only a symbol of discrete systems
    CHECK(message(kUngm, {"system.time=\"continuous\""}).find("unknown symbol 'k'") != std::string::npos);
    RunConfig cfg = config_of(kUngm);
    std::string why;
    try {
        make_particle_filter(filter_model(cfg), 10, 0.5, 0.0);
    } catch (const Error& e) {
        why = e.what();
    }
    CHECK(why.empty());  // the PF runs discrete systems
}
