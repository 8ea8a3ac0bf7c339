// A gain network's input for an angle state (network.angle_inputs, docs/method.md section 16.19): "periodic" (the
// default) feeds (cos, sin) of the estimate's angle, so the gain K(x^) is the same a turn on, however far the angle
// has wound beyond training's estimates; "raw" standardises it as any state (every gain network before 2026-12-07,
// and a checkpoint of that time reads as "raw").
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "config/run_config.hpp"
#include "helpers.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"
#include "net/network.hpp"
#include "train/trainer.hpp"

using namespace hinf;

namespace {

// a phase-locked loop: phase and frequency of a sinusoid seen through one noisy sample stream (the phase winds)
std::string pll_config(const std::string& network = "") {
    return test::phase_lock_system() + R"cfg([filter]
variant = "gain"
rho = 0.5
x0 = [0.0, 6.0]
xhat0 = [0.4, 5.5]
dt = 0.01
t_final = 0.5
[network]
hidden = [8]
)cfg" + network +
           R"cfg(
[training]
samples = 64
batch = 32
adam_steps = 2
checkpoint_every = 50
acceptance_runs = 0
select_every = 0
[online]
disturbance_std = [0.05, 0.3]
noise_std = 0.1
)cfg";
}

// the largest |K(x^ with phi + turn) - K(x^)| over the largest |K(x^)|
double turn_change(FrozenNetwork& net, const System& sys, double turn) {
    double worst = 0, scale = 0;
    for (const double phi : {0.3, 2.0, -1.2}) {
        for (const double w : {5.0, 6.5}) {
            const double a[2] = {phi, w}, b[2] = {phi + turn, w};
            double Ka[2], Kb[2];
            net.gain(Ka, nullptr, nullptr, a, 0.2, sys, 1);
            net.gain(Kb, nullptr, nullptr, b, 0.2, sys, 1);
            for (int e = 0; e < 2; ++e) {
                worst = std::max(worst, std::fabs(Ka[e] - Kb[e]));
                scale = std::max(scale, std::fabs(Ka[e]));
            }
        }
    }
    REQUIRE(scale > 0);
    return worst / scale;
}

}  // namespace

TEST_CASE("angle inputs: a trained gain is the same a turn on, where the raw input is not", "[train][gain][angle]") {
    const double turn = 2.0 * M_PI;
    test::TempDir d("angle-inputs");
    for (const char* inputs : {"periodic", "raw"}) {
        INFO(inputs);
        const bool periodic = std::string(inputs) == "periodic";
        const RunConfig cfg =
            test::config_from_text(pll_config(periodic ? "" : "angle_inputs = \"raw\"\n"));  // the default is periodic
        TrainOptions opt;
        opt.out_dir = d / inputs;
        opt.quiet = true;
        REQUIRE(train_start(cfg, opt).status == 0);
        RunConfig trained;
        const std::unique_ptr<FrozenNetwork> net =
            ckpt_frozen_network(d / (std::string(inputs) + "/checkpoint.h5"), &trained);
        CHECK(trained.angle_inputs == inputs);
        // the angle is two entries of the network's input: (cos, sin)
        CHECK(net->step_config().shape.inputs() == (periodic ? 3 : 2));
        for (const std::string& set : ckpt_as_trained(d / (std::string(inputs) + "/checkpoint.h5")))
            CHECK(set.find("angle_inputs") == std::string::npos);  // this hinf's files record it
        for (const double turns : {1.0, 10.0}) {  // ten turns: far beyond every training estimate (0.5 s)
            const double change = turn_change(*net, *cfg.system, turns * turn);
            INFO(turns << " turns: relative change of K " << change);
            if (periodic)
                CHECK(change < 1e-12);
            else
                CHECK(change > 1e-3);
        }
        // filtering six times training's horizon: the raw phase leaves training's region (and its gain is the box
        // edge's, which hinf says); (cos, sin) does not
        const std::string file =
            test::write_file(d, std::string(inputs) + ".toml", pll_config(periodic ? "" : "angle_inputs = \"raw\"\n"));
        const auto r = test::run_hinf("compare " + file + " --network " + d / (std::string(inputs) + "/checkpoint.h5") +
                                      " --filters dnn --runs 2 --set filter.t_final=3 --quiet --out " +
                                      d / (std::string(inputs) + "-long"));
        INFO(r.output);
        CHECK(r.status == 0);
        CHECK((r.output.find("went far beyond the region") != std::string::npos) == !periodic);
    }
}

TEST_CASE("angle inputs: a gain checkpoint written before the key reads and filters as raw",
          "[train][gain][angle][legacy]") {
    // written by hinf 42d5451 (before network.angle_inputs) from tests/corpus/legacy/gain_angle_raw.toml
    const std::string path = test::source_path("tests/corpus/legacy/gain_angle_raw_checkpoint.h5");
    const std::vector<std::string> sets = ckpt_as_trained(path);
    CHECK(std::find(sets.begin(), sets.end(), "network.angle_inputs=\"raw\"") != sets.end());
    RunConfig trained;
    const std::unique_ptr<FrozenNetwork> net = ckpt_frozen_network(path, &trained);
    CHECK(trained.angle_inputs == "raw");
    CHECK(net->step_config().shape.inputs() == 2);
    CHECK(turn_change(*net, *trained.system, 2.0 * M_PI) > 1e-3);
    // a config of today, the same file: filtered as it was trained
    test::TempDir d("angle-legacy");
    const auto r = test::run_hinf("operate " + test::source_path("tests/corpus/legacy/gain_angle_raw.toml") +
                                  " --network " + path + " --runs 1 --quiet --out " + d / "op");
    INFO(r.output);
    CHECK(r.status == 0);
}

TEST_CASE("angle inputs: a gain network without angle states, or of another variant, is as before",
          "[train][gain][angle]") {
    // no angle state: the input is the n standardised states whatever the key says
    std::string plain = pll_config();
    plain.replace(plain.find("angle_states = [1]\n"), 19, "");
    const RunConfig cfg = test::config_from_text(plain);
    CHECK(network_step_config(cfg).shape.inputs() == 2);
    CHECK(network_step_config(test::config_from_text(pll_config())).shape.inputs() == 3);
    // another variant's network sees the error, not the estimate: the key is refused there
    std::string dissipative = pll_config("angle_inputs = \"periodic\"\n");
    dissipative.replace(dissipative.find("variant = \"gain\""), 16, "variant = \"dissipative\"");
    CHECK_THROWS_WITH(test::config_from_text(dissipative),
                      Catch::Contains("angle_inputs") && Catch::Contains("variant = \"gain\""));
}

TEST_CASE("angle inputs: the on-line check and retraining run on the (cos, sin) row, the same bits twice",
          "[train][gain][angle][cli]") {
    // hinf operate's on-line check samples errors around x^ and its retraining takes Adam steps on them: both form the
    // network's input as training does (its n + 1 entries here), over a phase that winds past training's estimates
    test::TempDir d("angle-online");
    const std::string cfg = test::write_file(d, "pll.toml", pll_config());
    const auto t = test::run_hinf("train " + cfg + " --quiet --out " + d / "run");
    INFO(t.output);
    REQUIRE(t.status == 0);
    std::string first;
    for (const char* out : {"op1", "op2"}) {
        const auto r = test::run_hinf("operate " + cfg + " --network " + d / "run/checkpoint.h5" +
                                      " --set online.retrain=true --set online.retrain_delta=0 --set filter.t_final=2"
                                      " --runs 1 --quiet --out " +
                                      d / out);
        INFO(r.output);
        REQUIRE(r.status == 0);
        h5::Handle f = h5::open_file(d / (std::string(out) + "/operate.h5"), false);
        const std::vector<double> xhat = h5::read_doubles(f.get(), "xhat");
        CHECK(r.output.find("on-line retraining (delta 0): 0 trigger") == std::string::npos);
        CHECK(r.output.find("on-line retraining (delta 0):") != std::string::npos);
        REQUIRE(xhat.size() == 2 * 200);
        std::string bits(reinterpret_cast<const char*>(xhat.data()), xhat.size() * sizeof(double));
        if (first.empty())
            first = bits;
        else
            CHECK(bits == first);
        for (double v : xhat) REQUIRE(std::isfinite(v));
    }
}

TEST_CASE("angle inputs: training says nothing of an angle's sign", "[train][gain][angle][cli]") {
    // the phase starts at 0 and winds up: the note on estimates that cross a sign the truth keeps (for a level or a
    // concentration) would advise state_bounds = [0, inf] for it, which means nothing for an angle
    test::TempDir d("angle-sign");
    const std::string cfg = test::write_file(d, "pll.toml", pll_config());
    const auto r = test::run_hinf("train " + cfg + " --quiet --out " + d / "run");
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK(r.output.find("state_bounds") == std::string::npos);
    std::string plain = pll_config();  // the same phase, not named an angle: the note, as before
    plain.replace(plain.find("angle_states = [1]\n"), 19, "");
    const auto p =
        test::run_hinf("train " + test::write_file(d, "plain.toml", plain) + " --quiet --out " + d / "plain");
    INFO(p.output);
    CHECK(p.status == 0);
    CHECK(p.output.find("keeps phi >= 0") != std::string::npos);
}
