// Outputs that are angles ([system] angle_outputs, docs/formats.md): a difference of two bearings wraps into
// [-pi, pi], through any weighting of the outputs (noise_std lists, noise_cov), and a system without angles keeps
// the plain subtraction bit for bit; bad lists are refused in one line; across the +-pi cut of a radar's bearing the
// EKF, UKF and PF track with the key and the EKF loses the target without it; the gain variant's training samples
// see the wrapped difference.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "config/run_config.hpp"
#include "helpers.hpp"
#include "hinf/error.hpp"
#include "models/weighted_system.hpp"
#include "net/network.hpp"
#include "train/gain_samples.hpp"

using namespace hinf;
using hinf::test::run_hinf;
using hinf::test::TempDir;
using hinf::test::write_file;

namespace {

// a target moving down past the negative x axis, seen by a radar at the origin: its bearing crosses +-pi at step 15
std::string crossing(const std::string& angles, const std::string& online = "noise_std = [5.0, 0.005]\n") {
    return "[system]\nkind = \"expr\"\ntime = \"discrete\"\nstates = [\"px\", \"py\", \"vx\", \"vy\"]\n"
           "units = [\"m\", \"m\", \"m/s\", \"m/s\"]\ndisturbances = 2\nmeasurements = 2\n"
           "f = [\"px + vx\", \"py + vy\", \"vx\", \"vy\"]\n"
           "g = [[\"0.5\", \"0\"], [\"0\", \"0.5\"], [\"1\", \"0\"], [\"0\", \"1\"]]\n"
           "h = [\"sqrt(px^2 + py^2)\", \"atan2(py, px)\"]\n" + angles +
           "[filter]\nx0 = [-1000.0, 150.0, 0.0, -10.0]\nxhat0 = [-990.0, 140.0, 1.0, -9.0]\ndt = 1.0\nt_final = 40\n"
           "[online]\ndisturbance_std = 0.2\n" + online + "settle_time = 5\n";
}

using hinf::test::config_from_text;

// settled position RMSE per filter from compare.csv
std::vector<std::pair<std::string, double>> settled(const std::string& csv_path) {
    std::ifstream in(csv_path);
    std::string line;
    std::getline(in, line);
    std::vector<std::string> head;
    std::istringstream hs(line);
    for (std::string cell; std::getline(hs, cell, ',');) head.push_back(cell);
    std::size_t col = 0;
    while (col < head.size() && head[col] != "rmse_position_settled") ++col;
    REQUIRE(col < head.size());
    std::vector<std::pair<std::string, double>> out;
    while (std::getline(in, line)) {
        std::vector<std::string> cells;
        std::istringstream ls(line);
        for (std::string cell; std::getline(ls, cell, ',');) cells.push_back(cell);
        out.emplace_back(cells[1], std::stod(cells[col]));
    }
    return out;
}

}  // namespace

TEST_CASE("angle outputs: differences wrap into [-pi, pi] through any output weighting", "[angles]") {
    const double y[2] = {1000.0, 3.10}, c[2] = {990.0, -3.10};
    const double wrapped = 6.20 - 2.0 * M_PI;
    double r[2];
    SECTION("one noise std: the system itself") {
        const RunConfig cfg = config_from_text(crossing("angle_outputs = [2]\n", "noise_std = 5.0\n"));
        REQUIRE(cfg.system->angle_outputs() == std::vector<int>{1});
        cfg.system->output_difference(r, y, c);
        CHECK(r[0] == 10.0);
        CHECK(r[1] == Approx(wrapped).epsilon(1e-12));
        const RunConfig plain = config_from_text(crossing("", "noise_std = 5.0\n"));
        CHECK_FALSE(plain.system->wraps_outputs());
        plain.system->output_difference(r, y, c);
        CHECK(r[0] == y[0] - c[0]);
        CHECK(r[1] == y[1] - c[1]);  // bit for bit the subtraction
    }
    SECTION("noise std lists and a noise covariance: W wrap(y - c) in the user's units") {
        for (const char* online : {"noise_std = [5.0, 0.005]\n", "noise_cov = [[25.0, 0.01], [0.01, 2.5e-5]]\n"}) {
            const RunConfig cfg = config_from_text(crossing("angle_outputs = [2]\n", online));
            REQUIRE(cfg.system->wraps_outputs());
            const auto* ws = dynamic_cast<const WeightedSystem*>(cfg.system.get());
            REQUIRE(ws != nullptr);
            const std::vector<double>& W = ws->output_weight();  // lower triangular [2 x 2]
            const double yw[2] = {W[0] * y[0], W[2] * y[0] + W[3] * y[1]};
            const double cw[2] = {W[0] * c[0], W[2] * c[0] + W[3] * c[1]};
            cfg.system->output_difference(r, yw, cw);
            INFO(online);
            CHECK(r[0] == Approx(W[0] * 10.0).epsilon(1e-12));
            CHECK(r[1] == Approx(W[2] * 10.0 + W[3] * wrapped).epsilon(1e-9));
            // without the key the weighted difference is the plain subtraction, bit for bit
            const RunConfig plain = config_from_text(crossing("", online));
            plain.system->output_difference(r, yw, cw);
            CHECK(r[0] == yw[0] - cw[0]);
            CHECK(r[1] == yw[1] - cw[1]);
        }
    }
}

TEST_CASE("angle outputs: bad lists are refused in one line", "[angles]") {
    const char* bad[] = {"angle_outputs = [3]\n", "angle_outputs = [0]\n", "angle_outputs = [2, 2]\n"};
    for (const char* key : bad) {
        INFO(key);
        try {
            config_from_text(crossing(key));
            FAIL("accepted");
        } catch (const Error& e) {
            const std::string what = e.what();
            CHECK(what.find("angle_outputs") != std::string::npos);
            CHECK(what.find('\n') == std::string::npos);
        }
    }
}

TEST_CASE("angle outputs: the Bayesian filters track a target across the bearing's +-pi cut", "[angles][cli]") {
    TempDir d("angles");
    const std::string with = write_file(d, "with.toml", crossing("angle_outputs = [2]\n"));
    const std::string without = write_file(d, "without.toml", crossing(""));
    for (const std::string& cfg : {with, without}) {
        auto r = run_hinf("compare " + cfg + " --filters ekf,ukf,pf --runs 10 --quiet --out " +
                          (d / (cfg == with ? "with" : "without")));
        INFO(r.output);
        REQUIRE(r.status == 0);
    }
    // measured: 4.3 m for each filter with the key; the EKF 636 m without it (the bearing's 2 pi jump)
    for (const auto& [filter, rmse] : settled(d / "with/compare.csv")) {
        INFO(filter << " " << rmse);
        CHECK(rmse < 10.0);
    }
    for (const auto& [filter, rmse] : settled(d / "without/compare.csv"))
        if (filter == "ekf") CHECK(rmse > 30.0);
}

TEST_CASE("angle outputs: the gain variant's samples see the wrapped bearing difference", "[angles][gain]") {
    // errors sampled around estimates near the cut straddle it: without the key their bearing difference is near
    // 2 pi (in units of the bearing's noise, 0.005 rad: about 1257); with it, within pi of 0 there
    for (const bool angles : {true, false}) {
        const RunConfig cfg = config_from_text(crossing(angles ? "angle_outputs = [2]\n" : ""));
        const GainPool pool = gain_pool_build(cfg);
        const kern::GainSpec g = network_step_config(cfg).gain;
        GainSamples s;
        gain_samples_build(&s, cfg, pool, g, 4000, 0);
        double top = 0;
        for (std::int64_t i = 0; i < 4000; ++i) top = std::max(top, std::fabs(s.dC[i * 2 + 1]));
        INFO("angle_outputs " << angles << ": largest |bearing difference| " << top << " (noise units)");
        if (angles) CHECK(top <= M_PI / 0.005 + 1e-6);
        else CHECK(top > 1.5 * M_PI / 0.005);
    }
}
