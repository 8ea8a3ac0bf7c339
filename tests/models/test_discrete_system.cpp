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
#include "eval/engine.hpp"

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
const char* kLinearDiscrete = R"toml([system]
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
    RunConfig cfg = config_of(kLinearDiscrete);
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
    double worst = 0, worst_filtered = 0;
    for (std::int64_t k = 0; k < K; ++k) {
        FilterInput in{&tr.y[k], cfg.time_of(k), k, nullptr};
        REQUIRE(ekf->step(in) == FILTER_OK);
        REQUIRE(ukf->step(in) == FILTER_OK);
        const double S = (H * P * H.transpose())(0, 0) + r;
        const Eigen::Vector2d Kg = P * H.transpose() / S;
        x = x + Kg * (tr.y[k] - H * x);
        P = P - Kg * S * Kg.transpose();
        // the filtered estimate x^_{k|k}: after the measurement at k, before the prediction
        for (int i = 0; i < 2; ++i)
            for (const double* xf : {ekf->filtered(), ukf->filtered()})
                worst_filtered = std::max(worst_filtered, std::fabs(xf[i] - x[i]) / std::max(std::fabs(x[i]), 1e-3));
        x = F * x;
        P = F * P * F.transpose() + q * G * G.transpose();
        for (int i = 0; i < 2; ++i) {
            worst = std::max(worst, std::fabs(ekf->estimate()[i] - x[i]) / std::max(std::fabs(x[i]), 1e-3));
            worst = std::max(worst, std::fabs(ukf->estimate()[i] - x[i]) / std::max(std::fabs(x[i]), 1e-3));
            for (int j = 0; j < 2; ++j)
                worst = std::max(worst, std::fabs(ekf->covariance()[i * 2 + j] - P(i, j)) / std::max(std::fabs(P(i, j)), 1e-6));
        }
    }
    INFO("worst relative difference " << worst << ", filtered " << worst_filtered);
    CHECK(worst < 1e-10);
    CHECK(worst_filtered < 1e-10);
}

TEST_CASE("discrete system: a known initial state (P0 = 0) and the PF's stratified resampling", "[models][discrete][pf]") {
    RunConfig cfg = config_of(kLinearDiscrete);
    const std::int64_t K = 60;
    TruthRun tr = truth_simulate(cfg, scenario_named("nominal"), 1, K);
    FilterStart start;
    start.xhat0 = cfg.x0;  // the true start, known exactly
    start.P0 = {0.0, 0.0, 0.0, 0.0};
    start.seed = 3;
    auto ekf = make_ekf(filter_model(cfg)), ukf = make_ukf(filter_model(cfg));
    auto pf = make_particle_filter(filter_model(cfg), 20000, 1.0, 0.0, true);
    for (auto* f : {ekf.get(), ukf.get(), pf.get()}) f->reset(start);
    // every particle starts at x0; the UKF's sigma points collapse onto it (a PSD square root of P0 = 0)
    CHECK(pf->estimate()[0] == Approx(cfg.x0[0]).epsilon(1e-12));
    CHECK(pf->estimate()[1] == Approx(cfg.x0[1]).epsilon(1e-12));
    double worst_ukf = 0, worst_pf = 0;
    for (std::int64_t k = 0; k < K; ++k) {
        FilterInput in{&tr.y[k], cfg.time_of(k), k, nullptr};
        REQUIRE(ekf->step(in) == FILTER_OK);
        REQUIRE(ukf->step(in) == FILTER_OK);
        REQUIRE(pf->step(in) == FILTER_OK);
        for (int i = 0; i < 2; ++i) {
            worst_ukf = std::max(worst_ukf, std::fabs(ukf->filtered()[i] - ekf->filtered()[i]));
            worst_pf = std::max(worst_pf, std::fabs(pf->filtered()[i] - ekf->filtered()[i]));
        }
    }
    INFO("UKF " << worst_ukf << ", stratified PF (20000 particles, resampled every step) " << worst_pf);
    CHECK(worst_ukf < 1e-9);  // a linear system: the UKF is the Kalman filter
    CHECK(worst_pf < 0.05);   // Monte Carlo error of the posterior mean (its std is about 0.5)
    // stratified and systematic resampling differ in their draws, not in what they estimate
    auto sys_pf = make_particle_filter(filter_model(cfg), 20000, 1.0, 0.0, false);
    sys_pf->reset(start);
    bool differ = false;
    for (std::int64_t k = 0; k < 5; ++k) {
        FilterInput in{&tr.y[k], cfg.time_of(k), k, nullptr};
        REQUIRE(sys_pf->step(in) == FILTER_OK);
    }
    pf->reset(start);
    for (std::int64_t k = 0; k < 5; ++k) {
        FilterInput in{&tr.y[k], cfg.time_of(k), k, nullptr};
        REQUIRE(pf->step(in) == FILTER_OK);
    }
    differ = pf->filtered()[0] != sys_pf->filtered()[0];
    CHECK(differ);
}

TEST_CASE("discrete system: [baseline] changes what the filters are told, not the truth", "[models][discrete][baseline]") {
    const std::string with_param = std::string(kLinearDiscrete).replace(std::string(kLinearDiscrete).find("f = ["), 5,
                                                                "parameters = { c = 0.2 }\nf = [") ;
    std::string text = with_param;
    text.replace(text.find("0.9*a + 0.2*b"), 13, "0.9*a + c*b");
    RunConfig same = config_of(text);
    CHECK(same.told_system == same.system);
    CHECK(same.told_noise_std == same.noise_std);
    RunConfig cfg = config_of(text, {"baseline.parameters.c=0.5", "baseline.noise_std=2", "baseline.initial_std=[0, 3]"});
    REQUIRE(cfg.told_system != cfg.system);
    const double x[2] = {1.0, 1.0};
    double truth[2], told[2];
    system_advance(*cfg.system, truth, x, nullptr, 0.0, cfg.dt);
    system_advance(*cfg.told_system, told, x, nullptr, 0.0, cfg.dt);
    CHECK(truth[0] == Approx(1.1));
    CHECK(told[0] == Approx(1.4));
    FilterModel m = scenario_told_model(cfg, scenario_named("nominal"));
    CHECK(m.system == cfg.told_system.get());
    CHECK(m.noise_std == 2.0);
    CHECK(m.disturbance_std == cfg.disturbance_std);
    CHECK(engine_filter_start(cfg, 0).P0 == std::vector<double>{0.0, 0.0, 0.0, 9.0});
    auto message = [&](const std::vector<std::string>& sets) {
        try {
            config_of(text, sets);
        } catch (const Error& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    CHECK(message({"baseline.parameters.zeta=1"}).find("'zeta' is not a [system] parameter") != std::string::npos);
    CHECK(message({"baseline.noise_std=0"}).find("must be > 0") != std::string::npos);
    CHECK(message({"baseline.initial_std=[1, -1]"}).find("entries must be >= 0") != std::string::npos);
    CHECK(message({"baseline.ukf_kappa=-2"}).find("use kappa > -n") != std::string::npos);
    CHECK(message({"baseline.pf_resampling=\"multinomial\""}).find("is not one of: systematic, stratified") !=
          std::string::npos);
    CHECK(message({"baseline.pf_ess_fraction=2"}).find("out of range") != std::string::npos);
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
