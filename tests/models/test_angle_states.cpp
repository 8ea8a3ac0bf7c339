// States that are angles ([system] angle_states, docs/formats.md): an error x - x^ or an offset of a sigma point or
// particle wraps into [-pi, pi], a system without angle states keeps the plain subtraction bit for bit, bad lists are
// refused in one line; on a body that spins, its heading wrapped by its own model, the UKF's and PF's means and every
// error statistic are right across the cut with the key and wrong without it.
#include <catch2/catch.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "config/run_config.hpp"
#include "eval/compare.hpp"
#include "filters/ekf.hpp"
#include "filters/pf.hpp"
#include "filters/ukf.hpp"
#include "helpers.hpp"

using namespace hinf;
using hinf::test::TempDir;

namespace {

// a heading th that turns by w each step and is wrapped by the map itself, seen through its cosine and sine
RunConfig spin(const std::string& key) {
    return load_run_config(ConfigDoc::from_text(
        "[system]\nkind = \"expr\"\ntime = \"discrete\"\nstates = [\"th\", \"w\"]\nunits = [\"rad\", \"rad/step\"]\n"
        "disturbances = 2\nmeasurements = 2\nf = [\"atan2(sin(th + w), cos(th + w))\", \"w\"]\n"
        "g = [[\"1\", \"0\"], [\"0\", \"1\"]]\nh = [\"cos(th)\", \"sin(th)\"]\n" + key +
        "[filter]\nx0 = [0.0, 0.3]\nxhat0 = [0.2, 0.25]\ndt = 1.0\nt_final = 100\n"
        "[online]\ndisturbance_std = [0.02, 0.001]\nnoise_std = 0.05\nsettle_time = 20\n"
        "[baseline]\ninitial_std = [0.3, 0.1]\n",
        "spin.toml"));
}

}  // namespace

TEST_CASE("state_difference wraps the angle states only and is a plain subtraction without them", "[model][angle]") {
    const RunConfig with = spin("angle_states = [1]\n"), without = spin("");
    const double a[4] = {3.1, 0.3, -3.0, 7.0}, b[4] = {-3.1, 0.1, 3.0, 1.0};
    double d[4];
    with.system->state_difference(d, a, b, 2);
    CHECK(d[0] == Approx(6.2 - 2 * M_PI).margin(1e-15));
    CHECK(d[1] == a[1] - b[1]);  // not an angle: as subtracted
    CHECK(d[2] == Approx(2 * M_PI - 6.0).margin(1e-15));
    CHECK(d[3] == a[3] - b[3]);
    without.system->state_difference(d, a, b, 2);
    for (int k = 0; k < 4; ++k) CHECK(d[k] == a[k] - b[k]);
    CHECK_THROWS_WITH(spin("angle_states = [3]\n"), Catch::Contains("angle_states"));
    CHECK_THROWS_WITH(spin("angle_states = [1, 1]\n"), Catch::Contains("twice"));
}

TEST_CASE("across the +-pi cut of a spinning heading the filters track with angle_states", "[filters][angle]") {
    // the heading turns by 0.3 rad a step, so it crosses the cut every 21 steps
    auto figures = [](const RunConfig& cfg, const std::string& dir) {
        const FilterModel model = filter_model(cfg);
        auto ekf = make_ekf(model), ukf = make_ukf(model), pf = make_particle_filter(model, 1000);
        CompareOptions opt;
        opt.out_dir = dir;
        opt.runs = 6;
        opt.quiet = true;
        return compare_run(cfg, {ekf.get(), ukf.get(), pf.get()}, opt);
    };
    TempDir d("angle-states");
    const CompareSummary with = figures(spin("angle_states = [1]\n"), d / "with");
    const CompareSummary without = figures(spin(""), d / "without");
    const double ekf = with.filters[0].rmse_position_settled;
    INFO("settled heading RMSE with the key: EKF " << ekf << ", UKF " << with.filters[1].rmse_position_settled
                                                   << ", PF " << with.filters[2].rmse_position_settled);
    CHECK(ekf < 0.1);  // the noise allows about 0.04 rad
    CHECK(with.filters[1].rmse_position_settled < 1.1 * ekf);
    CHECK(with.filters[2].rmse_position_settled < 1.2 * ekf);
    // without it an estimate on the other side of the cut counts 2 pi, and the UKF's mean of sigma points that
    // straddle it lands near 0
    INFO("without: EKF " << without.filters[0].rmse_position_settled << ", UKF "
                         << without.filters[1].rmse_position_settled);
    CHECK(without.filters[0].rmse_position_settled > 3 * ekf);
    CHECK(without.filters[1].rmse_position_settled > 5 * ekf);
}
