// A `gain` checkpoint written before network.storage_knots existed (one constant S; the default is now a
// time-varying S(t)) still means what it meant: hinf reads it with storage_knots = 0, compares with it, and a resume
// continues bit for bit as the uninterrupted training of that hinf did (fixtures in tests/corpus/legacy, written by
// the hinf of commit e8e26a9: the 0.3 s checkpoint with its trajectory, and the 0.5 s checkpoint of the full run).
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "helpers.hpp"
#include "config/run_config.hpp"
#include "hinf/config.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"

using hinf::test::run_hinf;
using hinf::test::source_path;

TEST_CASE("a gain checkpoint with a constant S from before storage_knots loads and resumes as trained", "[cli][gain]") {
    hinf::test::TempDir d("legacy");
    const std::string dir = d / "run";
    hinf::test::copy_legacy_run("gain_constant_s", dir);
    const std::string cfg = source_path("tests/corpus/legacy/gain_constant_s.toml");

    auto c = run_hinf("compare " + cfg + " --network " + dir + "/checkpoint.h5 --filters dnn --runs 1 --quiet --out " +
                      (d / "cmp"));
    INFO(c.output);
    CHECK(c.status == 0);

    auto r = run_hinf("resume " + dir + "/checkpoint.h5 --quiet");
    INFO(r.output);
    REQUIRE(r.status == 0);
    hinf::h5::Handle got = hinf::h5::open_file(dir + "/checkpoint.h5", false);
    hinf::h5::Handle want = hinf::h5::open_file(source_path("tests/corpus/legacy/gain_constant_s_full.h5"), false);
    for (const char* name : {"network/layer_1/W", "network/layer_2/W", "network/storage"})
        hinf::test::check_legacy_array(hinf::h5::read_doubles(got.get(), name),
                                       hinf::h5::read_doubles(want.get(), name));
    hinf::h5::Handle net = hinf::h5::open_group(got.get(), "network");
    CHECK(hinf::h5::get_attr_int(net.get(), "storage_knots") == 0);
    const std::string text = hinf::h5::read_string(got.get(), "config");
    CHECK(text.find("# hinf resume at step 30: --set network.storage_knots=0") != std::string::npos);
}

TEST_CASE("a state started without error gets an error floor from its motion, and older files keep theirs",
          "[config][gain][legacy]") {
    // p starts with an error of 1, w (its velocity) and c (a constant) with none
    const std::string text = R"([system]
kind = "expr"
states = ["p", "w", "c"]
disturbances = 1
measurements = 1
f = ["w", "-4*p - 0.2*w", "0"]
g = [["0"], ["1"], ["0"]]
h = ["p + c"]
[filter]
rho = 2
Q = [1, 1, 1]
x0 = [1.0, 0.0, 3.0]
xhat0 = [0.0, 0.0, 3.0]
dt = 0.01
t_final = 0.5
[network]
hidden = [8]
[training]
samples = 40
batch = 20
adam_steps = 2
checkpoint_every = 10
acceptance_runs = 0
[online]
disturbance_std = 0.5
noise_std = 0.1
)";
    const hinf::RunConfig c = hinf::load_run_config(hinf::ConfigDoc::from_text(text, "t.toml"));
    std::vector<double> mean, sd;
    hinf::nominal_moments(c, &mean, &sd);
    REQUIRE(sd[1] > 0.1);  // w moves although it starts right
    CHECK(c.error_floor[0] == 0.1);
    CHECK(c.error_floor[1] == 0.1 * sd[1]);
    CHECK(c.error_floor[2] == 3e-3);  // c does not move: a thousandth of its size
    CHECK(hinf::error_floor_default(c, true) == std::vector<double>{0.1, 1e-3, 3e-3});

    // a file written before the rule, for the gain variant (its error scale) and for dissipative (its samples):
    // trained with the old floor, a config naming none, no error_floor attribute (made here from a run with that
    // floor set, its config put back to the text without it)
    hinf::test::TempDir d("floor");
    for (const std::string variant : {"gain", "dissipative"}) {
        INFO("variant " << variant);
        std::string plain = text;
        if (variant != "gain") plain.replace(plain.find("[filter]\n"), 9, "[filter]\nvariant = \"" + variant + "\"\n");
        const std::string run = d / variant;
        const std::string cfg =
            hinf::test::write_file(d, variant + ".toml", plain + "[sampling]\nerror_floor = [0.1, 0.001, 0.003]\n");
        auto t = run_hinf("train " + cfg + " --until 0.2 --out " + run + " --quiet");
        INFO(t.output);
        REQUIRE(t.status == 0);
        const std::string ck = run + "/checkpoint.h5";
        CHECK(hinf::ckpt_as_trained(ck).empty());
        {
            hinf::h5::Handle f = hinf::h5::open_file(ck, true);
            REQUIRE(H5Ldelete(f.get(), "config", H5P_DEFAULT) >= 0);
            hinf::h5::write_string(f.get(), "config", plain);
            REQUIRE(H5Adelete(f.get(), "config_hash") >= 0);
            hinf::h5::set_attr(f.get(), "config_hash", hinf::config_hash(plain));
            REQUIRE(H5Adelete(f.get(), "content_digest") >= 0);  // it covers the config (files without one still read)
            hinf::h5::Handle net = hinf::h5::open_group(f.get(), "network");
            REQUIRE(H5Adelete(net.get(), "error_floor") >= 0);
            for (const char* name : {"/trajectory.h5", "/trajectory.ckpt.h5"})  // the run's config there: the same
                if (std::filesystem::exists(run + name))
                    hinf::h5::set_text(hinf::h5::open_file(run + name, true).get(), "config", plain);
        }
        const std::string set = "sampling.error_floor=[0.10000000000000001, 0.001, 0.0030000000000000001]";
        CHECK(hinf::ckpt_as_trained(ck) == std::vector<std::string>{set});
        CHECK(hinf::ckpt_config(ck).error_floor == std::vector<double>{0.1, 1e-3, 3e-3});
        // it loads and resumes as trained (a gain network's input standardisation, checked on load, was made with
        // the old floor), and compares with the config as the user has it (no floor named)
        auto r = run_hinf("resume " + ck + " --until 0.3 --quiet");
        INFO(r.output);
        CHECK(r.status == 0);
        CHECK(hinf::h5::read_string(hinf::h5::open_file(ck, false).get(), "config").find("--set " + set) !=
              std::string::npos);
        auto cmp = run_hinf("compare " + hinf::test::write_file(d, variant + "_plain.toml", plain) + " --network " +
                            ck + " --filters dnn --runs 1 --quiet --out " + (d / (variant + "_cmp")));
        INFO(cmp.output);
        CHECK(cmp.status == 0);
    }
}
