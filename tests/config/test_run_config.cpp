// Defaults for a system of one's own come from its own scales, never the missile's (issue 15); the missile keeps
// its documented defaults.
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "config/run_config.hpp"
#include "helpers.hpp"
#include "hinf/config.hpp"
#include "train/trainer.hpp"

using namespace hinf;

namespace {
std::string own_text() { return test::read_text(test::source_path("tests/corpus/good/vanderpol_own_defaults.toml")); }
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

TEST_CASE("a default settle window shorter than a tenth of the run is none and a named one is kept",
          "[config][defaults]") {
    const std::string missile = "[system]\nkind = \"missile\"\n[filter]\nt_final = ";
    CHECK(load_run_config(ConfigDoc::from_text(missile + "70\n", "m.toml")).settle_time == 5.0);
    CHECK(load_run_config(ConfigDoc::from_text(missile + "5.6\n", "m.toml")).settle_time == 5.0);  // 0.6 s of 5.6
    // 5.3 s would settle on its last 0.3 s (30 steps of 0.01 s); 5.005 s on one step: the whole run instead
    CHECK(load_run_config(ConfigDoc::from_text(missile + "5.3\n", "m.toml")).settle_time == 5.3);
    CHECK(load_run_config(ConfigDoc::from_text(missile + "5.005\n", "m.toml")).settle_time == 5.005);
    CHECK(load_run_config(ConfigDoc::from_text(missile + "3\n", "m.toml")).settle_time == 5.0);  // no window anyway
    CHECK(load_run_config(ConfigDoc::from_text(missile + "5.3\n[online]\nsettle_time = 5\n", "m.toml"))
              .settle_time == 5.0);
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

TEST_CASE("a large system of one's own gets a default network it can load and train", "[config][defaults]") {
    // hidden = [2 O, O], O = n(n+1)/2, up to about 57 states; beyond, both widths shrink alike to at most 1e7
    // parameters (at 100 states the rule alone gave 1.0e8 and the config was refused by its own default)
    auto load_n = [](int n) {
        std::string st, f, g, x0, xh;
        for (int i = 0; i < n; ++i) {
            const std::string c = i ? ", " : "";
            st += c + "\"x" + std::to_string(i) + "\"";
            f += c + "\"-x" + std::to_string(i) + "\"";
            g += c + "[\"1\"]";
            x0 += c + "1.0";
            xh += c + "0.0";
        }
        return load_run_config(ConfigDoc::from_text(
            "[system]\nkind = \"expr\"\nstates = [" + st + "]\ndisturbances = 1\nmeasurements = 1\nf = [" + f +
                "]\ng = [" + g + "]\nh = [\"x0\"]\n[filter]\nrho = 10\nx0 = [" + x0 + "]\nxhat0 = [" + xh +
                "]\ndt = 0.01\nt_final = 0.05\n[online]\ndisturbance_std = 1\nnoise_std = 1\n",
            "big.toml"));
    };
    auto params = [](int n, const std::vector<int>& h) {
        double p = 0;
        for (std::size_t l = 0; l <= h.size(); ++l) {
            const double din = l == 0 ? n : h[l - 1], dout = l == h.size() ? double(n) * n : h[l];
            p += din * dout + dout;
        }
        return p;
    };
    CHECK(load_n(40).hidden == std::vector<int>{1640, 820});  // the rule, unchanged
    for (int n : {57, 100, 150}) {
        INFO(n << " states");
        const RunConfig c = load_n(n);
        REQUIRE(c.hidden.size() == 2u);
        CHECK(params(n, c.hidden) <= 1e7);
        CHECK(params(n, c.hidden) > 0.7e7);      // shrunk by the smallest steps that fit, not more
        CHECK(std::abs(c.hidden[0] - 2 * c.hidden[1]) <= 10);  // alike (to the rounding of each step)
    }
}

TEST_CASE("the keys hinf chose travel in a comment line and are left out of the config as given", "[config][resume]") {
    // docs/method.md section 16.7, "A start that diverges": the start check's flat knots are hinf's choice, not the
    // user's; a run resumed to t_final decides its storage from the config as given, as the run uninterrupted does
    const RunConfig given = load_run_config(
        ConfigDoc::from_file(test::source_path("tests/corpus/good/vanderpol_own_defaults.toml")));
    REQUIRE(given.variant == "gain");
    REQUIRE(given.storage_knots > 0);
    REQUIRE(given.storage_init == "riccati");
    const RunConfig flat = flat_start_config(given, /*by_hinf=*/true);
    CHECK(flat.chosen == std::vector<std::string>{"network.storage_init", "objective.margin"});
    const std::string text = config_record(flat);
    CHECK(chosen_keys(text) == flat.chosen);
    const RunConfig read = load_run_config(ConfigDoc::from_text(text, "record.toml"));  // the line is a comment
    CHECK(read.storage_init == "flat");
    CHECK(read.margin == given.margin);
    RunConfig with_keys = read;
    with_keys.chosen = chosen_keys(text);
    const RunConfig back = config_as_given(with_keys);
    CHECK_FALSE(ConfigSection(back.doc, "network").has("storage_init"));  // (an emptied table may stay)
    CHECK_FALSE(ConfigSection(back.doc, "objective").has("margin"));
    CHECK(back.storage_init == "riccati");
    CHECK(back.chosen.empty());
    // a flat start kept as an alternative reads as named; a config that named a key keeps it as its own
    CHECK(flat_start_config(given, /*by_hinf=*/false).chosen.empty());
    CHECK(config_record(flat_start_config(given, false)) == flat_start_config(given, false).doc.text());
    ConfigDoc named = given.doc;
    named.set("objective.margin=0.01");
    CHECK(flat_start_config(load_run_config(named), true).chosen == std::vector<std::string>{"network.storage_init"});
    CHECK(chosen_keys(given.doc.text()).empty());

    // a system of one's own that names no level and no Q: hinf's defaults, recorded as its choice; as given, the
    // level stays the one trained with and reads as the default again
    ConfigDoc bare = given.doc;
    bare.unset("filter.rho");
    bare.unset("filter.Q");
    const RunConfig defaults = load_run_config(bare);
    REQUIRE(defaults.rho_auto);
    CHECK(defaults.chosen == std::vector<std::string>{"filter.rho", "filter.Q"});
    RunConfig stored = load_run_config(ConfigDoc::from_text(config_record(defaults), "stored.toml"));
    CHECK_FALSE(stored.rho_auto);  // the text names the level
    stored.chosen = chosen_keys(config_record(defaults));
    const RunConfig as_given = config_as_given(stored);
    CHECK(as_given.rho_auto);
    CHECK(as_given.q_auto);
    CHECK(as_given.rho == defaults.rho);
    CHECK(as_given.rho_bound == Approx(defaults.rho_bound).epsilon(1e-15));
    CHECK(as_given.chosen == defaults.chosen);
    // a config made from it with another storage keeps them as hinf's; one that names another level does not
    ConfigDoc other = stored.doc;
    other.set("network.storage_knots=0");
    RunConfig constant = load_run_config(other);
    inherit_chosen(&constant, stored);
    CHECK(constant.chosen == std::vector<std::string>{"filter.rho", "filter.Q"});
    other.set("filter.rho=7");
    RunConfig named_level = load_run_config(other);
    inherit_chosen(&named_level, stored);
    CHECK(named_level.chosen == std::vector<std::string>{"filter.Q"});
}

TEST_CASE("every example config and every config in runs loads", "[config][examples]") {
    // the configs the README and docs tell a user to run: a default or a rule that changes must keep them loading
    // (need_level = false: a system of one's own that names no rho is not solved for rho* here)
    int count = 0;
    for (const char* folder : {"examples/systems", "runs"}) {
        for (const auto& entry : std::filesystem::directory_iterator(test::source_path(folder))) {
            if (entry.path().extension() != ".toml") continue;
            INFO(entry.path().string());
            if (entry.path().filename().string().rfind("delay_", 0) == 0) continue;  // hinf lmi's own format
            CHECK_NOTHROW(load_run_config(ConfigDoc::from_file(entry.path().string()), /*need_level=*/false));
            ++count;
        }
    }
    CHECK(count >= 50);
}
