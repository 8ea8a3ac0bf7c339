// End-to-end training on a small configuration: 1 vs 2 threads bit-identical; train 2T vs train T +
// resume + train T bit-identical (weights, Adam moments, states, trajectory); files read back.
#include <omp.h>

#include <catch2/catch.hpp>

#include "helpers.hpp"
#include "train/same_run.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"
#include "train/trainer.hpp"

using namespace hinf;
using hinf::test::require_same_checkpoint;
using hinf::test::require_same_trajectory;

namespace {

const char* kSmallTrain = R"(
[system]
kind = "KIND"
[filter]
type = "TYPE"
variant = "VARIANT"
t_final = 0.12
[network]
hidden = [16, 8]
precision = "PRECISION"
chunk = 30
[training]
samples = 200
batch = 80
adam_steps = 3
checkpoint_every = 4
RESET
)";

// variant gain on a small linear discrete-time system (the one-step game, docs/method.md section 16.8)
const std::string kSmallDiscrete = hinf::test::linear_discrete_system_toml() + R"([filter]
variant = "gain"
rho = 6
Q = [1.0, 1.0]
x0 = [1, -1]
xhat0 = [0, 0]
dt = 0.01
t_final = 0.12
[online]
disturbance_std = 0.3
noise_std = 0.3
[network]
hidden = [16, 8]
precision = "PRECISION"
chunk = 30
[training]
samples = 200
batch = 80
adam_steps = 3
checkpoint_every = 4
RESET
)";

// type "h2hinf" runs seed 001's mixed filter on its maneuvering missile (time-varying, nv = 6); variant
// "gain_discrete" is variant gain on kSmallDiscrete
RunConfig small_config(const std::string& variant, const std::string& precision, bool reset = true,
                       const std::string& type = "hinf") {
    if (variant == "gain_discrete") {
        std::string text = kSmallDiscrete;
        text.replace(text.find("PRECISION"), 9, precision);
        text.replace(text.find("RESET"), 5, reset ? "" : "reset_adam_each_step = false");
        return load_run_config(ConfigDoc::from_text(text, "small_discrete.toml"));
    }
    std::string text = kSmallTrain;
    text.replace(text.find("KIND"), 4, type == "h2hinf" ? "maneuvering_missile" : "missile");
    text.replace(text.find("TYPE"), 4, type);
    text.replace(text.find("VARIANT"), 7, variant);
    text.replace(text.find("PRECISION"), 9, precision);
    text.replace(text.find("RESET"), 5, reset ? "" : "reset_adam_each_step = false");
    return load_run_config(ConfigDoc::from_text(text, "small.toml"));
}

TrainSummary train(const RunConfig& cfg, const std::string& dir, double until, int threads) {
    omp_set_num_threads(threads);
    TrainOptions opt;
    opt.out_dir = dir;
    opt.until = until;
    opt.quiet = true;
    TrainSummary s = train_start(cfg, opt);
    omp_set_num_threads(2);
    return s;
}



}  // namespace

TEST_CASE("1 and 2 threads give bit-identical training", "[train][determinism]") {
    for (const char* variant : {"dissipative", "paper", "gain", "gain_discrete"}) {
        INFO(variant);
        test::TempDir d1("thr1"), d2("thr2");
        RunConfig cfg = small_config(variant, "float");
        train(cfg, d1 / "run", -1, 1);
        train(cfg, d2 / "run", -1, 2);
        require_same_checkpoint<float>(d1 / "run/checkpoint.h5", d2 / "run/checkpoint.h5");
        require_same_trajectory(d1 / "run/trajectory.h5", d2 / "run/trajectory.h5");
    }
}

TEST_CASE("mixed H2/H-infinity filter: 1 and 2 threads bit-identical, resume bit-identical", "[train][mixed]") {
    for (const char* variant : {"dissipative", "paper"}) {
        INFO(variant);
        test::TempDir d1("mthr1"), d2("mthr2");
        RunConfig cfg = small_config(variant, "float", true, "h2hinf");
        REQUIRE(cfg.nv == 6);
        train(cfg, d1 / "run", -1, 1);
        train(cfg, d2 / "run", -1, 2);
        require_same_checkpoint<float>(d1 / "run/checkpoint.h5", d2 / "run/checkpoint.h5");
        require_same_trajectory(d1 / "run/trajectory.h5", d2 / "run/trajectory.h5", true);
        // train T, resume, train T == train 2T
        TrainSummary half = train(cfg, d2 / "split", 0.06, 2);
        REQUIRE(half.last_step == 6);
        TrainOptions opt;
        opt.quiet = true;
        TrainSummary rest = train_resume(d2 / "split/checkpoint.h5", opt);
        CHECK(rest.last_step == 12);
        CHECK(rest.mixed);
        require_same_checkpoint<float>(d2 / "run/checkpoint.h5", d2 / "split/checkpoint.h5");
        require_same_trajectory(d2 / "run/trajectory.h5", d2 / "split/trajectory.h5", true);
    }
}

TEST_CASE("mixed filter: x^ + x~ equals x at every step, eqs. (11) and (23) as printed do not", "[train][mixed]") {
    test::TempDir d("mgap");
    RunConfig cfg = small_config("dissipative", "double", true, "h2hinf");
    TrainSummary s = train(cfg, d / "run", -1, 2);
    REQUIRE(s.status == 0);
    h5::Handle f = h5::open_file(d / "run/trajectory.h5", false);
    std::vector<double> gap = h5::read_doubles(f.get(), "consistency_gap");
    std::vector<double> printed = h5::read_doubles(f.get(), "consistency_gap_printed");
    std::vector<double> gain = h5::read_doubles(f.get(), "gain"), xt = h5::read_doubles(f.get(), "xtilde");
    REQUIRE(gap.size() == 12);
    for (std::size_t k = 0; k < gap.size(); ++k) {
        // the states are ~1e5: round-off of x - x^ is ~1e-11; the printed signs leave 2 h |l* dC| (dC = x~ here)
        CHECK(gap[k] < 1e-8);
        double worst = 0;
        for (int i = 0; i < 6; ++i) {
            double ldc = 0;
            for (int j = 0; j < 6; ++j) ldc += gain[k * 36 + i * 6 + j] * xt[k * 6 + j];
            worst = std::max(worst, 2 * cfg.dt * std::fabs(ldc));
        }
        CHECK(printed[k] == Approx(worst).epsilon(1e-6));
        CHECK(printed[k] > 1e-3);
    }
    CHECK(s.max_consistency_gap < 1e-8);
}

TEST_CASE("train 2T equals train T, resume, train T (bit-identical)", "[train][resume]") {
    for (std::string precision : {"float", "double"}) {
        for (bool reset : {true, false}) {
          for (const char* variant : {"dissipative", "gain", "gain_discrete"}) {
            INFO(precision << " reset_adam " << reset << " variant " << variant);
            test::TempDir d("resume");
            RunConfig cfg = small_config(variant, precision, reset);
            train(cfg, d / "full", -1, 2);
            TrainSummary half = train(cfg, d / "split", 0.06, 2);
            REQUIRE(half.last_step == 6);
            TrainOptions opt;
            opt.quiet = true;
            TrainSummary rest = train_resume(d / "split/checkpoint.h5", opt);
            CHECK(rest.first_step == 6);
            CHECK(rest.last_step == 12);
            if (precision == "float") require_same_checkpoint<float>(d / "full/checkpoint.h5", d / "split/checkpoint.h5");
            else require_same_checkpoint<double>(d / "full/checkpoint.h5", d / "split/checkpoint.h5");
            require_same_trajectory(d / "full/trajectory.h5", d / "split/trajectory.h5");
          }
        }
    }
}

TEST_CASE("resuming from an older checkpoint cuts the trajectory back and matches", "[train][resume]") {
    test::TempDir d("older");
    RunConfig cfg = small_config("dissipative", "float");
    train(cfg, d / "full", -1, 2);
    train(cfg, d / "split", -1, 2);
    // split/checkpoint.prev.h5 is the step-8 checkpoint; its trajectory already holds 12 rows
    std::filesystem::rename(d / "split/checkpoint.prev.h5", d / "split/checkpoint.h5");
    TrainOptions opt;
    opt.quiet = true;
    TrainSummary s = train_resume(d / "split/checkpoint.h5", opt);
    CHECK(s.first_step == 8);
    require_same_checkpoint<float>(d / "full/checkpoint.h5", d / "split/checkpoint.h5");
    require_same_trajectory(d / "full/trajectory.h5", d / "split/trajectory.h5");
}

TEST_CASE("training files read back through the library", "[io][files]") {
    test::TempDir d("files");
    RunConfig cfg = small_config("dissipative", "float");
    train(cfg, d / "run", -1, 2);
    Checkpoint<float> ck = ckpt_read<float>(d / "run/checkpoint.h5");
    CHECK(ck.state.step == 12);
    CHECK(ck.net.theta.size() == std::size_t(ck.net.step.shape.param_count()));
    CHECK(ck.net.step.shape.sizes == std::vector<int>{6, 16, 8, 21});
    h5::Handle f = h5::open_file(d / "run/trajectory.h5", false);
    std::vector<hsize_t> dims;
    std::vector<double> x = h5::read_doubles(f.get(), "x", &dims);
    CHECK(dims == std::vector<hsize_t>{12, 6});
    CHECK(x[0] == 150000.0);  // X(0) of seed 000
    std::vector<double> t = h5::read_doubles(f.get(), "t");
    CHECK(t[11] == Approx(0.11));
    h5::Handle ds(H5Dopen2(f.get(), "gain", H5P_DEFAULT));
    CHECK(h5::get_attr_string(ds.get(), "units") == "state/output per s");
    CHECK(h5::get_attr_string(f.get(), "format") == "hinf-trajectory");
    // the frozen network reproduces the last row's p at x~
    RunConfig stored = ckpt_config(d / "run/checkpoint.h5");
    CHECK(stored.n == 6);
}
