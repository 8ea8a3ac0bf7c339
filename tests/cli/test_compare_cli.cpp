// `hinf compare` end to end on a tiny trained network: table, compare.h5 groups, CSV rows, bad input.
#include <catch2/catch.hpp>
#include <fstream>
#include <sstream>

#include "helpers.hpp"
#include "hinf/h5.hpp"

using hinf::test::run_hinf;
using hinf::test::TempDir;

using hinf::test::expect_one_line_error;

TEST_CASE("hinf compare writes the table, compare.h5 and compare.csv and rejects bad input", "[cli][compare]") {
    TempDir d("cli-compare");
    const std::string cfg = d / "tiny.toml";
    std::ofstream(cfg) << hinf::test::tiny_missile_config();
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet");
    INFO(t.output);
    REQUIRE(t.status == 0);
    const std::string net = d / "run/checkpoint.h5";
    auto r = run_hinf("compare " + cfg + " --network " + net +
                      " --filters dnn,ekf,ukf,pf,open_loop,glf --runs 3 --particles 50 --quiet --out " + (d / "cmp"));
    INFO(r.output);
    REQUIRE(r.status == 0);
    CHECK(r.output.find("measurement streams identical for all filters: yes") != std::string::npos);
    const std::vector<std::string> names = {"dnn_dissipative_oracle", "dnn_dissipative_measured", "ekf", "ukf", "pf",
                                            "open_loop", "glf"};
    hinf::h5::Handle f = hinf::h5::open_file(d / "cmp/compare.h5", false);
    for (const auto& n : names) {
        CHECK(r.output.find(n) != std::string::npos);
        hinf::h5::Handle g = hinf::h5::open_group(f.get(), n);
        CHECK(hinf::h5::read_doubles(g.get(), "error_mean").size() == 6u);
    }
    std::ifstream csv(d / "cmp/compare.csv");
    std::string line;
    std::vector<std::string> lines;
    while (std::getline(csv, line)) lines.push_back(line);
    REQUIRE(lines.size() == names.size() + 1);
    CHECK(lines[0].rfind("scenario,filter,mode,runs,diverged_runs,x_mean,", 0) == 0);
    CHECK(lines[1].rfind("nominal,dnn_dissipative_oracle,oracle,3,", 0) == 0);
    CHECK(lines[3].rfind("nominal,ekf,measured,3,", 0) == 0);

    // --plot: PNGs drawn from compare.h5 alone (Debian's python3-h5py/-matplotlib, installed by scripts/setup);
    // scripts/plot also draws the training figure from trajectory.h5
    auto p = run_hinf("compare " + cfg + " --filters ekf,open_loop --runs 2 --quiet --plot --out " + (d / "plot"));
    INFO(p.output);
    REQUIRE(p.status == 0);
    CHECK(p.output.find("PNGs in") != std::string::npos);
    CHECK(p.output.find("RMSEpos5 ") != std::string::npos);  // the settled column named by settle_time (5 s)
    // a 0.05 s run has no step after 5 s: the state columns give the whole run's errors, and the header says so
    CHECK(p.output.find("errors x - x^ over the whole run (no step at or after t = 5 s)") != std::string::npos);
    CHECK(p.output.find("nan+-nan") == std::string::npos);
    auto st = run_hinf("compare " + cfg + " --filters ekf --runs 1 --quiet --set online.settle_time=0.02 --out " +
                       (d / "settle"));
    INFO(st.output);
    CHECK(st.output.find("RMSEpos0.02") != std::string::npos);
    CHECK(st.output.find("errors x - x^ after t = 0.02 s") != std::string::npos);
    CHECK(st.output.find("RMSEpos5") == std::string::npos);
    auto t2 = hinf::test::run_command("/usr/bin/python3 " + hinf::test::source_path("scripts/plot") + " " +
                                      (d / "run/trajectory.h5") + " --out " + (d / "plot"));
    INFO(t2.output);
    CHECK(t2.status == 0);
    for (const char* png : {"compare_trajectories.png", "compare_errors.png", "compare_errors_zoom.png", "training.png"}) {
        std::ifstream in(d / (std::string("plot/") + png), std::ios::binary);
        char magic[4] = {0, 0, 0, 0};
        in.read(magic, 4);
        INFO(png);
        CHECK(std::string(magic + 1, 3) == "PNG");
    }

    expect_one_line_error("compare " + cfg + " --filters ekf,kf", "unknown filter 'kf'");
    expect_one_line_error("compare " + cfg + " --filters glf --glf-vertices 0", "vertex count");
    expect_one_line_error("compare " + cfg + " --filters dnn", "needs --network");
    expect_one_line_error("compare " + cfg + " --filters ekf --scenario windy", "is not one of");
    expect_one_line_error("compare " + cfg + " --filters dnn --network " + net + " --mode both", "is not one of");
}
