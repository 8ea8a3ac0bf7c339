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
