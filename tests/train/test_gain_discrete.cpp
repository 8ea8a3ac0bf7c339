// Variant gain on a discrete-time system (docs/method.md section 16.8): a short training on a small linear system
// x_{k+1} = F x + G w, y = H x + v whose open-loop error level (gamma^2 ~ 4800) is far above rho = 6 gives a gain
// whose filter x^_{k+1} = F x^ + K(x^)(y - H x^) is stable at every estimate it meets, satisfies the one-step
// dissipation inequality at errors sampled around those estimates, and keeps the H-infinity bound on a run with
// fresh noise. Any of them can fail: they are what training is for.
#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>

#include "eval/engine.hpp"
#include "eval/operate.hpp"
#include "filters/dnn.hpp"
#include "filters/factory.hpp"
#include "filters/gain_law.hpp"
#include "gain.hpp"
#include "helpers.hpp"
#include "hinf/config.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"
#include "sim/truth.hpp"
#include "train/gain_samples.hpp"
#include "train/trainer.hpp"

using namespace hinf;

namespace {

const std::string kLinearGainTrain = hinf::test::linear_discrete_system_toml() + R"toml([filter]
variant = "gain"
rho = 6
Q = [1.0, 1.0]
x0 = [1, -1]
xhat0 = [0, 0]
dt = 1
t_final = 200
[online]
disturbance_std = 0.3
noise_std = 0.3
seed = 99
[network]
hidden = [16, 8]
[training]
samples = 256
batch = 64
adam_steps = 10
)toml";

}  // namespace

TEST_CASE("gain variant on a linear discrete system: stable, dissipative at sampled errors, within rho",
          "[train][gain][discrete][kalman]") {
  // both gain heads: K = rate D o diag(dy)^-1 ("direct") and K = F P H'(H P H' + R)^-1 ("kalman", method.md 16.16)
  for (const std::string head : {"direct", "kalman"}) {
    INFO("network.gain_head = " << head);
    test::TempDir d("gain-discrete-" + head);
    std::string text = kLinearGainTrain;
    text.replace(text.find("hidden = [16, 8]"), 16, "hidden = [16, 8]\ngain_head = \"" + head + "\"");
    RunConfig cfg = load_run_config(ConfigDoc::from_text(text, "linear.toml"));
    TrainOptions opt;
    opt.out_dir = d / "run";
    opt.quiet = true;
    const TrainSummary s = train_start(cfg, opt);
    REQUIRE(s.status == 0);
    RunConfig ncfg;
    std::unique_ptr<FrozenNetwork> net = ckpt_frozen_network(d / "run/checkpoint.h5", &ncfg);
    REQUIRE(net->step_config().gain.loss.discrete);
    REQUIRE(net->step_config().gain.kalman == (head == "kalman"));  // the checkpoint keeps the head

    // the trained filter on a run with the on-line seed (never a training run)
    const std::int64_t steps = cfg.steps_until();
    const TruthRun tr = truth_simulate(cfg, Scenario{}, 3, steps);
    std::unique_ptr<OnlineFilter> f = make_gain_filter(filter_model(cfg), *net, "dnn");
    f->reset(FilterStart{cfg.xhat0, {}, cfg.online_seed, 3});
    Eigen::Matrix2d F;
    F << 1.05, 0.2, -0.1, 0.9;
    const Eigen::RowVector2d H(1.0, 0.5);
    kern::GainLossParams lp = net->step_config().gain.loss;
    GainSamples smp;
    double error_energy = 0, signal_energy = 0, worst_radius = 0;
    int violations = 0, sampled = 0;
    for (std::int64_t k = 0; k < steps; ++k) {
        const double* x = tr.x.data() + k * 2;
        const std::vector<double> xhat(f->estimate(), f->estimate() + 2);
        const double e0 = x[0] - xhat[0], e1 = x[1] - xhat[1];
        error_energy += e0 * e0 + e1 * e1;
        signal_energy += tr.energy[k];
        double K[2], S[4];
        net->gain(K, S, nullptr, xhat.data(), cfg.time_of(k), *cfg.system, 1);
        const Eigen::Matrix2d A = F - Eigen::Vector2d(K[0], K[1]) * H;
        worst_radius = std::max(worst_radius, A.eigenvalues().cwiseAbs().maxCoeff());
        if (k % 10 == 0) {  // the one-step inequality at 16 errors sampled around this estimate
            gain_samples_at(&smp, cfg, net->step_config().gain, xhat.data(), cfg.time_of(k), 16,
                            (std::uint64_t(1) << 40) + std::uint64_t(k));
            for (int i = 0; i < 16; ++i) {
                const kern::GainSampleValue v = kern::gain_sample_forward(K, S, smp.view(), i, lp);
                violations += v.residual > 0.01 * v.abs_sum ? 1 : 0;
                ++sampled;
            }
        }
        FilterInput in;
        in.y = tr.y.data() + k;
        in.t = cfg.time_of(k);
        in.step = k;
        REQUIRE(f->step(in) == FILTER_OK);
    }
    INFO("spectral radius " << worst_radius << ", violations " << violations << " of " << sampled
                            << ", ratio " << error_energy / signal_energy);
    CHECK(worst_radius < 0.95);
    CHECK(violations <= sampled / 50);  // at most 2 %
    // the H-infinity bound of the one-step game: sum x~'Q x~ - V(x~(0)) <= rho sum |w|^2
    double K0[2], S0[4];
    net->gain(K0, S0, nullptr, cfg.xhat0.data(), 0.0, *cfg.system, 1);
    const double v0 = quadratic_form(S0, std::vector<double>{1.0, -1.0}.data(), 2);
    CHECK(error_energy - v0 <= cfg.rho * signal_energy);
    CHECK(error_energy / signal_energy < 0.5 * cfg.rho);
    if (head == "kalman") {  // K = F A with H A in [0, 1) at any estimate, trained or not (method.md 16.16)
        for (double a : {-30.0, -1.0, 0.0, 0.7, 50.0}) {
            double K1[2], S1[4];
            const double xh[2] = {a, -0.5 * a};
            net->gain(K1, S1, nullptr, xh, 0.0, *cfg.system, 1);
            const Eigen::Vector2d A = F.inverse() * Eigen::Vector2d(K1[0], K1[1]);
            const double ha = H * A;
            INFO("estimate " << a << ": H A = " << ha);
            CHECK(ha >= 0.0);
            CHECK(ha < 1.0);
        }
    }
  }
}

TEST_CASE("an ensemble of gain networks filters with the mean of their gains and refuses mixed models",
          "[train][gain][discrete][ensemble]") {
    test::TempDir d("gain-ensemble");
    ConfigDoc doc = ConfigDoc::from_text(kLinearGainTrain, "linear.toml");
    doc.set("filter.t_final=40");
    const RunConfig cfg = load_run_config(doc);
    auto train = [&](const std::vector<std::string>& sets, const std::string& dir) {
        ConfigDoc di = doc;
        for (const auto& s : sets) di.set(s);
        TrainOptions opt;
        opt.out_dir = d / dir;
        opt.quiet = true;
        REQUIRE(train_start(load_run_config(di), opt).status == 0);
        return d / (dir + "/checkpoint.h5");
    };
    const std::string p1 = train({"training.seed=1"}, "s1"), p2 = train({"training.seed=2"}, "s2");
    RunConfig ncfg;
    const std::unique_ptr<FrozenNetwork> n1 = ckpt_frozen_network(p1, &ncfg), n2 = ckpt_frozen_network(p2, &ncfg);
    const FilterModel model = filter_model(cfg);
    const TruthRun tr = truth_simulate(cfg, Scenario{}, 3, cfg.steps_until());
    auto input = [&](std::int64_t k) {
        FilterInput in;
        in.y = tr.y.data() + k;
        in.t = cfg.time_of(k);
        in.step = k;
        return in;
    };

    SECTION("two copies of one network are that network, bit for bit") {
        std::unique_ptr<OnlineFilter> one = make_gain_filter(model, *n1, "dnn");
        std::unique_ptr<OnlineFilter> two = make_gain_ensemble_filter(model, {n1.get(), n1.get()}, "dnn");
        one->reset(FilterStart{cfg.xhat0, {}, cfg.online_seed, 3});
        two->reset(FilterStart{cfg.xhat0, {}, cfg.online_seed, 3});
        for (std::int64_t k = 0; k < cfg.steps_until(); ++k) {
            REQUIRE(one->step(input(k)) == FILTER_OK);
            REQUIRE(two->step(input(k)) == FILTER_OK);
            for (int i = 0; i < 2; ++i) REQUIRE(one->estimate()[i] == two->estimate()[i]);
        }
    }
    SECTION("two networks: every step is F x^ + (K1 + K2)/2 (y - H x^) at the ensemble's own estimate") {
        std::unique_ptr<OnlineFilter> f = make_gain_ensemble_filter(model, {n1.get(), n2.get()}, "dnn");
        f->reset(FilterStart{cfg.xhat0, {}, cfg.online_seed, 3});
        double gain_gap = 0;
        for (std::int64_t k = 0; k < cfg.steps_until(); ++k) {
            const double xh[2] = {f->estimate()[0], f->estimate()[1]};
            double K1[2], K2[2];
            n1->gain(K1, nullptr, nullptr, xh, cfg.time_of(k), *cfg.system, 1);
            n2->gain(K2, nullptr, nullptr, xh, cfg.time_of(k), *cfg.system, 1);
            gain_gap = std::max(gain_gap, std::abs(K1[0] - K2[0]) + std::abs(K1[1] - K2[1]));
            const double e = tr.y[k] - (xh[0] + 0.5 * xh[1]);
            const double want[2] = {1.05 * xh[0] + 0.2 * xh[1] + 0.5 * (K1[0] + K2[0]) * e,
                                    -0.1 * xh[0] + 0.9 * xh[1] + 0.5 * (K1[1] + K2[1]) * e};
            REQUIRE(f->step(input(k)) == FILTER_OK);
            for (int i = 0; i < 2; ++i) REQUIRE(f->estimate()[i] == Approx(want[i]).margin(1e-12));
        }
        CHECK(gain_gap > 1e-3);  // the seeds' gains differ, so the mean is not either member's
    }
    SECTION("operate: the mean gain runs on-line, checked against each member's storage") {
        OperateOptions oo;
        oo.out_dir = d / "op";
        oo.mode = "measured";
        oo.runs = 2;
        oo.quiet = true;
        const OperateSummary s = operate_run(cfg, {n1.get(), n2.get()}, {p1, p2}, oo);
        REQUIRE(s.online_check_violation_fraction_per_network.size() == 2);
        REQUIRE(s.online_hji_violation_fraction_per_network.size() == 2);
        const std::vector<double>& f = s.online_check_violation_fraction_per_network;
        INFO("sampled violations against each storage: " << f[0] << ", " << f[1]);
        CHECK(s.online_check_violation_fraction == std::min(f[0], f[1]));
        CHECK(s.online_check_violation_fraction == f[s.online_check_network]);
        CHECK(s.online_hji_violation_fraction == s.online_hji_violation_fraction_per_network[s.online_check_network]);
        CHECK(std::isnan(s.attenuation_ratio_minus_v0));
        for (double v : f) CHECK((v >= 0.0 && v <= 1.0));
        // run 0's estimates are those of the ensemble filter on run 0's measurements
        const std::int64_t K = cfg.steps_until();
        const TruthRun t0 = truth_simulate(cfg, Scenario{}, 0, K);
        std::unique_ptr<OnlineFilter> ens = make_gain_ensemble_filter(model, {n1.get(), n2.get()}, "dnn");
        ens->reset(engine_filter_start(cfg, 0));
        h5::Handle file = h5::open_file(d / "op/operate.h5", false);
        const std::vector<double> xhat = h5::read_doubles(file.get(), "xhat");
        REQUIRE(xhat.size() == std::size_t(K) * 2);
        for (std::int64_t k = 0; k < K; ++k) {
            for (int i = 0; i < 2; ++i) REQUIRE(ens->estimate()[i] == xhat[std::size_t(k) * 2 + i]);
            FilterInput in;
            in.y = t0.y.data() + k;
            in.t = cfg.time_of(k);
            in.step = k;
            REQUIRE(ens->step(in) == FILTER_OK);
        }
        // one network's operate gives the same figures as an "ensemble" of its two copies, bit for bit
        oo.out_dir = d / "op1";
        const OperateSummary one = operate_run(cfg, *n1, p1, oo);
        oo.out_dir = d / "op11";
        const OperateSummary twice = operate_run(cfg, {n1.get(), n1.get()}, {p1, p1}, oo);
        CHECK(one.attenuation_ratio == twice.attenuation_ratio);
        CHECK(one.online_check_violation_fraction == twice.online_check_violation_fraction);
        CHECK(twice.online_check_violation_fraction_per_network[0] == twice.online_check_violation_fraction_per_network[1]);
        CHECK(one.online_hji_violation_fraction == twice.online_hji_violation_fraction);
        // retraining is per network: refused for an ensemble
        RunConfig re = cfg;
        re.retrain = true;
        CHECK_THROWS_WITH(operate_run(re, {n1.get(), n2.get()}, {p1, p2}, oo), Catch::Contains("retrains one network"));
    }
    SECTION("the factory: --ensemble gives one filter, and refuses one network or networks of two models") {
        const FilterModel told = model;
        FilterSetArgs a{"dnn", {p1, p2}, "measured", 100, 0.0, 8, true};
        const FilterSet set = build_filter_set(cfg, a, told, model);
        REQUIRE(set.filters.size() == 1);
        CHECK(set.filters[0]->name() == "dnn_gain_ensemble");
        a.networks = {p1};
        CHECK_THROWS_WITH(build_filter_set(cfg, a, told, model), Catch::Contains("two or more networks"));
        a.networks = {p1, train({"training.seed=1", "system.h=[\"a + 0.6*b\"]"}, "other")};
        CHECK_THROWS_WITH(build_filter_set(cfg, a, told, model), Catch::Contains("trained on another model"));
        a.networks = {p1, p2};
        a.filters = "ekf";  // --ensemble with no dnn filter to average
        CHECK_THROWS_WITH(build_filter_set(cfg, a, told, model), Catch::Contains("add dnn to --filters"));
        a.filters = "dnn";
        a.modes = "oracle";
        CHECK_THROWS_WITH(build_filter_set(cfg, a, told, model), Catch::Contains("measurements only"));
        a.modes = "measured";
        a.ensemble = false;
        CHECK_THROWS_WITH(build_filter_set(cfg, a, told, model), Catch::Contains("--ensemble averages"));
    }
}
