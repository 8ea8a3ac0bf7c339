// [sampling] state_bounds (docs/method.md section 16.3): the region where the model is meant to hold. The gain
// variant's training samples keep x and x^ inside it (x~ = x - x^ after), the on-line check's samples keep x inside
// it around the filter's own estimate, and a config without the key, or with open bounds, draws the same bits.
#include <catch2/catch.hpp>
#include <cmath>
#include <string>

#include "helpers.hpp"
#include "hinf/config.hpp"
#include "hinf/error.hpp"
#include "net/network.hpp"
#include "train/gain_samples.hpp"

using namespace hinf;

namespace {

RunConfig load_vdp(const std::string& set = "") {
    ConfigDoc doc = ConfigDoc::from_text(test::tiny_vdp_gain_config("0.5"), "t.toml");
    if (!set.empty()) doc.set(set);
    return load_run_config(doc);
}

GainSamples draw(const RunConfig& cfg) {
    GainSamples s;
    gain_samples_build(&s, cfg, gain_pool_build(cfg), network_step_config(cfg).gain, cfg.samples, 5);
    return s;
}

}  // namespace

TEST_CASE("state_bounds hold the gain variant's training samples inside the region and change nothing else",
          "[gain][state_bounds]") {
    const RunConfig free = load_vdp(), open = load_vdp("sampling.state_bounds=[[-inf, inf], [-inf, inf]]"),
                    held = load_vdp("sampling.state_bounds=[[0.0, 2.5], [-inf, inf]]");
    REQUIRE(free.state_lo.empty());
    REQUIRE(held.state_lo.size() == 2);
    CHECK(held.state_lo[0] == 0.0);
    CHECK(held.state_hi[0] == 2.5);
    CHECK(std::isinf(held.state_hi[1]));
    const GainSamples a = draw(free), b = draw(open), c = draw(held);
    const int n = free.n;
    CHECK(test::bitwise_equal(a.xt, b.xt));  // open bounds: the same samples
    CHECK(test::bitwise_equal(a.xhat, b.xhat));
    CHECK(test::bitwise_equal(a.dC, b.dC));
    int moved = 0;
    for (std::int64_t i = 0; i < free.samples; ++i) {
        INFO("sample " << i);
        CHECK(c.x[i * n] >= 0.0);
        CHECK(c.x[i * n] <= 2.5);
        CHECK(c.xhat[i * n] >= 0.0);
        CHECK(c.xhat[i * n] <= 2.5);
        CHECK(c.x[i * n + 1] == a.x[i * n + 1]);  // the open state is as drawn
        CHECK(c.xhat[i * n + 1] == a.xhat[i * n + 1]);
        const bool here = c.xhat[i * n] != a.xhat[i * n] || c.x[i * n] != a.x[i * n];
        if (here)  // held: the error is what is left between the two
            CHECK(c.xt[i * n] == c.x[i * n] - c.xhat[i * n]);
        else  // inside: the drawn error, bit for bit
            CHECK(c.xt[i * n] == a.xt[i * n]);
        CHECK(c.xt[i * n + 1] == a.xt[i * n + 1]);
        moved += here ? 1 : 0;
    }
    CHECK(moved > 0);  // the draw reaches outside [0, 2.5] (x0 = 2, errors of scale 1.7)

    // the on-line check's samples: the filter's own estimate stays, the errors' states are held
    GainSamples at;
    const double xhat[2] = {0.1, 0.3};
    gain_samples_at(&at, held, network_step_config(held).gain, xhat, 0.2, 200, 9);
    for (std::int64_t i = 0; i < 200; ++i) {
        CHECK(at.xhat[i * n] == 0.1);
        CHECK(at.x[i * n] >= 0.0);
        if (at.x[i * n] == 0.0) CHECK(at.xt[i * n] == -0.1);  // held at the bound
    }
}

TEST_CASE("state_bounds are refused in one line where they cannot hold", "[gain][state_bounds]") {
    CHECK_THROWS_WITH(load_vdp("sampling.state_bounds=[[0.0, 1.0]]"),
                      Catch::Contains("one [lo, hi] pair per state (2)"));
    CHECK_THROWS_WITH(load_vdp("sampling.state_bounds=[[1.0, 1.0], [-inf, inf]]"),
                      Catch::Contains("lo must be below hi"));
    CHECK_THROWS_WITH(load_vdp("sampling.state_bounds=[[0.0, 1.0], [-inf, inf]]"),
                      Catch::Contains("must hold [filter] x0 = 2 and xhat0 = 0.5"));
    CHECK_THROWS_WITH(load_vdp("sampling.state_bounds=[[0.0, 1.0, 2.0], [-inf, inf]]"),
                      Catch::Contains("must be two numbers [lo, hi]"));
    CHECK_THROWS_WITH(load_vdp("sampling.state_bounds=[[\"a\", 1.0], [-inf, inf]]"),
                      Catch::Contains("must be two numbers [lo, hi]"));
    std::string text = test::tiny_vdp_gain_config("0.5");
    text.replace(text.find("variant = \"gain\""), 16, "variant = \"dissipative\"");
    ConfigDoc doc = ConfigDoc::from_text(text, "t.toml");
    doc.set("sampling.state_bounds=[[-inf, inf], [-inf, inf]]");
    CHECK_THROWS_WITH(load_run_config(doc), Catch::Contains("variant = \"gain\" only"));
}

TEST_CASE("a state the truth runs keep on one side of 0 is named when the samples cross it", "[gain][state_bounds]") {
    // c stays at 1 and p at -1 on every run (no disturbance reaches them), s wanders around 0 on both sides; the
    // initial errors of 2 put a share of the sampled estimates of c below 0 and of p above 0
    const std::string text = R"([system]
kind = "expr"
states = ["c", "p", "s"]
disturbances = 1
measurements = 3
f = ["1 - c", "-1 - p", "-s"]
g = [["0"], ["0"], ["1"]]
h = ["c", "p", "s"]
[filter]
variant = "gain"
rho = 2.0
x0 = [1.0, -1.0, 0.0]
xhat0 = [3.0, -3.0, 0.5]
dt = 0.01
t_final = 0.5
[training]
samples = 100
batch = 40
[sampling]
trajectories = 3
[online]
disturbance_std = 0.5
noise_std = 0.1
)";
    const RunConfig cfg = load_run_config(ConfigDoc::from_text(text, "t.toml"));
    const GainPool pool = gain_pool_build(cfg);
    const std::vector<SignCrossing> x = gain_sign_crossings(cfg, pool, network_step_config(cfg).gain);
    REQUIRE(x.size() == 2);
    CHECK(x[0].state == 0);
    CHECK(x[0].positive);
    CHECK(x[0].share > kSignCrossingShare);
    CHECK(x[1].state == 1);
    CHECK_FALSE(x[1].positive);
    CHECK(x[1].share > kSignCrossingShare);
    const std::string note = gain_sign_note(cfg, x);
    CHECK_THAT(note, Catch::Contains("keeps c >= 0"));
    CHECK_THAT(note, Catch::Contains("and p <= 0"));
    CHECK_THAT(note, Catch::Contains("state_bounds = [[0, inf], [-inf, 0], [-inf, inf]]"));
    CHECK(gain_sign_note(cfg, {}).empty());

    // bounds named (the user's choice, whatever it is): no note
    ConfigDoc doc = ConfigDoc::from_text(text, "t.toml");
    doc.set("sampling.state_bounds=[[-inf, inf], [-inf, inf], [-inf, inf]]");
    const RunConfig held = load_run_config(doc);
    CHECK(gain_sign_crossings(held, gain_pool_build(held), network_step_config(held).gain).empty());
    // errors too small to reach 0: no note
    ConfigDoc near = ConfigDoc::from_text(text, "t.toml");
    near.set("filter.xhat0=[1.01, -1.01, 0.5]");
    near.set("sampling.error_floor=[0.001, 0.001, 0.1]");
    const RunConfig small = load_run_config(near);
    CHECK(gain_sign_crossings(small, gain_pool_build(small), network_step_config(small).gain).empty());
}
