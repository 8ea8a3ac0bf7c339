// [online] / [baseline] noise_std and disturbance_std as lists, one per output or input (models/weighted_system.hpp,
// docs/method.md section 16.13): the model sees the system in units of its noise; the user's records, the library's
// y and v and the written measurements stay in the user's units. Checked against a textbook Kalman filter with
// R = diag(sn_j^2) written here, the truth's noise per output, and the closed-form rho* of a two-sensor random walk.
#include <catch2/catch.hpp>
#include <cmath>

#include <Eigen/Dense>

#include "config/game_level.hpp"
#include "config/run_config.hpp"
#include "helpers.hpp"
#include "hinf/config.hpp"
#include "hinf/hinf.hpp"
#include "models/weighted_system.hpp"
#include "sim/truth.hpp"

using namespace hinf;

namespace {
RunConfig load(const std::string& text) { return load_run_config(ConfigDoc::from_text(text, "t.toml")); }

// x+ = F x + G v, y = H x + n (discrete, linear): 2 states, 2 inputs, 2 outputs
const char* kLinear =
    "[system]\nkind = \"expr\"\ntime = \"discrete\"\nstates = [\"a\", \"b\"]\ndisturbances = 2\nmeasurements = 2\n"
    "f = [\"a + 0.1*b\", \"0.95*b\"]\ng = [[\"0.5\", \"0\"], [\"1\", \"0.2\"]]\nh = [\"a + 0.5*b\", \"b\"]\n"
    "[filter]\nrho = 5\nQ = [1.0, 1.0]\nx0 = [1.0, -1.0]\nxhat0 = [0.0, 0.0]\ndt = 1\nt_final = 400\n"
    "[online]\ndisturbance_std = [0.3, 1.5]\nnoise_std = [0.1, 0.4]\n";

// x+ = x + v, y_j = x + n_j: one state, one disturbance, two sensors of the given noise
std::string random_walk(const std::string& noise) {
    return "[system]\nkind = \"expr\"\ntime = \"discrete\"\nstates = [\"x\"]\ndisturbances = 1\nmeasurements = 2\n"
           "f = [\"x\"]\ng = [[\"1\"]]\nh = [\"x\", \"x\"]\n[filter]\nQ = [1.0]\nx0 = [1.0]\nxhat0 = [0.0]\ndt = 1\n"
           "t_final = 200\n[online]\ndisturbance_std = 0.1\nnoise_std = " + noise + "\n";
}
}  // namespace

TEST_CASE("std lists: the model measures every output and input in units of its own std", "[config][channels]") {
    const RunConfig c = load(kLinear);
    CHECK(c.noise_std == 1.0);
    CHECK(c.disturbance_std == 1.0);
    CHECK(c.output_weight == std::vector<double>{1.0 / 0.1, 1.0 / 0.4});
    CHECK(c.disturbance_scale == std::vector<double>{0.3, 1.5});
    const auto* w = dynamic_cast<const WeightedSystem*>(c.system.get());
    REQUIRE(w != nullptr);
    const double x[2] = {0.7, -0.3};
    double y[2], raw[2], H[4], Hr[4], B[4], Br[4];
    c.system->measurement(y, x, 0, 1);
    w->inner().measurement(raw, x, 0, 1);
    c.system->measurement_jacobian(H, x, 0);
    w->inner().measurement_jacobian(Hr, x, 0);
    c.system->disturbance_gain(B, x, 0, 1);
    w->inner().disturbance_gain(Br, x, 0, 1);
    for (int j = 0; j < 2; ++j) {
        CHECK(y[j] == raw[j] * c.output_weight[j]);
        for (int i = 0; i < 2; ++i) CHECK(H[j * 2 + i] == Hr[j * 2 + i] * c.output_weight[j]);
        for (int i = 0; i < 2; ++i) CHECK(B[i * 2 + j] == Br[i * 2 + j] * c.disturbance_scale[j]);
    }
    // the user's units and back
    double u[2] = {raw[0], raw[1]};
    outputs_to_model(c, u, 1);
    CHECK(u[0] == y[0]);
    CHECK(u[1] == y[1]);
    outputs_to_user(c, u, 1);
    CHECK(u[0] == Approx(raw[0]).epsilon(1e-15));
    // a list's one-number partner is weighted too; two numbers keep the user's units
    const RunConfig partner = load(random_walk("[0.1, 0.4]"));
    CHECK(partner.disturbance_scale == std::vector<double>{0.1});
    CHECK(partner.disturbance_std == 1.0);
    const RunConfig plain = load(random_walk("0.2"));
    CHECK(plain.output_weight.empty());
    CHECK(plain.disturbance_scale.empty());
    CHECK(dynamic_cast<const WeightedSystem*>(plain.system.get()) == nullptr);
    CHECK(plain.noise_std == 0.2);
}

TEST_CASE("std lists: the truth's noise has each output's std in the user's units", "[config][channels]") {
    const RunConfig c = load(kLinear);
    const std::int64_t K = c.steps_until();
    const auto* w = dynamic_cast<const WeightedSystem*>(c.system.get());
    REQUIRE(w != nullptr);
    double sum2[2] = {0, 0};
    std::int64_t count = 0;
    for (std::uint64_t run = 0; run < 10; ++run) {
        TruthRun tr = truth_simulate(c, scenario_named("nominal"), run, K);
        outputs_to_user(c, tr.y.data(), K);
        for (std::int64_t k = 0; k < K; ++k) {
            double raw[2];
            w->inner().measurement(raw, tr.x.data() + k * 2, c.time_of(k), 1);
            for (int j = 0; j < 2; ++j) sum2[j] += (tr.y[k * 2 + j] - raw[j]) * (tr.y[k * 2 + j] - raw[j]);
            ++count;
        }
    }
    // 4000 draws: the sample std is within 5 % (about 4.5 standard errors)
    CHECK(std::sqrt(sum2[0] / double(count)) == Approx(0.1).epsilon(0.05));
    CHECK(std::sqrt(sum2[1] / double(count)) == Approx(0.4).epsilon(0.05));
}

TEST_CASE("std lists: EKF, UKF (and PF) on a record in the user's units are the Kalman filter with R = diag(sn_j^2)",
          "[config][channels][api]") {
    // the told noise differs from the truth's per output ([baseline] list), the process noise per input
    const std::string text = std::string(kLinear) + "[baseline]\nnoise_std = [0.2, 0.3]\ninitial_std = [1.0, 1.0]\n";
    const hinf::Config cfg = hinf::Config::from_text(text, "t.toml");
    const int K = 60;
    std::vector<double> t, y;
    std::vector<double> x = cfg.initial_state();
    for (int k = 0; k < K; ++k) {
        const std::vector<double> c = cfg.measure(x, double(k));
        t.push_back(double(k));
        y.push_back(c[0] + 0.1 * std::sin(0.7 * k));  // deterministic "noise" in each output's units
        y.push_back(c[1] + 0.4 * std::cos(1.3 * k));
        x = cfg.advance(x, {0.3 * std::sin(0.2 * k), 1.5 * std::cos(0.5 * k)}, double(k), 1.0);
    }
    // the textbook filter in the user's units: R = diag(0.2^2, 0.3^2), Q = G diag(0.3^2, 1.5^2) G'
    Eigen::Matrix2d F, G, H, Qv;
    F << 1, 0.1, 0, 0.95;
    G << 0.5, 0, 1, 0.2;
    H << 1, 0.5, 0, 1;
    Qv = Eigen::Vector2d(0.09, 2.25).asDiagonal();
    auto kalman = [&](const Eigen::Matrix2d& R) {
        Eigen::Matrix2d P = Eigen::Matrix2d::Identity();
        Eigen::Vector2d xh(0, 0);
        std::vector<double> out;
        for (int k = 0; k < K; ++k) {
            out.push_back(xh[0]);
            out.push_back(xh[1]);
            const Eigen::Matrix2d S = H * P * H.transpose() + R;
            const Eigen::Matrix2d Kg = P * H.transpose() * S.inverse();
            xh += Kg * (Eigen::Vector2d(y[2 * k], y[2 * k + 1]) - H * xh);
            const Eigen::Matrix2d IKH = Eigen::Matrix2d::Identity() - Kg * H;
            P = IKH * P * IKH.transpose() + Kg * R * Kg.transpose();
            xh = F * xh;
            P = F * P * F.transpose() + G * Qv * G.transpose();
        }
        return out;
    };
    const Eigen::Matrix2d R = Eigen::Vector2d(0.04, 0.09).asDiagonal();
    const std::vector<double> want = kalman(R);
    // Config::advance takes v and measure gives y in the user's units: x+ = F x + G v, y = H x
    const std::vector<double> x1 = cfg.advance({1.0, -1.0}, {0.3, 1.5}, 0.0, 1.0);
    const Eigen::Vector2d x1_want = F * Eigen::Vector2d(1.0, -1.0) + G * Eigen::Vector2d(0.3, 1.5);
    CHECK(x1[0] == Approx(x1_want[0]).epsilon(1e-14));
    CHECK(x1[1] == Approx(x1_want[1]).epsilon(1e-14));
    const std::vector<double> y1 = cfg.measure(x1, 1.0);
    const Eigen::Vector2d y1_want = H * x1_want;
    CHECK(y1[0] == Approx(y1_want[0]).epsilon(1e-14));
    CHECK(y1[1] == Approx(y1_want[1]).epsilon(1e-14));
    for (const char* name : {"ekf", "ukf"}) {
        INFO(name);
        hinf::Filter f = hinf::Filter::create(cfg, name);
        for (int k = 0; k < K; ++k) {
            const std::vector<double> xe = f.estimate();
            CHECK(xe[0] == Approx(want[2 * k]).margin(1e-9));
            CHECK(xe[1] == Approx(want[2 * k + 1]).margin(1e-9));
            REQUIRE(f.step(&y[2 * k], t[k]));
        }
        // the whole record at once (hinf filter's path), innovations in the user's units
        const hinf::FilterTrace tr = f.run(t, y);
        for (int k = 0; k < K; ++k) CHECK(tr.xhat[2 * k] == Approx(want[2 * k]).margin(1e-9));
        const std::vector<double> c0 = cfg.measure({want[0], want[1]}, 0.0);
        CHECK(tr.innovation[0] == Approx(y[0] - c0[0]).margin(1e-12));
        CHECK(tr.innovation[1] == Approx(y[1] - c0[1]).margin(1e-12));
    }
    // the particle filter's likelihood: nearer the Kalman filter with this R than that with one std (0.3) for both
    const std::vector<double> one_std = kalman(Eigen::Vector2d(0.09, 0.09).asDiagonal());
    hinf::FilterOptions o;
    o.particles = 4000;
    const hinf::FilterTrace pf = hinf::Filter::create(cfg, "pf", o).run(t, y);
    double to_right = 0, to_wrong = 0, apart = 0;
    for (int k = 10; k < K; ++k)
        for (int i = 0; i < 2; ++i) {
            to_right = std::max(to_right, std::fabs(pf.xhat[2 * k + i] - want[2 * k + i]));
            to_wrong = std::max(to_wrong, std::fabs(pf.xhat[2 * k + i] - one_std[2 * k + i]));
            apart = std::max(apart, std::fabs(one_std[2 * k + i] - want[2 * k + i]));
        }
    INFO("PF to the right KF " << to_right << ", to the one-std KF " << to_wrong << ", the KFs apart " << apart);
    CHECK(to_right < 0.4 * apart);
    CHECK(to_right < to_wrong);
}

TEST_CASE("std lists: rho* of a two-sensor random walk is b^2 + 1 / sum_j sn_j^-2", "[config][channels][rho]") {
    // in the model's units x+ = x + b v~, y~_j = x / sn_j + n~_j with unit stds, b = sv = 0.1: the a-priori
    // P+ = 1 / (1/P + h - 1/rho) + b^2, h = sum_j sn_j^-2, meets the existence bound P = rho at rho* = b^2 + 1/h
    // (one sensor in the user's units, b = h = 1: rho* = 2, test_game_level.cpp)
    const RunConfig c = load(random_walk("[0.1, 0.4]"));
    const double h = 1.0 / (0.1 * 0.1) + 1.0 / (0.4 * 0.4), want = 0.01 + 1.0 / h;
    REQUIRE(c.rho_auto);
    CHECK(c.rho_bound == Approx(want).epsilon(1e-2));
    CHECK(c.rho == Approx(kAutoRhoFactor * c.rho_bound).epsilon(1e-12));
}

TEST_CASE("std lists: bad lists are one line", "[config][channels]") {
    auto fails = [](const std::string& text, const std::string& fragment) {
        return hinf::test::one_line_error([&] { load(text); }, fragment);
    };
    CHECK(fails(random_walk("[0.1, 0.0]"), "entries must be in (0, 1e12]"));
    CHECK(fails(random_walk("[0.1, 0.2, 0.3]"), "has 3 entries, expected 2"));
    CHECK(fails(random_walk("[0.1, -0.2]"), "entries must be in (0, 1e12]"));
    CHECK(fails(random_walk("[0.1, 0.2]") + "[baseline]\nnoise_std = [0.1, 0.0]\n", "must be > 0"));
    // a list's partner of 0 (no process noise) stays in its own units
    const RunConfig still = load(random_walk("[0.1, 0.2]").replace(random_walk("[0.1, 0.2]").find("disturbance_std = 0.1"),
                                                                    21, "disturbance_std = 0.0"));
    CHECK(still.disturbance_scale.empty());
    CHECK(still.disturbance_std == 0.0);
}
