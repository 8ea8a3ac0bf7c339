// Defaults for a system of one's own come from its own scales, never the missile's (issue 15); the missile keeps
// its documented defaults.
#include <catch2/catch.hpp>
#include <fstream>
#include <iterator>

#include "config/run_config.hpp"
#include "helpers.hpp"
#include "hinf/config.hpp"

using namespace hinf;

namespace {
std::string own_text() {
    std::ifstream in(test::source_path("tests/corpus/good/vanderpol_own_defaults.toml"));
    return std::string(std::istreambuf_iterator<char>(in), {});
}
}  // namespace

TEST_CASE("a system of one's own gets defaults from its own scales", "[config][defaults]") {
    RunConfig c = load_run_config(ConfigDoc::from_file(test::source_path("tests/corpus/good/vanderpol_own_defaults.toml")));
    // intensity = std^2 dt from its [online] noise levels (0.5, 0.1; dt = 0.01)
    CHECK(c.disturbance_intensity == Approx(0.5 * 0.5 * 0.01));
    CHECK(c.noise_intensity == Approx(0.1 * 0.1 * 0.01));
    // a tenth of the initial error |x0 - xhat0| = (1.5, 1.0)
    REQUIRE(c.error_floor.size() == 2u);
    CHECK(c.error_floor[0] == Approx(0.15));
    CHECK(c.error_floor[1] == Approx(0.1));
    CHECK(c.hidden == std::vector<int>{64, 32});

    SECTION("intensities given, noise levels follow") {
        std::string text = own_text();
        text = text.substr(0, text.find("[online]")) + "[objective]\ndisturbance_intensity = 0.04\nnoise_intensity = 0.0004\n";
        RunConfig d = load_run_config(ConfigDoc::from_text(text, "own.toml"));
        CHECK(d.disturbance_std == Approx(2.0));
        CHECK(d.noise_std == Approx(0.2));
    }
    SECTION("neither given: one line naming the key") {
        std::string text = own_text();
        text = text.substr(0, text.find("[online]"));
        CHECK_THROWS_WITH(load_run_config(ConfigDoc::from_text(text, "own.toml")),
                          Catch::Contains("disturbance_std: is required for a system of your own"));
    }
}

TEST_CASE("the built-in missile keeps its documented defaults", "[config][defaults]") {
    RunConfig c = load_run_config(ConfigDoc::from_text("[system]\nkind = \"missile\"\n", "m.toml"));
    CHECK(c.disturbance_intensity == 4.0);
    CHECK(c.noise_intensity == 4.0);
    CHECK(c.error_floor == std::vector<double>(6, 20.0));
    CHECK(c.hidden == std::vector<int>{256, 128, 32});
}

TEST_CASE("variant gain keeps its best validated checkpoint by default, about ten validations a run",
          "[config][defaults][select]") {
    // the missile: 7000 steps, checkpoints every 100 -> every 700 steps; another variant: off
    const std::string missile = "[system]\nkind = \"missile\"\n[filter]\nvariant = ";
    CHECK(load_run_config(ConfigDoc::from_text(missile + "\"gain\"\n", "m.toml")).select_every == 700);
    CHECK(load_run_config(ConfigDoc::from_text(missile + "\"dissipative\"\n", "m.toml")).select_every == 0);
    // a run shorter than ten checkpoints validates every checkpoint; a multiple of checkpoint_every always
    const std::string shorter = missile + "\"gain\"\nt_final = 3\n[training]\ncheckpoint_every = 40\n";
    CHECK(load_run_config(ConfigDoc::from_text(shorter, "m.toml")).select_every == 40);
    // the user's value wins, 0 included
    CHECK(load_run_config(ConfigDoc::from_text(missile + "\"gain\"\n[training]\nselect_every = 0\n", "m.toml"))
              .select_every == 0);
}
