// `hinf worst` end to end on a tiny trained network: the table, worst.h5, --replay against another filter set,
// the plots and the table script, and one clear line for every bad flag or file.
#include <catch2/catch.hpp>
#include <fstream>

#include "helpers.hpp"
#include "hinf/h5.hpp"

using hinf::test::expect_one_line_error;
using hinf::test::run_hinf;
using hinf::test::TempDir;

TEST_CASE("hinf worst searches, saves, replays and rejects bad input", "[cli][worst]") {
    TempDir d("cli-worst");
    const std::string cfg = d / "tiny.toml";
    std::ofstream(cfg) << hinf::test::tiny_missile_config("0.3");
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet");
    INFO(t.output);
    REQUIRE(t.status == 0);
    const std::string net = d / "run/checkpoint.h5";
    const std::string small = " --evals 8 --random-starts 1 --scenario-starts nominal --quiet";
    auto r = run_hinf("worst " + cfg + " --network " + net + " --mode oracle --filters dnn,ekf" + small + " --out " +
                      (d / "w"));
    INFO(r.output);
    REQUIRE(r.status == 0);
    for (const char* name : {"dnn_dissipative_oracle", "ekf"}) CHECK(r.output.find(name) != std::string::npos);
    hinf::h5::Handle f = hinf::h5::open_file(d / "w/worst.h5", false);
    CHECK(hinf::h5::get_attr_string(f.get(), "format") == "hinf-worst");
    {
        // the DNN filter got the game's start besides the random and the scenario one
        hinf::h5::Handle g = hinf::h5::open_group(f.get(), "filters/dnn_dissipative_oracle");
        CHECK(hinf::h5::get_attr_string(g.get(), "starts") == "random:0,scenario:nominal,game,linear");
        hinf::h5::Handle e = hinf::h5::open_group(f.get(), "filters/ekf");
        CHECK(hinf::h5::get_attr_string(e.get(), "starts") == "random:0,scenario:nominal,linear");
        CHECK(hinf::h5::get_attr_double(e.get(), "linear_gain") > 0);
        hinf::h5::Handle c = hinf::h5::open_group(f.get(), "cross");
        CHECK(hinf::h5::read_doubles(c.get(), "ratio").size() == 4u);
    }

    // the same signals against another filter set
    auto p = run_hinf("worst " + cfg + " --replay " + (d / "w/worst.h5") +
                      " --filters ukf,open_loop --quiet --plot --out " + (d / "rp"));
    INFO(p.output);
    REQUIRE(p.status == 0);
    CHECK(p.output.find("2 signal set(s)") != std::string::npos);
    for (const char* png : {"worst_signals.png", "worst_errors.png"}) {
        std::ifstream in(d / (std::string("rp/") + png), std::ios::binary);
        char magic[4] = {0, 0, 0, 0};
        in.read(magic, 4);
        INFO(png);
        CHECK(std::string(magic + 1, 3) == "PNG");
    }
    // the particle filter with compare's and filter's --pf-roughening, on the same signals
    auto pr = run_hinf("worst " + cfg + " --replay " + (d / "w/worst.h5") +
                       " --filters pf --particles 100 --pf-roughening 0.2 --quiet --out " + (d / "rpf"));
    INFO(pr.output);
    REQUIRE(pr.status == 0);
    CHECK(pr.output.find("pf_roughened") != std::string::npos);
    auto tab = hinf::test::run_command("/usr/bin/python3 " + hinf::test::source_path("scripts/worst-table") + " " +
                                       (d / "w/worst.h5"));
    INFO(tab.output);
    CHECK(tab.status == 0);
    CHECK(tab.output.find("| dnn_dissipative_oracle | oracle |") != std::string::npos);

    // bad input: one line and a non-zero exit
    const std::string base = "worst " + cfg + " --filters ekf" + small;
    expect_one_line_error(base + " --energy -1", "--energy must be a finite number > 0");
    expect_one_line_error(base + " --energy 0", "--energy must be a finite number > 0");
    expect_one_line_error(base + " --energy nan", "--energy must be a finite number > 0");
    expect_one_line_error(base + " --energy inf", "--energy must be a finite number > 0");
    expect_one_line_error(base + " --algorithm GN_DIRECT", "is not one of");
    expect_one_line_error(base + " --pieces 0 --sines 0", "not both 0");
    expect_one_line_error(base + " --linear-pieces -1", "--linear-pieces must be in [0, 1000]");
    expect_one_line_error(base + " --linear-steps -1", "--linear-steps must be a finite number >= 0");
    expect_one_line_error(base + " --pf-roughening -1", "--pf-roughening must be a finite number >= 0");
    expect_one_line_error(base + " --particles 0", "--particles must be >= 1");
    expect_one_line_error("worst " + cfg + " --filters ekf --evals 0", "--evals must be >= 1");
    expect_one_line_error("worst " + cfg + " --filters ekf --scenario-starts nominal,windy", "is not one of");
    // a filter whose one start was its linear one, which found no linear regime (the Henon map's UKF over 30 steps,
    // docs/compare.md "The linear start"; the EKF has one): said for that filter, where a write of its empty worst
    // signals once failed with "disk full, or a damaged file?"
    expect_one_line_error("worst " + hinf::test::source_path("examples/systems/henon.toml") +
                              " --filters ekf,ukf --until 30 --random-starts 0 --scenario-starts none --evals 1 --quiet --out " +
                              (d / "henon"),
                          "worst: no start for ukf: its linear start found no linear regime");
    const std::string vdp = hinf::test::source_path("runs/vanderpol.toml");
    expect_one_line_error("worst " + vdp + " --filters ekf --replay " + (d / "w/worst.h5"), "its signals are for system");
    expect_one_line_error("worst " + cfg + " --filters ekf --replay " + (d / "run/trajectory.h5"), "not a file written by");
    expect_one_line_error("worst " + cfg + " --filters ekf --replay " + (d / "missing.h5"), "missing.h5");
}
