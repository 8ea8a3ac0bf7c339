// A model that escapes under its own noise (the Henon map near the edge of its basin): its truth runs run away (out
// of the finite numbers, or 1e12 times beyond every scale the config gives them). Training draws from the runs that
// stay; compare and operate leave such runs out of every filter's figures and count them apart, instead of calling
// them every filter's divergence; the worst-case search scores them 0; a model every run of which escapes is refused
// in one line, and a continuous one whose Euler step runs away is told to take a shorter dt (where only some runs
// escape, the notes name the step beside the noise). (docs/compare.md "A
// truth that escapes", docs/method.md section 16.3.)
#include <catch2/catch.hpp>
#include <cmath>
#include <string>

#include "eval/compare.hpp"
#include "eval/worst.hpp"
#include "filters/ekf.hpp"
#include "filters/ukf.hpp"
#include "helpers.hpp"
#include "hinf/h5.hpp"
#include "sim/truth.hpp"
#include "train/gain_samples.hpp"

using namespace hinf;
using hinf::test::TempDir;

namespace {

// x_{k+1} = 1 - a x^2 + y + w1, y_{k+1} = b x + w2: with w of std 0.01 some runs of 200 steps leave the basin
RunConfig henon(const std::string& f0 = "1 - a*x^2 + y") {
    return load_run_config(ConfigDoc::from_text(
        "[system]\nkind = \"expr\"\ntime = \"discrete\"\nstates = [\"x\", \"y\"]\ndisturbances = 2\n"
        "measurements = 1\nf = [\"" + f0 + "\", \"b*x\"]\ng = [[\"1\", \"0\"], [\"0\", \"1\"]]\nh = [\"x\"]\n"
        "[system.parameters]\na = 1.4\nb = 0.3\n"
        "[filter]\nrho = 20\nx0 = [0.1, 0.1]\nxhat0 = [0.0, 0.0]\ndt = 1.0\nt_final = 200\n"
        "[online]\ndisturbance_std = 0.01\nnoise_std = 0.05\n",
        "henon.toml"));
}

}  // namespace

TEST_CASE("truth_escape_step finds the first step that runs away", "[sim][escape]") {
    TruthRun run;
    run.x = {1, 2, 3, 4, INFINITY, 6, 7, 8};  // 4 steps x 2 states: step 2 holds the inf
    run.y = {1, 2, 3, 4};
    CHECK(truth_escape_step(run, 2, 1, nullptr) == 2);
    run.x[4] = 5;
    CHECK(truth_escape_step(run, 2, 1, nullptr) == -1);
    const double bound[2] = {4.5, 100};  // beyond a bound: state 0 at step 2 (5 > 4.5)
    CHECK(truth_escape_step(run, 2, 1, bound) == 2);
    run.y[1] = NAN;  // a measurement alone
    CHECK(truth_escape_step(run, 2, 1, nullptr) == 1);
    // the bound: 1e12 times the config's scales, the noise-free run's included (the Henon attractor's |x| <= 1.3)
    const RunConfig cfg = henon();
    const std::vector<double> b = truth_escape_bound(cfg, cfg.steps_until());
    CHECK(b[0] > kTruthEscapeFactor * 1.0);
    CHECK(b[0] < kTruthEscapeFactor * 2.0);
}

TEST_CASE("training's truth pool leaves out the runs that escape and keeps the others", "[train][escape]") {
    const RunConfig cfg = henon();
    const GainPool pool = gain_pool_build(cfg);
    REQUIRE(pool.escaped > 0);  // the property the test stands on: some runs of this noise escape ...
    REQUIRE(pool.runs.size() > 0);  // ... and some stay
    CHECK(std::int64_t(pool.runs.size()) + pool.escaped == cfg.trajectories);
    CHECK(pool.first_escape >= 0);
    const std::vector<double> bound = truth_escape_bound(cfg, pool.steps);
    for (const TruthRun& r : pool.runs) CHECK(truth_escape_step(r, cfg.n, cfg.m, bound.data()) == -1);
    const std::string note = gain_pool_note(cfg, pool);
    CHECK(note.find(std::to_string(pool.escaped) + " of " + std::to_string(cfg.trajectories)) != std::string::npos);
    CHECK(note.find(truth_escape_cause(cfg)) != std::string::npos);
    CHECK(note.find("Euler") == std::string::npos);  // a map has no Euler step to blame
    // every run escapes: refused in one line that says what to change
    CHECK_THROWS_WITH(gain_pool_build(henon("2*x^2 + 1 + y")), Catch::Contains("ran away") &&
                                                                   Catch::Contains("lower the noise"));
}

TEST_CASE("compare counts a truth that escapes for no filter and says how many did", "[eval][compare][escape]") {
    const RunConfig cfg = henon();
    const FilterModel model = filter_model(cfg);
    auto ekf = make_ekf(model), ukf = make_ukf(model);
    TempDir d("compare-escape");
    CompareOptions opt;
    opt.out_dir = d / "c";
    opt.runs = 24;
    opt.quiet = true;
    const CompareSummary s = compare_run(cfg, {ekf.get(), ukf.get()}, opt);
    REQUIRE(s.truth_escaped_runs > 0);
    REQUIRE(s.truth_escaped_runs < opt.runs);
    h5::Handle f = h5::open_file(opt.out_dir + "/compare.h5", false);
    const std::vector<double> esc = h5::read_doubles(f.get(), "truth_escaped_at");
    REQUIRE(esc.size() == std::size_t(opt.runs));
    std::int64_t counted = 0;
    for (double e : esc) counted += e >= 0 ? 1 : 0;
    CHECK(counted == s.truth_escaped_runs);
    for (const char* name : {"ekf", "ukf"}) {
        h5::Handle g = h5::open_group(f.get(), name);
        const std::vector<double> at = h5::read_doubles(g.get(), "diverged_at");
        std::int64_t div = 0;
        for (std::size_t r = 0; r < at.size(); ++r) {
            if (esc[r] >= 0) CHECK(std::isnan(at[r]));  // not the filter's divergence
            else div += at[r] >= 0 ? 1 : 0;
        }
        CHECK(h5::get_attr_int(g.get(), "diverged_runs") == div);
        CHECK(h5::get_attr_int(g.get(), "kept_runs") == opt.runs - s.truth_escaped_runs - div);
    }
    for (const auto& fr : s.filters) CHECK(std::isfinite(fr.rmse_position));  // figures of the runs that stayed
}

TEST_CASE("a continuous model whose Euler step runs away is told to take a shorter dt", "[config][escape]") {
    // the Duffing oscillator x'' = -0.2 x' - x - 0.5 x^3 stepped by forward Euler with dt = 0.9 s: unstable
    const std::string text =
        "[system]\nkind = \"expr\"\nstates = [\"x\", \"v\"]\ndisturbances = 1\nmeasurements = 1\n"
        "f = [\"v\", \"-0.2*v - x - 0.5*x^3\"]\ng = [[\"0\"], [\"1\"]]\nh = [\"x\"]\n"
        "[filter]\nx0 = [1.5, 0.0]\nxhat0 = [1.0, 0.5]\ndt = DT\nt_final = 20\n"
        "[online]\ndisturbance_std = 0.3\nnoise_std = 0.05\n";
    auto with_dt = [&](const std::string& dt) {
        std::string t = text;
        t.replace(t.find("DT"), 2, dt);
        return load_run_config(ConfigDoc::from_text(t, "duffing.toml"));
    };
    const RunConfig bad = with_dt("0.9");
    CHECK(bad.rho <= 0);  // no default level ...
    CHECK_THAT(bad.rho_unset, Catch::Contains("leaves the finite numbers") && Catch::Contains("shorter [filter] dt"));
    const FilterModel model = filter_model(bad);
    auto ekf = make_ekf(model);
    TempDir d("compare-euler");
    CompareOptions opt;
    opt.out_dir = d / "c";
    opt.runs = 3;
    opt.quiet = true;
    CHECK_THROWS_WITH(compare_run(bad, {ekf.get()}, opt), Catch::Contains("shorter [filter] dt"));
    // where only some runs escape, train's, compare's and operate's notes name the step as a cause beside the noise
    const std::string cause = truth_escape_cause(bad);
    CHECK_THAT(cause, Catch::Contains("under its [online] noise") && Catch::Contains("step dt = 0.9 s") &&
                          Catch::Contains("shorter [filter] dt"));
    const RunConfig good = with_dt("0.01");  // ... and with a step the dynamics allow, one
    CHECK(good.rho > 0);
}

TEST_CASE("an escape begun at the horizon is seen by the look past it and scores nothing in the worst-case search",
          "[sim][worst][escape]") {
    const RunConfig cfg = henon();
    const std::int64_t K = cfg.steps_until();
    const std::vector<double> bound = truth_escape_bound(cfg, K);
    Signals s{std::vector<double>(std::size_t(K) * cfg.nv, 0.0), std::vector<double>(std::size_t(K) * cfg.m, 0.0)};
    std::int64_t at = -2;
    TruthRun quiet = truth_simulate_checked(cfg, Scenario{}, 0, K, bound.data(), &at, &s);
    CHECK(at == -1);  // the noise-free map stays on its attractor
    CHECK(quiet.x.size() == std::size_t(K) * cfg.n);  // cut back to the horizon
    s.v[std::size_t(K - 2) * cfg.nv] = 3.0;  // a kick in the last steps: x leaves the basin
    TruthRun kicked = truth_simulate_checked(cfg, Scenario{}, 0, K, bound.data(), &at, &s);
    for (double x : kicked.x) REQUIRE(std::isfinite(x));  // still finite within the horizon ...
    CHECK(truth_escape_step(kicked, cfg.n, cfg.m, bound.data()) == -1);
    CHECK(at >= K);  // ... and running away just past it
    const FilterModel model = filter_model(cfg);
    auto ekf = make_ekf(model);
    CHECK(std::isnan(worst_ratio(cfg, *ekf, s, K)));  // no filter's failure: the search's objective reads it as 0
    s.v[std::size_t(K - 2) * cfg.nv] = 0.01;
    CHECK(std::isfinite(worst_ratio(cfg, *ekf, s, K)));
}
