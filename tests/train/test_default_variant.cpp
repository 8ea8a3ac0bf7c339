// The default variant (docs/formats.md [filter] variant): `gain` for an H-infinity filter of at most 32 states,
// outputs and disturbances, `dissipative` otherwise; `[online] mode` follows (measured for gain). A checkpoint from
// before the change (a config naming no variant, a network without a storage) is read, resumed and operated as the
// `dissipative` network it is.
#include <catch2/catch.hpp>
#include <string>

#include "config/run_config.hpp"
#include "helpers.hpp"
#include "hinf/config.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"

namespace {
using hinf::test::config_from_text;
}  // namespace

TEST_CASE("the default variant is gain where it applies, dissipative elsewhere", "[config][gain][default]") {
    const std::string missile = "[system]\nkind = \"missile\"\n";
    CHECK(config_from_text(missile).variant == "gain");
    CHECK(config_from_text(missile).mode == "measured");
    CHECK(config_from_text(missile + "[filter]\ntype = \"h2hinf\"\n").variant == "dissipative");
    CHECK(config_from_text(missile + "[filter]\ntype = \"h2hinf\"\n").mode == "oracle");
    CHECK(config_from_text(missile + "[filter]\nvariant = \"dissipative\"\n").mode == "oracle");
    // more than 32 states: the gain variant's fixed-size kernels do not take it
    std::string big = "[system]\nkind = \"expr\"\nstates = [";
    std::string f = "f = [", h = "h = [", g = "g = [";
    for (int i = 0; i < 33; ++i) {
        const std::string s = "s" + std::to_string(i), c = i ? ", " : "";
        big += c + "\"" + s + "\"";
        f += c + "\"-" + s + "\"";
        g += c + "[\"1\"]";
        if (i < 3) h += c + "\"" + s + "\"";
    }
    std::string x0 = "x0 = [", xh0 = "xhat0 = [";
    for (int i = 0; i < 33; ++i) {
        x0 += std::string(i ? ", " : "") + "1.0";
        xh0 += std::string(i ? ", " : "") + "0.0";
    }
    big += "]\nmeasurements = 3\n" + f + "]\n" + g + "]\n" + h + "]\n[filter]\n" + x0 + "]\n" + xh0 + "]\ndt = 0.01\nt_final = 1\n" +
           "[online]\ndisturbance_std = 1\nnoise_std = 1\n";
    CHECK(config_from_text(big).n == 33);
    CHECK(config_from_text(big).variant == "dissipative");
}

TEST_CASE("a config that names no variant trains the gain filter and operates it from measurements",
          "[cli][gain][default]") {
    hinf::test::TempDir d("defaulttrain");
    // a tiny missile run of the given [filter] lines, trained into DIR/out
    auto train = [&d](const std::string& filter, const std::string& out) {
        const std::string cfg = hinf::test::write_file(
            d, out + ".toml",
            "[system]\nkind = \"missile\"\n[filter]\n" + filter + "t_final = 0.05\n[network]\nhidden = [8]\n"
            "[training]\nsamples = 40\nbatch = 20\nadam_steps = 2\ncheckpoint_every = 5\nacceptance_runs = 0\n");
        auto t = hinf::test::run_hinf("train " + cfg + " --out " + (d / out) + " --quiet");
        INFO(t.output);
        REQUIRE(t.status == 0);
        return cfg;
    };
    const std::string cfg = train("", "run");
    CHECK(hinf::ckpt_config(d / "run/checkpoint.h5").variant == "gain");
    CHECK(hinf::ckpt_config(d / "run/checkpoint.h5").errors_per_estimate == 4);
    CHECK(hinf::ckpt_as_trained(d / "run/checkpoint.h5").empty());  // a file of this hinf: nothing read as legacy
    // nor for a network without a storage whose config names no variant (the mixed filter's default is dissipative)
    train("type = \"h2hinf\"\n", "mixed");
    CHECK(hinf::ckpt_config(d / "mixed/checkpoint.h5").variant == "dissipative");
    CHECK(hinf::ckpt_as_trained(d / "mixed/checkpoint.h5").empty());
    auto o = hinf::test::run_hinf("operate " + cfg + " --network " + (d / "run/checkpoint.h5") + " --runs 1 --quiet --out " +
                                  (d / "op"));
    INFO(o.output);
    REQUIRE(o.status == 0);
    CHECK(o.output.find("on-line phase: measured mode, 1 run(s), filter hinf, variant gain") != std::string::npos);
}

TEST_CASE("a checkpoint from before gain became the default resumes and operates as dissipative",
          "[cli][gain][default][legacy]") {
    // fixtures written by the hinf of commit 321db3c from tests/corpus/legacy/dissipative_default.toml (no variant):
    // the 0.05 s checkpoint with its trajectory, and the 0.1 s checkpoint of the uninterrupted run
    using hinf::test::source_path;
    hinf::test::TempDir d("defaultlegacy");
    const std::string dir = d / "run";
    hinf::test::copy_legacy_run("dissipative_default", dir);
    CHECK(hinf::ckpt_config(dir + "/checkpoint.h5").variant == "dissipative");
    CHECK(config_from_text(hinf::ConfigDoc::from_text(hinf::h5::read_string(hinf::h5::open_file(dir + "/checkpoint.h5", false).get(),
                                                                "config"),
                                          "c.toml")
                   .text())
              .variant == "gain");  // its config text alone now reads as gain
    auto r = hinf::test::run_hinf("resume " + dir + "/checkpoint.h5 --quiet");
    INFO(r.output);
    REQUIRE(r.status == 0);
    hinf::h5::Handle got = hinf::h5::open_file(dir + "/checkpoint.h5", false);
    hinf::h5::Handle want = hinf::h5::open_file(source_path("tests/corpus/legacy/dissipative_default_full.h5"), false);
    for (const char* name : {"network/layer_1/W", "network/layer_2/W", "adam/m", "adam/v"})
        hinf::test::check_legacy_array(hinf::h5::read_doubles(got.get(), name),
                                       hinf::h5::read_doubles(want.get(), name));
    CHECK(hinf::h5::read_string(got.get(), "config").find("# hinf resume at step 5: --set filter.variant=\"dissipative\"\n") !=
          std::string::npos);
    CHECK(hinf::ckpt_as_trained(dir + "/checkpoint.h5").empty());  // the resumed file names its variant
    // operated with the old config (no variant, so measured by default now): the dissipative network's filter
    auto o = hinf::test::run_hinf("operate " + source_path("tests/corpus/legacy/dissipative_default.toml") +
                                  " --network " + dir + "/checkpoint.h5 --runs 1 --quiet --out " + (d / "op"));
    INFO(o.output);
    REQUIRE(o.status == 0);
    CHECK(o.output.find("on-line phase: oracle mode, 1 run(s), filter hinf, variant dissipative") != std::string::npos);
}
