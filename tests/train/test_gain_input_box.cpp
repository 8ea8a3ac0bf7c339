// Where the gain filter holds its network's input (network.input_box, docs/method.md section 16.10): training draws
// the box once, at creation, from its own estimates (the q and 1 - q quantiles of z per state); training itself is
// unchanged; the filter evaluates the network at z held in the box, so far from the training estimates it keeps the
// gain of the box's edge instead of an extrapolation. A checkpoint from before the key holds nothing.
#include <catch2/catch.hpp>
#include <cmath>
#include <string>

#include "helpers.hpp"
#include "hinf/config.hpp"
#include "hinf/h5.hpp"
#include "filters/dnn.hpp"
#include "eval/worst.hpp"
#include "io/checkpoint.hpp"
#include "train/gain_samples.hpp"
#include "train/trainer.hpp"

using namespace hinf;

namespace {

// Van der Pol with a constant storage: K = rate dx o(z) / dy depends on x^ through z alone
std::string constant_s_config() {
    std::string text = test::tiny_vdp_gain_config("0.5");
    const std::string at = "hidden = [8]\n";
    return text.replace(text.find(at), at.size(), at + "storage_knots = 0\n");
}

using hinf::test::config_from_text;

void train(const RunConfig& cfg, const std::string& dir) {
    TrainOptions opt;
    opt.out_dir = dir;
    opt.quiet = true;
    REQUIRE(train_start(cfg, opt).status == 0);
}

std::vector<double> gain_at(FrozenNetwork& net, const RunConfig& cfg, const std::vector<double>& xhat) {
    std::vector<double> K(std::size_t(cfg.n) * cfg.m);
    net.gain(K.data(), nullptr, nullptr, xhat.data(), 0.2, *cfg.system, 1);
    return K;
}

}  // namespace

TEST_CASE("input_box: training is unchanged, and the filter holds the network's input in the training estimates' box",
          "[gain][input_box]") {
    test::TempDir d("inputbox");
    const RunConfig held = config_from_text(constant_s_config());
    const RunConfig free = config_from_text(constant_s_config(), "network.input_box=0");
    CHECK(held.input_box == 0.005);
    train(held, d / "held");
    train(free, d / "free");
    const Checkpoint<float> a = ckpt_read<float>(d / "held/checkpoint.h5"), b = ckpt_read<float>(d / "free/checkpoint.h5");
    CHECK(test::bitwise_equal(a.net.theta, b.net.theta));  // the box is not used in training
    CHECK(test::bitwise_equal(a.adam_m, b.adam_m));
    REQUIRE(b.net.step.gain.zlo.empty());
    const kern::GainSpec& g = a.net.step.gain;
    REQUIRE(g.zlo.size() == 2);
    REQUIRE(g.zhi.size() == 2);

    // the box holds all but about q = 0.5 % of the training estimates on each side: checked on 20000 others
    GainSamples s;
    kern::GainSpec one = g;
    one.group = 1;
    const std::int64_t N = 20000;
    gain_samples_build(&s, held, gain_pool_build(held), one, N, 7);
    for (int j = 0; j < 2; ++j) {
        REQUIRE(g.zlo[j] < g.zhi[j]);
        std::int64_t below = 0, above = 0;
        for (std::int64_t i = 0; i < N; ++i) {
            below += s.z[i * 2 + j] < g.zlo[j] ? 1 : 0;
            above += s.z[i * 2 + j] > g.zhi[j] ? 1 : 0;
        }
        INFO("state " << j << ": " << below << " below, " << above << " above of " << N);
        CHECK(below >= N / 1000);
        CHECK(below <= N / 100);
        CHECK(above >= N / 1000);
        CHECK(above <= N / 100);
    }

    RunConfig cfg;
    std::unique_ptr<FrozenNetwork> box = ckpt_frozen_network(d / "held/checkpoint.h5", &cfg);
    std::unique_ptr<FrozenNetwork> none = ckpt_frozen_network(d / "free/checkpoint.h5");
    auto at_z = [&](double z0, double z1) {
        return std::vector<double>{g.shift[0] + g.spread[0] * z0, g.shift[1] + g.spread[1] * z1};
    };
    // inside the box: the same network, the same gain
    const std::vector<double> mid = at_z(0.5 * (g.zlo[0] + g.zhi[0]), 0.5 * (g.zlo[1] + g.zhi[1]));
    CHECK(test::bitwise_equal(gain_at(*box, cfg, mid), gain_at(*none, cfg, mid)));
    // beyond it: the gain at the box's edge, not the extrapolation
    const std::vector<double> far = at_z(g.zhi[0] + 40.0, g.zlo[1] - 40.0), edge = at_z(g.zhi[0], g.zlo[1]);
    const std::vector<double> k_far = gain_at(*box, cfg, far), k_edge = gain_at(*none, cfg, edge);
    for (std::size_t i = 0; i < k_far.size(); ++i) CHECK(k_far[i] == Approx(k_edge[i]).epsilon(1e-12));
    CHECK(gain_at(*none, cfg, far) != k_far);

    // the filter says when its estimate went more than the box's width beyond it (hinf filter's note), and a reset
    // forgets it; an estimate inside says nothing
    std::unique_ptr<OnlineFilter> filter = make_gain_filter(filter_model(cfg), *box, "dnn_gain_measured");
    auto note_from = [&](const std::vector<double>& x0) {
        FilterStart start;
        start.xhat0 = x0;
        filter->reset(start);
        FilterInput in;  // no measurement: the estimate the network sees is x0
        in.t = 0.25;
        filter->step(in);
        return filter->run_note();
    };
    const std::string said = note_from(far);
    CHECK(said.find(" reached ") != std::string::npos);
    CHECK(said.find("where training's estimates spanned [") != std::string::npos);
    CHECK(said.find(", first more than a width beyond at t = 0.25 (") != std::string::npos);  // when it left
    CHECK(note_from(mid).empty());

    // hinf worst's replay keeps that note for each (set, filter), so it can say under which sets the estimate left
    // the region: a filter started far beyond the box says so, one started at the truth on nothing does not
    const std::int64_t K = 20;
    WorstSignals zero;
    zero.source = "zero";
    zero.signals.v.assign(std::size_t(K) * cfg.nv, 0.0);
    zero.signals.n.assign(std::size_t(K) * cfg.m, 0.0);
    RunConfig from_far = cfg, from_truth = cfg;
    from_far.xhat0 = far;
    from_truth.xhat0 = cfg.x0;
    const WorstReplay out = worst_replay(from_far, {filter.get()}, {zero}, K);
    REQUIRE(out.note.size() == 1);
    CHECK(out.note[0].rfind("its estimate went far beyond the region its network was trained on (", 0) == 0);
    CHECK(out.note[0].find(" reached ") != std::string::npos);
    const WorstReplay in = worst_replay(from_truth, {filter.get()}, {zero}, K);
    REQUIRE(in.note.size() == 1);
    CHECK(in.note[0].empty());

    // the bounds travel with the network
    h5::Handle f = h5::open_file(d / "held/checkpoint.h5", false);
    h5::Handle net = h5::open_group(f.get(), "network");
    CHECK(h5::get_attr_doubles(net.get(), "input_low") == g.zlo);
    CHECK(h5::get_attr_doubles(net.get(), "input_high") == g.zhi);
}

TEST_CASE("input_box: a gain checkpoint from before the key holds nothing and resets Adam as it was trained", "[gain][input_box][legacy]") {
    test::TempDir d("inputboxlegacy");
    const std::string dir = d / "run";
    test::copy_legacy_run("gain_constant_s", dir);
    CHECK(ckpt_config(dir + "/checkpoint.h5").input_box == 0);
    CHECK(ckpt_config(dir + "/checkpoint.h5").reset_adam);  // trained with the moments reset (method.md 16.11)
    RunConfig cfg;
    std::unique_ptr<FrozenNetwork> net = ckpt_frozen_network(dir + "/checkpoint.h5", &cfg);
    CHECK(net->step_config().gain.zlo.empty());
}

TEST_CASE("input_box: a share in [0, 0.49], for the gain variant only (and the Adam default of the gain variant)", "[gain][input_box][config]") {
    CHECK(config_from_text(constant_s_config(), "network.input_box=0.02").input_box == 0.02);
    CHECK_THROWS_WITH(config_from_text(constant_s_config(), "network.input_box=0.5"), Catch::Contains("input_box"));
    std::string dissipative = constant_s_config();
    dissipative.replace(dissipative.find("variant = \"gain\""), 16, "variant = \"dissipative\"");
    dissipative.replace(dissipative.find("storage_knots = 0\n"), 18, "");
    CHECK(config_from_text(dissipative).input_box == 0);
    // Adam: the gain variant keeps its moments across time steps, the chained variants restart them (method.md 16.11)
    CHECK_FALSE(config_from_text(constant_s_config()).reset_adam);
    CHECK(config_from_text(dissipative).reset_adam);
    CHECK_THROWS_WITH(config_from_text(dissipative, "network.input_box=0.01"), Catch::Contains("variant = \"gain\""));
}
