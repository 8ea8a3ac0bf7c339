// [online] / [baseline] noise_std and disturbance_std as lists, one per output or input, and noise_cov /
// disturbance_cov, full covariances (models/weighted_system.hpp, docs/method.md section 16.13): the model sees the
// system in units of its noise (whitened); the user's records, the library's y and v and the written measurements
// stay in the user's units. Checked against a textbook Kalman filter with R = diag(sn_j^2) or a full R written here,
// the truth's noise per output (and its correlation), and the closed-form rho* of a two-sensor random walk.
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
using hinf::test::config_from_text;

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

// C, dC/dx and B of kLinear-shaped config c's (weighted) system and of its inner one at x = (0.7, -0.3), t = 0
struct Readout {
    double y[2], raw[2], H[4], Hr[4], B[4], Br[4];
    explicit Readout(const RunConfig& c) {
        const auto* w = dynamic_cast<const WeightedSystem*>(c.system.get());
        REQUIRE(w != nullptr);
        const double x[2] = {0.7, -0.3};
        c.system->measurement(y, x, 0, 1);
        w->inner().measurement(raw, x, 0, 1);
        c.system->measurement_jacobian(H, x, 0);
        w->inner().measurement_jacobian(Hr, x, 0);
        c.system->disturbance_gain(B, x, 0, 1);
        w->inner().disturbance_gain(Br, x, 0, 1);
    }
};

// kLinear's matrices: x+ = F x + G v, y = H x
const Eigen::Matrix2d kF = (Eigen::Matrix2d() << 1, 0.1, 0, 0.95).finished();
const Eigen::Matrix2d kG = (Eigen::Matrix2d() << 0.5, 0, 1, 0.2).finished();
const Eigen::Matrix2d kH = (Eigen::Matrix2d() << 1, 0.5, 0, 1).finished();

// The textbook Kalman filter of kLinear told R and Q = G Qv G' on the record y (K rows of 2), from x^ = 0, P = I:
// its one-step predictions, K rows of 2
std::vector<double> kalman(const std::vector<double>& y, int K, const Eigen::Matrix2d& R, const Eigen::Matrix2d& Qv) {
    Eigen::Matrix2d P = Eigen::Matrix2d::Identity();
    Eigen::Vector2d xh(0, 0);
    std::vector<double> out;
    for (int k = 0; k < K; ++k) {
        out.push_back(xh[0]);
        out.push_back(xh[1]);
        const Eigen::Matrix2d S = kH * P * kH.transpose() + R;
        const Eigen::Matrix2d Kg = P * kH.transpose() * S.inverse();
        xh += Kg * (Eigen::Vector2d(y[2 * k], y[2 * k + 1]) - kH * xh);
        const Eigen::Matrix2d IKH = Eigen::Matrix2d::Identity() - Kg * kH;
        P = IKH * P * IKH.transpose() + Kg * R * Kg.transpose();
        xh = kF * xh;
        P = kF * P * kF.transpose() + kG * Qv * kG.transpose();
    }
    return out;
}

// A record of K steps of cfg's system (kLinear's shape) driven by deterministic disturbances, its outputs with
// deterministic "noise" in each output's units (`cross` x the first output's in the second: correlated)
void make_record(const hinf::Config& cfg, int K, double cross, std::vector<double>* t, std::vector<double>* y) {
    std::vector<double> x = cfg.initial_state();
    for (int k = 0; k < K; ++k) {
        const std::vector<double> c = cfg.measure(x, double(k));
        t->push_back(double(k));
        y->push_back(c[0] + 0.1 * std::sin(0.7 * k));
        y->push_back(c[1] + 0.4 * std::cos(1.3 * k) + cross * std::sin(0.7 * k));
        x = cfg.advance(x, {0.3 * std::sin(0.2 * k), 1.5 * std::cos(0.5 * k)}, double(k), 1.0);
    }
}

// EKF and UKF stepped through the record (t, y) give the one-step predictions `want` to 1e-9; Config::advance takes
// v in the user's units (x+ = F x + G v)
void check_stepped(const hinf::Config& cfg, const std::vector<double>& t, const std::vector<double>& y,
                   const std::vector<double>& want) {
    const std::vector<double> x1 = cfg.advance({1.0, -1.0}, {0.3, 1.5}, 0.0, 1.0);
    const Eigen::Vector2d x1_want = kF * Eigen::Vector2d(1.0, -1.0) + kG * Eigen::Vector2d(0.3, 1.5);
    CHECK(x1[0] == Approx(x1_want[0]).epsilon(1e-14));
    CHECK(x1[1] == Approx(x1_want[1]).epsilon(1e-14));
    for (const char* name : {"ekf", "ukf"}) {
        INFO(name);
        hinf::Filter f = hinf::Filter::create(cfg, name);
        for (std::size_t k = 0; k < t.size(); ++k) {
            const std::vector<double> xe = f.estimate();
            CHECK(xe[0] == Approx(want[2 * k]).margin(1e-9));
            CHECK(xe[1] == Approx(want[2 * k + 1]).margin(1e-9));
            REQUIRE(f.step(&y[2 * k], t[k]));
        }
    }
}

// How far the PF (4000 particles) on the record is from the right Kalman filter and from a wrong one, and how far
// those two are apart: the largest gaps over steps 10 .. K-1. The PF must be much nearer the right one.
void check_pf_nearer(const hinf::Config& cfg, const std::vector<double>& t, const std::vector<double>& y,
                     const std::vector<double>& right, const std::vector<double>& wrong) {
    hinf::FilterOptions o;
    o.particles = 4000;
    const hinf::FilterTrace pf = hinf::Filter::create(cfg, "pf", o).run(t, y);
    double to_right = 0, to_wrong = 0, apart = 0;
    for (std::size_t k = 10; k < t.size(); ++k)
        for (std::size_t i = 0; i < 2; ++i) {
            to_right = std::max(to_right, std::fabs(pf.xhat[2 * k + i] - right[2 * k + i]));
            to_wrong = std::max(to_wrong, std::fabs(pf.xhat[2 * k + i] - wrong[2 * k + i]));
            apart = std::max(apart, std::fabs(wrong[2 * k + i] - right[2 * k + i]));
        }
    INFO("PF to the right KF " << to_right << ", to the wrong KF " << to_wrong << ", the KFs apart " << apart);
    CHECK(to_right < 0.4 * apart);
    CHECK(to_right < to_wrong);
}
}  // namespace

TEST_CASE("std lists: the model measures every output and input in units of its own std", "[config][channels]") {
    const RunConfig c = config_from_text(kLinear);
    CHECK(c.noise_std == 1.0);
    CHECK(c.disturbance_std == 1.0);
    CHECK(c.output_weight == std::vector<double>{1.0 / 0.1, 0.0, 0.0, 1.0 / 0.4});  // diag(1 / sn_j)
    CHECK(c.disturbance_scale == std::vector<double>{0.3, 0.0, 0.0, 1.5});      // diag(sv_k)
    const Readout r(c);
    const double *y = r.y, *raw = r.raw, *H = r.H, *Hr = r.Hr, *B = r.B, *Br = r.Br;
    for (int j = 0; j < 2; ++j) {
        CHECK(y[j] == raw[j] * c.output_weight[j * 3]);
        for (int i = 0; i < 2; ++i) CHECK(H[j * 2 + i] == Hr[j * 2 + i] * c.output_weight[j * 3]);
        for (int i = 0; i < 2; ++i) CHECK(B[i * 2 + j] == Br[i * 2 + j] * c.disturbance_scale[j * 3]);
    }
    // the user's units and back
    double u[2] = {raw[0], raw[1]};
    outputs_to_model(c, u, 1);
    CHECK(u[0] == y[0]);
    CHECK(u[1] == y[1]);
    outputs_to_user(c, u, 1);
    CHECK(u[0] == Approx(raw[0]).epsilon(1e-15));
    // a list's one-number partner is weighted too; two numbers keep the user's units
    const RunConfig partner = config_from_text(random_walk("[0.1, 0.4]"));
    CHECK(partner.disturbance_scale == std::vector<double>{0.1});
    CHECK(partner.disturbance_std == 1.0);
    const RunConfig plain = config_from_text(random_walk("0.2"));
    CHECK(plain.output_weight.empty());
    CHECK(plain.disturbance_scale.empty());
    CHECK(dynamic_cast<const WeightedSystem*>(plain.system.get()) == nullptr);
    CHECK(plain.noise_std == 0.2);
}

TEST_CASE("std lists: the truth's noise has each output's std in the user's units", "[config][channels]") {
    const RunConfig c = config_from_text(kLinear);
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
    make_record(cfg, K, 0.0, &t, &y);
    // the textbook filter in the user's units: R = diag(0.2^2, 0.3^2), Q = G diag(0.3^2, 1.5^2) G'
    const Eigen::Matrix2d F = kF, G = kG, H = kH, Qv = Eigen::Vector2d(0.09, 2.25).asDiagonal();
    auto kalman = [&](const Eigen::Matrix2d& R) { return ::kalman(y, K, R, Qv); };
    const Eigen::Matrix2d R = Eigen::Vector2d(0.04, 0.09).asDiagonal();
    const std::vector<double> want = kalman(R);
    // Config::advance takes v and measure gives y in the user's units: x+ = F x + G v, y = H x
    check_stepped(cfg, t, y, want);
    const std::vector<double> x1 = cfg.advance({1.0, -1.0}, {0.3, 1.5}, 0.0, 1.0);
    const std::vector<double> y1 = cfg.measure(x1, 1.0);
    const Eigen::Vector2d y1_want = H * (F * Eigen::Vector2d(1.0, -1.0) + G * Eigen::Vector2d(0.3, 1.5));
    CHECK(y1[0] == Approx(y1_want[0]).epsilon(1e-14));
    CHECK(y1[1] == Approx(y1_want[1]).epsilon(1e-14));
    for (const char* name : {"ekf", "ukf"}) {
        INFO(name);
        hinf::Filter f = hinf::Filter::create(cfg, name);
        // the whole record at once (hinf filter's path), innovations in the user's units
        const hinf::FilterTrace tr = f.run(t, y);
        for (int k = 0; k < K; ++k) CHECK(tr.xhat[2 * k] == Approx(want[2 * k]).margin(1e-9));
        const std::vector<double> c0 = cfg.measure({want[0], want[1]}, 0.0);
        CHECK(tr.innovation[0] == Approx(y[0] - c0[0]).margin(1e-12));
        CHECK(tr.innovation[1] == Approx(y[1] - c0[1]).margin(1e-12));
    }
    // the particle filter's likelihood: nearer the Kalman filter with this R than that with one std (0.3) for both
    check_pf_nearer(cfg, t, y, want, kalman(Eigen::Vector2d(0.09, 0.09).asDiagonal()));
}

TEST_CASE("std lists: rho* of a two-sensor random walk is b^2 + 1 / sum_j sn_j^-2", "[config][channels][rho]") {
    // in the model's units x+ = x + b v~, y~_j = x / sn_j + n~_j with unit stds, b = sv = 0.1: the a-priori
    // P+ = 1 / (1/P + h - 1/rho) + b^2, h = sum_j sn_j^-2, meets the existence bound P = rho at rho* = b^2 + 1/h
    // (one sensor in the user's units, b = h = 1: rho* = 2, test_game_level.cpp)
    const RunConfig c = config_from_text(random_walk("[0.1, 0.4]"));
    const double h = 1.0 / (0.1 * 0.1) + 1.0 / (0.4 * 0.4), want = 0.01 + 1.0 / h;
    REQUIRE(c.rho_auto);
    CHECK(c.rho_bound == Approx(want).epsilon(1e-2));
    CHECK(c.rho == Approx(kAutoRhoFactor * c.rho_bound).epsilon(1e-12));
}

TEST_CASE("std lists: bad lists are one line", "[config][channels]") {
    auto fails = [](const std::string& text, const std::string& fragment) {
        return hinf::test::one_line_error([&] { config_from_text(text); }, fragment);
    };
    CHECK(fails(random_walk("[0.1, 0.0]"), "entries must be in (0, 1e12]"));
    CHECK(fails(random_walk("[0.1, 0.2, 0.3]"), "has 3 entries, expected 2"));
    CHECK(fails(random_walk("[0.1, -0.2]"), "entries must be in (0, 1e12]"));
    CHECK(fails(random_walk("[0.1, 0.2]") + "[baseline]\nnoise_std = [0.1, 0.0]\n", "must be > 0"));
    // a list's partner of 0 (no process noise) stays in its own units
    const RunConfig still = config_from_text(random_walk("[0.1, 0.2]").replace(random_walk("[0.1, 0.2]").find("disturbance_std = 0.1"),
                                                                    21, "disturbance_std = 0.0"));
    CHECK(still.disturbance_scale.empty());
    CHECK(still.disturbance_std == 0.0);
}

// ------------------------------------------------------------------ correlated noise: noise_cov, disturbance_cov

namespace {
// kLinear with correlated covariances: outputs sn = (0.1, 0.4) with correlation 0.3, inputs sv = (0.3, 1.5) with 0.6
std::string correlated(const std::string& baseline = "") {
    return "[system]\nkind = \"expr\"\ntime = \"discrete\"\nstates = [\"a\", \"b\"]\ndisturbances = 2\n"
           "measurements = 2\nf = [\"a + 0.1*b\", \"0.95*b\"]\ng = [[\"0.5\", \"0\"], [\"1\", \"0.2\"]]\n"
           "h = [\"a + 0.5*b\", \"b\"]\n[filter]\nrho = 5\nQ = [1.0, 1.0]\nx0 = [1.0, -1.0]\nxhat0 = [0.0, 0.0]\n"
           "dt = 1\nt_final = 400\n[online]\nnoise_cov = [[0.01, 0.012], [0.012, 0.16]]\n"
           "disturbance_cov = [[0.09, 0.27], [0.27, 2.25]]\n" + baseline;
}
Eigen::Matrix2d mat2(const std::vector<double>& v) {
    Eigen::Matrix2d M;
    M << v[0], v[1], v[2], v[3];
    return M;
}
}  // namespace

TEST_CASE("noise_cov: the model whitens correlated outputs and inputs", "[config][channels][correlated]") {
    const RunConfig c = config_from_text(correlated());
    CHECK(c.noise_std == 1.0);
    CHECK(c.disturbance_std == 1.0);
    Eigen::Matrix2d R, V;
    R << 0.01, 0.012, 0.012, 0.16;
    V << 0.09, 0.27, 0.27, 2.25;
    const Eigen::Matrix2d W = mat2(c.output_weight), U = mat2(c.disturbance_scale);
    CHECK(W(0, 1) == 0.0);  // lower triangular
    CHECK(U(0, 1) == 0.0);
    // W R W' = I (the model's noise is white with unit std) and U U' = V
    CHECK((W * R * W.transpose() - Eigen::Matrix2d::Identity()).cwiseAbs().maxCoeff() < 1e-12);
    CHECK((U * U.transpose() - V).cwiseAbs().maxCoeff() < 1e-12);
    const Readout r(c);
    const double *y = r.y, *raw = r.raw, *H = r.H, *Hr = r.Hr, *B = r.B, *Br = r.Br;
    const Eigen::Vector2d y_want = W * Eigen::Vector2d(raw[0], raw[1]);
    const Eigen::Matrix2d H_want = W * mat2({Hr[0], Hr[1], Hr[2], Hr[3]}), B_want = mat2({Br[0], Br[1], Br[2], Br[3]}) * U;
    for (int j = 0; j < 2; ++j) {
        CHECK(y[j] == Approx(y_want[j]).epsilon(1e-14));
        for (int i = 0; i < 2; ++i) CHECK(H[j * 2 + i] == Approx(H_want(j, i)).epsilon(1e-14));
        for (int i = 0; i < 2; ++i) CHECK(B[j * 2 + i] == Approx(B_want(j, i)).epsilon(1e-14));
    }
    // the user's units and back; v~ = U^-1 v
    double u[2] = {raw[0], raw[1]};
    outputs_to_model(c, u, 1);
    CHECK(u[0] == Approx(y[0]).epsilon(1e-14));
    CHECK(u[1] == Approx(y[1]).epsilon(1e-14));
    outputs_to_user(c, u, 1);
    CHECK(u[0] == Approx(raw[0]).epsilon(1e-14));
    CHECK(u[1] == Approx(raw[1]).epsilon(1e-14));
    double v[2] = {0.3, -1.2};
    disturbances_to_model(c, v, 1);
    const Eigen::Vector2d v_want = U.inverse() * Eigen::Vector2d(0.3, -1.2);
    CHECK(v[0] == Approx(v_want[0]).epsilon(1e-14));
    CHECK(v[1] == Approx(v_want[1]).epsilon(1e-14));
    // a diagonal given as a flat list is the std list of its square roots, bit for bit
    const RunConfig flat = config_from_text(random_walk("0.1").replace(random_walk("0.1").find("noise_std = 0.1"), 15,
                                                           "noise_cov = [0.01, 0.16]"));
    const RunConfig list = config_from_text(random_walk("[0.1, 0.4]"));
    CHECK(flat.output_weight == list.output_weight);
    CHECK(flat.disturbance_scale == list.disturbance_scale);
}

TEST_CASE("noise_cov: the truth's noise and disturbance have the given covariances in the user's units",
          "[config][channels][correlated]") {
    const RunConfig c = config_from_text(correlated());
    const std::int64_t K = c.steps_until();
    const auto* w = dynamic_cast<const WeightedSystem*>(c.system.get());
    REQUIRE(w != nullptr);
    Eigen::Matrix2d Sn = Eigen::Matrix2d::Zero(), Sv = Eigen::Matrix2d::Zero();
    const Eigen::Matrix2d Ginv = mat2({0.5, 0.0, 1.0, 0.2}).inverse();
    std::int64_t count = 0;
    for (std::uint64_t run = 0; run < 10; ++run) {
        TruthRun tr = truth_simulate(c, scenario_named("nominal"), run, K);
        outputs_to_user(c, tr.y.data(), K);
        for (std::int64_t k = 0; k + 1 < K; ++k) {
            const double* x = tr.x.data() + k * 2;
            double raw[2];
            w->inner().measurement(raw, x, c.time_of(k), 1);
            const Eigen::Vector2d nk(tr.y[k * 2] - raw[0], tr.y[k * 2 + 1] - raw[1]);
            // x+ = F x + G v: v = G^-1 (x+ - F x)
            const Eigen::Vector2d vk = Ginv * Eigen::Vector2d(tr.x[(k + 1) * 2] - x[0] - 0.1 * x[1],
                                                               tr.x[(k + 1) * 2 + 1] - 0.95 * x[1]);
            Sn += nk * nk.transpose();
            Sv += vk * vk.transpose();
            ++count;
        }
    }
    Sn /= double(count);
    Sv /= double(count);
    // ~4000 draws: stds within 5 %, correlations within 0.05 (about 3.5 standard errors)
    CHECK(std::sqrt(Sn(0, 0)) == Approx(0.1).epsilon(0.05));
    CHECK(std::sqrt(Sn(1, 1)) == Approx(0.4).epsilon(0.05));
    CHECK(Sn(0, 1) / std::sqrt(Sn(0, 0) * Sn(1, 1)) == Approx(0.3).margin(0.05));
    CHECK(std::sqrt(Sv(0, 0)) == Approx(0.3).epsilon(0.05));
    CHECK(std::sqrt(Sv(1, 1)) == Approx(1.5).epsilon(0.05));
    CHECK(Sv(0, 1) / std::sqrt(Sv(0, 0) * Sv(1, 1)) == Approx(0.6).margin(0.05));
}

TEST_CASE("noise_cov: EKF, UKF (and PF) on a record are the Kalman filter with the full R and Q",
          "[config][channels][correlated][api]") {
    // the told measurement noise is another correlated covariance ([baseline] noise_cov), the told process noise the
    // truth's (G V G' with V correlated)
    const std::string text = correlated("[baseline]\nnoise_cov = [[0.04, -0.03], [-0.03, 0.09]]\n"
                                        "initial_std = [1.0, 1.0]\n");
    const hinf::Config cfg = hinf::Config::from_text(text, "t.toml");
    const int K = 60;
    std::vector<double> t, y;
    make_record(cfg, K, 0.05, &t, &y);
    const Eigen::Matrix2d V = (Eigen::Matrix2d() << 0.09, 0.27, 0.27, 2.25).finished();
    Eigen::Matrix2d R;
    R << 0.04, -0.03, -0.03, 0.09;
    const std::vector<double> want = kalman(y, K, R, V);
    check_stepped(cfg, t, y, want);
    // the particle filter's likelihood and process noise: nearer this Kalman filter than one blind to both
    // correlations
    const Eigen::Matrix2d Rd = R.diagonal().asDiagonal(), Vd = V.diagonal().asDiagonal();
    check_pf_nearer(cfg, t, y, want, kalman(y, K, Rd, Vd));
}

TEST_CASE("noise_cov: rho* of a two-sensor random walk is b^2 + 1 / (1' R^-1 1)", "[config][channels][rho][correlated]") {
    // whitened, y~ = W 1 x + n~: the information per step is |W 1|^2 = 1' R^-1 1, so rho* = b^2 + 1 / (1' R^-1 1)
    // (the list's closed form above, with sum_j sn_j^-2 replaced)
    const std::string text = random_walk("0.1").replace(random_walk("0.1").find("noise_std = 0.1"), 15,
                                                         "noise_cov = [[0.01, -0.02], [-0.02, 0.16]]");
    const RunConfig c = config_from_text(text);
    Eigen::Matrix2d R;
    R << 0.01, -0.02, -0.02, 0.16;
    const double h = Eigen::Vector2d::Ones().dot(R.inverse() * Eigen::Vector2d::Ones()), want = 0.01 + 1.0 / h;
    REQUIRE(c.rho_auto);
    CHECK(c.rho_bound == Approx(want).epsilon(1e-2));
    // the correlation matters: the same stds uncorrelated give another level
    CHECK(std::fabs(want - (0.01 + 1.0 / (1.0 / 0.01 + 1.0 / 0.16))) > 0.05 * want);
}

TEST_CASE("noise_cov: bad covariances are one line", "[config][channels][correlated]") {
    auto fails = [](const std::string& text, const std::string& fragment) {
        return hinf::test::one_line_error([&] { config_from_text(text); }, fragment);
    };
    const std::string base = random_walk("0.1");
    auto with = [&](const std::string& noise) { return base.substr(0, base.find("noise_std = 0.1")) + noise + "\n"; };
    CHECK(fails(with("noise_cov = [[0.01, 0.02], [0.03, 0.16]]"), "must be symmetric"));
    CHECK(fails(with("noise_cov = [[0.01, 0.05], [0.05, 0.16]]"), "must be positive definite"));
    CHECK(fails(with("noise_cov = [[0.01, 0.0], [0.0, -0.16]]"), "must be positive definite"));
    CHECK(fails(with("noise_cov = [[0.01, 0.0], [0.0, 0.16], [0.0, 0.0]]"), "must have 2 rows"));
    CHECK(fails(with("noise_cov = [0.01, 0.02]\nnoise_std = 0.1"), "not both"));
    CHECK(fails(with("noise_cov = [0.01, 0.02]") + "[baseline]\nnoise_cov = [[1.0, 2.0], [2.0, 1.0]]\n",
                "must be positive definite"));
    CHECK(fails(with("noise_cov = [[0.01, 0.001], [0.001, 0.02]]") + "[baseline]\nnoise_cov = [0.01, 0.02]\n"
                                                                     "noise_std = 0.1\n",
                "not both"));
}
