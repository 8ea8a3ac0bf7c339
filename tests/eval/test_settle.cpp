// The settled window's check (docs/compare.md, "Settled"): whether a filter's error is still falling after
// settle_time, where it settles, and the note `compare` and the acceptance check print when the config names no
// settle_time and the EKF is still falling in the default window.
#include <catch2/catch.hpp>
#include <cmath>
#include <string>
#include <vector>

#include "eval/compare.hpp"
#include "filters/ekf.hpp"
#include "helpers.hpp"
#include "hinf/config.hpp"

using namespace hinf;

TEST_CASE("settle_check finds a falling error and where it settles", "[eval][settle]") {
    std::vector<double> t(1000), decay(1000), flat(1000, 3.0);
    for (int k = 0; k < 1000; ++k) {
        t[k] = 0.1 * k;                                // 0 .. 99.9 s
        decay[k] = 1.0 + 100.0 * std::exp(-t[k] / 10);  // a transient of 10 s on a floor of 1
    }
    const SettleCheck d = settle_check(t, decay, 5.0);
    // first half of [5, 100): mean of 1 + 100 e^(-t/10) over [5, 52.5) about 1 + 100*0.60/4.75; second half about 1
    CHECK(d.halves > 10);
    // within twice the last quarter's level (about 1) from the first block (of 5 s) whose mean of 100 e^(-t/10) is
    // below 1: over [45, 50) it is 100 (e^-4.5 - e^-5) 10/5 = 0.87, over [40, 45) 1.44
    CHECK(d.settled_after == Approx(45.0));
    const SettleCheck f = settle_check(t, flat, 5.0);
    CHECK(f.halves == Approx(1.0));
    CHECK(f.settled_after == 0.0);
    // too few samples after t0 for halves, too few for blocks
    CHECK(std::isnan(settle_check(t, decay, 99.5).halves));
    const std::vector<double> t30(t.begin(), t.begin() + 30), d30(decay.begin(), decay.begin() + 30);
    CHECK(std::isnan(settle_check(t30, d30, 0.0).settled_after));
    CHECK(std::isfinite(settle_check(t30, d30, 0.0).halves));
    // an error of 0 in the second half: no ratio
    std::vector<double> zero(1000, 0.0);
    CHECK(std::isnan(settle_check(t, zero, 5.0).halves));
}

namespace {

// A constant measured through heavy noise from a wrong start: the EKF's variance falls like 1/t, still falling
// long after the default settle_time of 5 s
std::string slow_config(const std::string& extra = "") {
    return R"([system]
kind = "expr"
states = ["c"]
disturbances = 1
measurements = 1
f = ["0"]
g = [["1"]]
h = ["c"]
[filter]
rho = 2.0
x0 = [1.0]
xhat0 = [3.0]
dt = 0.1
t_final = 100
[online]
disturbance_std = 0.0001
noise_std = 1.0
)" + extra;
}

}  // namespace

TEST_CASE("compare notes an EKF still falling in the default settled window", "[eval][settle]") {
    test::TempDir d("settle");
    const RunConfig cfg = load_run_config(ConfigDoc::from_text(slow_config(), "slow.toml"));
    const FilterModel model = filter_model(cfg);
    auto ekf = make_ekf(model);
    CompareOptions opt;
    opt.out_dir = d / "c";
    opt.runs = 8;
    opt.quiet = true;
    const CompareSummary s = compare_run(cfg, {ekf.get()}, opt);
    REQUIRE(s.filters.size() == 1);
    CHECK(s.filters[0].settle_halves > kSettleFactor);
    CHECK(s.filters[0].settled_after > cfg.settle_time);
    const std::string note = settle_note(cfg, s, "compare");
    CHECK_THAT(note, Catch::StartsWith("compare: note: the EKF's error is still falling after t = 5 s"));
    CHECK_THAT(note, Catch::Contains("--set online.settle_time="));

    // the config names the window (even the same 5 s): the user's choice, no note
    const RunConfig named = load_run_config(ConfigDoc::from_text(slow_config("settle_time = 5\n"), "slow.toml"));
    CHECK(settle_note(named, s, "compare").empty());
    // no reference filter (ekf, ukf or pf) among those compared: no note
    CompareSummary other = s;
    other.filters[0].name = "dnn_gain_measured";
    CHECK(settle_note(cfg, other, "compare").empty());
    // settled: no note
    CompareSummary settled = s;
    settled.filters[0].settle_halves = 1.5;
    CHECK(settle_note(cfg, settled, "acceptance").empty());
}
