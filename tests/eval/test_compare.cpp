// The comparison harness: every filter is fed the identical measurement stream (checked by recording
// and hashing it), results do not depend on the thread count, diverged filters are counted not dropped.
#include <catch2/catch.hpp>
#include <algorithm>
#include <map>
#include <mutex>
#include <sstream>
#include <fstream>
#include <omp.h>
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include "eval/compare.hpp"
#include "eval/engine.hpp"
#include "eval/filter_recorded.hpp"
#include "filters/dnn.hpp"
#include "helpers.hpp"
#include "hinf/h5.hpp"
#include "net/network.hpp"
#include "filters/ehf.hpp"
#include "filters/ekf.hpp"
#include "filters/open_loop.hpp"
#include "filters/pf.hpp"
#include "filters/ukf.hpp"

using namespace hinf;
using hinf::test::TempDir;

namespace {

RunConfig missile_config() {
    ConfigDoc doc = ConfigDoc::from_file(hinf::test::source_path("runs/missile_hinf.toml"));
    doc.set("network.hidden=[8]");
    return load_run_config(std::move(doc));
}

// Records every y it is given, per run (and can be told to diverge at a step). compare steps clones of it on
// several OpenMP threads at once, so the record the clones share is a map of runs behind a mutex: each run is
// stepped by one clone, and no two threads ever write one vector (a shared plain vector raced and made
// AddressSanitizer abort at random).
struct SpyRecord {
    std::mutex mutex;
    std::map<std::uint64_t, std::vector<double>> by_run;
};

class SpyFilter final : public OnlineFilter {
public:
    SpyFilter(std::string name, int m, std::int64_t diverge_at = -1)
        : name_(std::move(name)), m_(m), diverge_at_(diverge_at) {}
    std::string name() const override { return name_; }
    void reset(const FilterStart& s) override {
        xhat_ = s.xhat0;
        run_ = s.run;
        std::lock_guard<std::mutex> lock(record_->mutex);
        record_->by_run[run_].clear();
    }
    FilterStatus step(const FilterInput& in) override {
        {
            std::lock_guard<std::mutex> lock(record_->mutex);
            std::vector<double>& seen = record_->by_run[run_];
            seen.insert(seen.end(), in.y, in.y + m_);
        }
        if (in.step == diverge_at_) return FILTER_DIVERGED;
        return FILTER_OK;
    }
    const double* estimate() const override { return xhat_.data(); }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<SpyFilter>(*this); }
    // what run r was given (by whichever clone stepped it)
    std::vector<double> seen(std::uint64_t r) const {
        std::lock_guard<std::mutex> lock(record_->mutex);
        auto it = record_->by_run.find(r);
        return it == record_->by_run.end() ? std::vector<double>() : it->second;
    }

private:
    std::string name_;
    int m_;
    std::int64_t diverge_at_;
    std::vector<double> xhat_;
    std::uint64_t run_ = 0;
    std::shared_ptr<SpyRecord> record_ = std::make_shared<SpyRecord>();  // shared by clones, behind its mutex
};

}  // namespace

TEST_CASE("compare feeds every filter the identical measurement stream", "[eval][compare]") {
    RunConfig cfg = missile_config();
    TempDir d("compare-stream");
    FilterModel model = filter_model(cfg);
    auto ekf = make_ekf(model), pf = make_particle_filter(model, 50), ol = make_open_loop_filter(model);
    CompareOptions opt;
    opt.out_dir = d / "c";
    opt.runs = 3;
    opt.until = 0.2;
    opt.quiet = true;
    CompareSummary s = compare_run(cfg, {ekf.get(), pf.get(), ol.get()}, opt);
    REQUIRE(s.filters.size() == 3);
    for (const auto& f : s.filters) CHECK(f.stream_hash == s.truth_stream_hash);
    // the hash sees the noise: another online seed gives another stream
    RunConfig cfg2 = missile_config();
    cfg2.online_seed = 8;
    CompareSummary s2 = compare_run(cfg2, {ekf.get()}, opt);
    CHECK(s2.truth_stream_hash != s.truth_stream_hash);

    // independently of the harness's own hash: two spies record what they were fed (one run, so the one
    // clone of each spy sees the whole stream); it must be the measurements of run 0 stored in compare.h5
    SpyFilter a("spy_a", cfg.m), b("spy_b", cfg.m);
    opt.runs = 1;
    CompareSummary s1 = compare_run(cfg, {&a, &b}, opt);
    h5::Handle f = h5::open_file(opt.out_dir + "/compare.h5", false);
    std::vector<double> y = h5::read_doubles(f.get(), "y");
    REQUIRE(y.size() == 20u * cfg.m);
    CHECK(hinf::test::bitwise_equal(a.seen(0), y));
    CHECK(hinf::test::bitwise_equal(b.seen(0), y));
    const std::uint64_t hy = hash_bytes(hash_start, y.data(), y.size() * sizeof(double));
    CHECK(s1.truth_stream_hash == hash_bytes(hash_start, &hy, 8));
    CHECK(s1.filters[0].stream_hash == s1.truth_stream_hash);
}

TEST_CASE("compare results do not depend on the thread count", "[eval][compare][threads]") {
    RunConfig cfg = missile_config();
    TempDir d("compare-threads");
    FilterModel model = filter_model(cfg);
    std::unique_ptr<FrozenNetwork> net = network_freeze(network_create<float>(cfg));
    auto ekf = make_ekf(model), ukf = make_ukf(model), pf = make_particle_filter(model, 200),
         dnn_o = make_dnn_filter(model, *net, *make_hinf_gain_law(cfg.rho), false, "dnn_o"),
         dnn_m = make_dnn_filter(model, *net, *make_hinf_gain_law(cfg.rho), true, "dnn_m");
    std::vector<const OnlineFilter*> filters = {ekf.get(), ukf.get(), pf.get(), dnn_o.get(), dnn_m.get()};
    CompareOptions opt;
    opt.runs = 5;
    opt.until = 0.3;
    opt.quiet = true;
    std::vector<std::vector<double>> got[2];
    for (int threads : {1, 2}) {
        omp_set_num_threads(threads);
        opt.out_dir = d / ("t" + std::to_string(threads));
        CompareSummary s = compare_run(cfg, filters, opt);
        h5::Handle f = h5::open_file(opt.out_dir + "/compare.h5", false);
        for (const auto& fr : s.filters) {
            h5::Handle g = h5::open_group(f.get(), fr.name);
            for (const char* ds : {"error_mean", "error_std", "error_mean_t", "error_std_t", "xhat",
                                   "attenuation_ratio_per_run"})
                got[threads - 1].push_back(h5::read_doubles(g.get(), ds));
            got[threads - 1].push_back({fr.rmse_position, fr.attenuation_ratio, fr.mean_ci[0], fr.std_ci[5]});
        }
    }
    omp_set_num_threads(omp_get_num_procs());
    REQUIRE(got[0].size() == got[1].size());
    for (std::size_t i = 0; i < got[0].size(); ++i) {
        INFO("item " << i);
        CHECK(hinf::test::bitwise_equal(got[0][i], got[1][i]));
    }
}

TEST_CASE("compare counts a diverging filter and keeps it in the results", "[eval][compare]") {
    RunConfig cfg = missile_config();
    TempDir d("compare-div");
    SpyFilter ok("steady", cfg.m), bad("diverges", cfg.m, 3);
    CompareOptions opt;
    opt.out_dir = d / "c";
    opt.runs = 4;
    opt.until = 0.1;
    opt.quiet = true;
    CompareSummary s = compare_run(cfg, {&ok, &bad}, opt);
    REQUIRE(s.filters.size() == 2);
    CHECK(s.filters[0].diverged_runs == 0);
    CHECK(s.filters[1].diverged_runs == 4);
    CHECK(std::isnan(s.filters[1].rmse_position));  // no kept run: no statistics, not a made-up number
    h5::Handle f = h5::open_file(opt.out_dir + "/compare.h5", false);
    h5::Handle g = h5::open_group(f.get(), "diverges");
    std::vector<double> at = h5::read_doubles(g.get(), "diverged_at");
    REQUIRE(at.size() == 4u);
    for (double t : at) CHECK(t == Approx(3 * cfg.dt));
    // every run was recorded whole by the clone that stepped it (4 runs on several threads at once)
    for (std::uint64_t r = 0; r < 4; ++r) {
        CHECK(ok.seen(r).size() == std::size_t(10 * cfg.m));  // t < 0.1 s at dt = 0.01: 10 steps
        CHECK(bad.seen(r).size() == std::size_t(4 * cfg.m));  // frozen after its divergence at step 3
    }
}

namespace {
// A filter that never reports trouble while its estimate runs away (x^ multiplied by 10 each step): what an
// unstable model or a record on the wrong time base does. Only the plausible range can catch it.
class RunawayFilter final : public OnlineFilter {
public:
    std::string name() const override { return "runaway"; }
    void reset(const FilterStart& s) override {
        xhat_ = s.xhat0;
        for (double& v : xhat_) v = v == 0 ? 1 : v;
    }
    FilterStatus step(const FilterInput&) override {
        for (double& v : xhat_) v *= 10;
        return FILTER_OK;
    }
    const double* estimate() const override { return xhat_.data(); }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<RunawayFilter>(*this); }

private:
    std::vector<double> xhat_;
};
}  // namespace

TEST_CASE("an estimate that leaves the plausible range is reported as diverged", "[eval][compare][divergence]") {
    RunConfig cfg = missile_config();
    TempDir d("compare-runaway");
    SpyFilter ok("steady", cfg.m);
    RunawayFilter away;
    CompareOptions opt;
    opt.out_dir = d / "c";
    opt.runs = 2;
    opt.until = 0.1;
    opt.quiet = true;
    CompareSummary s = compare_run(cfg, {&ok, &away}, opt);
    REQUIRE(s.filters.size() == 2);
    CHECK(s.filters[0].diverged_runs == 0);  // an estimate that stays at x^0 is plausible
    CHECK(s.filters[1].diverged_runs == 2);
    // the range is 1000 x the system's own scale: |x^| grows 10x per step from x^0, so it leaves by step 3 or 4
    h5::Handle f = h5::open_file(opt.out_dir + "/compare.h5", false);
    h5::Handle g = h5::open_group(f.get(), "runaway");
    for (double t : h5::read_doubles(g.get(), "diverged_at")) CHECK(t <= 4 * cfg.dt + 1e-12);
    // the bound itself: 1000 x max(|x0|, |x^0|, sd0, |truth|) per state; the largest |y| for recorded data
    FilterStart start = engine_filter_start(cfg, 0);
    std::vector<double> b = plausible_bound(cfg, start, nullptr, nullptr, 0);
    for (int i = 0; i < cfg.n; ++i)
        CHECK(b[i] == Approx(kPlausibleFactor * std::max({std::fabs(cfg.x0[i]), std::fabs(cfg.xhat0[i]),
                                                          std::sqrt(start.P0[i * cfg.n + i])})));
    std::vector<double> y(cfg.m, 0.0);
    y[0] = 1e9;
    std::vector<double> by = plausible_bound(cfg, start, nullptr, y.data(), 1);
    for (int i = 0; i < cfg.n; ++i) CHECK(by[i] == Approx(kPlausibleFactor * 1e9));
}

namespace {
// A filter whose first state winds on by 10 a step (a phase on a long record), then, from step `bad`, is `last`.
class WindingFilter final : public OnlineFilter {
public:
    WindingFilter(std::int64_t bad, double last) : bad_(bad), last_(last) {}
    std::string name() const override { return "winding"; }
    void reset(const FilterStart& s) override { xhat_ = s.xhat0; }
    FilterStatus step(const FilterInput& in) override {
        xhat_[0] = in.step + 1 >= bad_ ? last_ : xhat_[0] + 10.0;
        return FILTER_OK;
    }
    const double* estimate() const override { return xhat_.data(); }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<WindingFilter>(*this); }

private:
    std::int64_t bad_;
    double last_;
    std::vector<double> xhat_;
};
}  // namespace

TEST_CASE("an angle state has no plausible range: a phase that winds far is not frozen, a non-finite one is",
          "[eval][compare][divergence][angle]") {
    const std::string text = test::phase_lock_system() + R"cfg([filter]
x0 = [0.0, 6.0]
xhat0 = [0.4, 5.5]
dt = 0.01
t_final = 20
[online]
disturbance_std = [0.05, 0.3]
noise_std = 0.1
)cfg";
    const std::int64_t K = 2000;  // the phase estimate reaches 2e4, 2e4 / 6 = 3300 times the largest scale
    const std::vector<double> y(K, 0.5), t(K, 0.0);
    std::string plain = text;
    plain.replace(plain.find("angle_states = [1]\n"), 19, "");
    for (const bool angle : {true, false}) {
        INFO("angle_states " << angle);
        const RunConfig cfg = test::config_from_text(angle ? text : plain);
        const FilterStart start = engine_filter_start(cfg, 0);
        const std::vector<double> bound = plausible_bound(cfg, start, nullptr, y.data(), K);  // hinf filter's
        CHECK(std::isfinite(bound[1]));
        CHECK((bound[0] == std::numeric_limits<double>::max()) == angle);
        for (const double last : {std::nan(""), double(INFINITY), -double(INFINITY)}) {
            WindingFilter winding(K, 0.0), broken(K / 2, last);
            winding.reset(start);
            broken.reset(start);
            const auto none = [](std::int64_t, const double*, bool) {};
            const StreamResult w =
                filter_stream(winding, y.data(), 1, t.data(), K, nullptr, 2, bound.data(), nullptr, none);
            const StreamResult b =
                filter_stream(broken, y.data(), 1, t.data(), K, nullptr, 2, bound.data(), nullptr, none);
            CHECK((w.diverged_at < 0) == angle);  // without the key the winding phase leaves its range
            CHECK(b.stepped <= K / 2);            // a non-finite phase is caught either way
        }
    }
}

namespace {
// A filter whose estimate sits a little off its start in every state, as a gain's first correction puts it.
class NudgedFilter final : public OnlineFilter {
public:
    std::string name() const override { return "nudged"; }
    void reset(const FilterStart& s) override {
        xhat_ = s.xhat0;
        for (double& v : xhat_) v += 1e-3;
    }
    FilterStatus step(const FilterInput&) override { return FILTER_OK; }
    const double* estimate() const override { return xhat_.data(); }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<NudgedFilter>(*this); }

private:
    std::vector<double> xhat_;
};
}  // namespace

TEST_CASE("a state with no scale has no plausible range: an estimate of it off zero is no divergence",
          "[eval][compare][divergence]") {
    // b is a constant that is 0 in the truth and in the start (a bias the sensor does not have): before, its range was
    // 1000 x 1e-300, and a DNN gain filter's first nudge of b counted as a divergence in every run
    const RunConfig cfg = test::config_from_text(R"([system]
kind = "expr"
states = ["a", "b"]
disturbances = 1
measurements = 1
f = ["-a + b", "0"]
g = [["1"], ["0"]]
h = ["a"]
[filter]
x0 = [1.0, 0.0]
xhat0 = [1.0, 0.0]
dt = 0.01
t_final = 0.2
[online]
disturbance_std = 0.2
noise_std = 0.1
)");
    const FilterStart start = engine_filter_start(cfg, 0);
    REQUIRE(start.P0[3] == 0);  // the premise: no initial spread in b either
    const std::vector<double> b = plausible_bound(cfg, start, nullptr, nullptr, 0);
    CHECK(b[0] == Approx(kPlausibleFactor * 1.0));
    CHECK(std::isinf(b[1]));
    TempDir d("compare-noscale");
    NudgedFilter nudged;
    CompareOptions opt;
    opt.out_dir = d / "c";
    opt.runs = 2;
    opt.quiet = true;
    CompareSummary s = compare_run(cfg, {&nudged}, opt);
    REQUIRE(s.filters.size() == 1);
    CHECK(s.filters[0].diverged_runs == 0);
}

TEST_CASE("compare scenarios: Student-t and biased measurement noise have the stated law", "[eval][compare]") {
    // n = y - C(x) from compare.h5 (run 0, 2000 steps x 6 channels). Median |n| / sigma_n: Gaussian 0.6745;
    // t_3 scaled to unit variance 0.7649 / sqrt(3) = 0.4416. With 12000 draws the sample median's standard
    // error is ~ 0.01, so the bands below are > 3 standard errors wide. Bias: mean n / sigma_n = 1 +- 0.03.
    RunConfig cfg = missile_config();
    TempDir d("compare-scen");
    SpyFilter spy("spy", cfg.m);
    for (const char* name : {"nominal", "student_t", "bias"}) {
        CompareOptions opt;
        opt.out_dir = d / name;
        opt.runs = 1;
        opt.until = 20.0;
        opt.quiet = true;
        opt.scenario = scenario_named(name);
        compare_run(cfg, {&spy}, opt);
        h5::Handle f = h5::open_file(opt.out_dir + "/compare.h5", false);
        std::vector<double> x = h5::read_doubles(f.get(), "x"), y = h5::read_doubles(f.get(), "y");
        const std::size_t steps = x.size() / cfg.n;
        std::vector<double> c(cfg.m), absn;
        double mean = 0;
        for (std::size_t s = 0; s < steps; ++s) {
            cfg.system->measurement(c.data(), x.data() + s * cfg.n, 0.0, 1);
            for (int j = 0; j < cfg.m; ++j) {
                const double nn = (y[s * cfg.m + j] - c[j]) / cfg.noise_std;
                absn.push_back(std::fabs(nn));
                mean += nn;
            }
        }
        mean /= double(absn.size());
        std::nth_element(absn.begin(), absn.begin() + absn.size() / 2, absn.end());
        const double med = absn[absn.size() / 2];
        INFO(name << ": median |n|/sigma = " << med << ", mean n/sigma = " << mean);
        if (std::string(name) == "student_t") CHECK((med > 0.40 && med < 0.48));
        else if (std::string(name) == "nominal") CHECK((med > 0.64 && med < 0.71));
        if (std::string(name) == "bias") CHECK(std::fabs(mean - 1.0) < 0.03);
        else CHECK(std::fabs(mean) < 0.03);
    }
    CHECK_THROWS_WITH(scenario_named("windy"), Catch::Contains("is not one of"));
}

TEST_CASE("the baselines are told the actual initial error in each state's units and no floor", "[eval][compare]") {
    const std::string text =
        "[system]\nkind = \"expr\"\nstates = [\"w1\", \"w2\"]\ndisturbances = 1\nmeasurements = 1\n"
        "f = [\"-w1*w2\", \"w1\"]\ng = [[\"1\"], [\"0\"]]\nh = [\"w1\"]\n"
        "[filter]\nrho = 2\nx0 = [1.0, 0.5]\nxhat0 = [0.8, 0.5]\ndt = 0.01\nt_final = 1\n"
        "[online]\ndisturbance_std = 0.1\nnoise_std = 0.1\n";
    const RunConfig small = load_run_config(ConfigDoc::from_text(text, "small.toml"));
    const std::vector<double> P0 = baseline_initial_covariance(small);
    REQUIRE(P0.size() == 4);
    CHECK(P0[0] == Approx(0.04).epsilon(1e-12));  // d = 0.2 rad/s: 0.04, not a floor of 1
    CHECK(P0[1] == 0.0);
    CHECK(P0[2] == 0.0);
    CHECK(P0[3] == 0.0);  // x0 = x^0: the start is exact there
    CHECK(engine_filter_start(small, 3).P0 == P0);
    CHECK_THAT(baseline_certain_note(small, P0), Catch::Contains("certain of w2") && !Catch::Contains("w1"));
    // an argument (hinf filter --initial-std, the library's initial_std) overrides the config, the config the default
    const std::vector<double> told = baseline_initial_covariance(small, {0.3, 0.1});
    CHECK(told[0] == Approx(0.09).epsilon(1e-12));
    CHECK(told[3] == Approx(0.01).epsilon(1e-12));
    CHECK(baseline_certain_note(small, told).empty());
    const RunConfig cfg_told =
        load_run_config(ConfigDoc::from_text(text + "[baseline]\ninitial_std = [0.5, 0.25]\n", "told.toml"));
    CHECK(baseline_initial_covariance(cfg_told)[3] == Approx(0.0625).epsilon(1e-12));
    CHECK_THROWS_WITH(baseline_initial_covariance(small, {0.1}), Catch::Contains("has 1 values, the system has 2"));
    // the missile's initial errors of 6-10 km and 300 m/s: the squares themselves
    const RunConfig missile = missile_config();
    const std::vector<double> Pm = baseline_initial_covariance(missile);
    for (int i = 0; i < missile.n; ++i) {
        const double d = missile.x0[i] - missile.xhat0[i];
        CHECK(Pm[std::size_t(i) * missile.n + i] == d * d);
    }
}

TEST_CASE("nees: the error against a covariance, NaN where the covariance is not positive definite", "[eval][compare]") {
    const double P[4] = {4.0, 0.0, 0.0, 1.0}, e[2] = {2.0, 1.0};
    CHECK(nees(P, e, 2) == Approx(2.0));  // 4/4 + 1/1
    const double Pc[4] = {2.0, 1.0, 1.0, 2.0}, ec[2] = {1.0, -1.0};
    CHECK(nees(Pc, ec, 2) == Approx(2.0));  // (1, -1) is an eigenvector of eigenvalue 1
    const double singular[4] = {1.0, 0.0, 0.0, 0.0}, indefinite[4] = {1.0, 0.0, 0.0, -1.0};
    CHECK(std::isnan(nees(singular, e, 2)));
    CHECK(std::isnan(nees(indefinite, e, 2)));
}

TEST_CASE("compare states each Bayesian filter's consistency and names an overconfident one", "[eval][compare]") {
    RunConfig cfg = missile_config();
    cfg.settle_time = 0;  // every step counts
    TempDir d("compare-nees");
    FilterModel model = filter_model(cfg);
    // the EKF told the true statistics is consistent; 50 particles on the missile (no process noise on the positions)
    // collapse; the open-loop predictor and the extended H-infinity filter state no error covariance
    auto ekf = make_ekf(model), pf = make_particle_filter(model, 50), ol = make_open_loop_filter(model),
         ehf = make_ehf(model, cfg.Q, cfg.rho);
    CompareOptions opt;
    opt.out_dir = d / "c";
    opt.runs = 3;
    opt.until = 1.0;
    opt.quiet = true;
    CompareSummary s = compare_run(cfg, {ekf.get(), pf.get(), ol.get(), ehf.get()}, opt);
    REQUIRE(s.filters.size() == 4);
    INFO("ekf " << s.filters[0].nees_per_state << ", pf " << s.filters[1].nees_per_state);
    CHECK(s.filters[0].nees_per_state > 0.3);
    CHECK(s.filters[0].nees_per_state < 3.0);
    CHECK(consistency_note(cfg, s.filters[0]).empty());
    CHECK(s.filters[1].nees_per_state > 100 * kOverconfidentNees);
    const std::string said = consistency_note(cfg, s.filters[1]);
    CHECK(said.rfind("note: pf: its settled errors are about ", 0) == 0);
    CHECK(said.find("--particles") != std::string::npos);
    CHECK(said.find("`hinf filter` would say so too") != std::string::npos);  // its NIS, 9696, shows it
    CHECK(std::isnan(s.filters[2].nees_per_state));
    CHECK(std::isnan(s.filters[3].nees_per_state));
    CHECK(consistency_note(cfg, s.filters[2]).empty());
    // the EKF's line names its own causes, not the particles
    CompareFilterResult ekf_over = s.filters[0];
    ekf_over.nees_per_state = 47.3;
    const std::string ekf_said = consistency_note(cfg, ekf_over);
    CHECK(ekf_said.rfind("note: ekf: its settled errors are about 6.88 times", 0) == 0);
    CHECK(ekf_said.find("--particles") == std::string::npos);
    CHECK(ekf_said.find("would pass unnoticed") != std::string::npos);  // its NIS, about 1, does not
    h5::Handle f = h5::open_file(opt.out_dir + "/compare.h5", false);
    h5::Handle g_ekf = h5::open_group(f.get(), "ekf"), g_ol = h5::open_group(f.get(), "open_loop");
    CHECK(h5::get_attr_double(g_ekf.get(), "nees_per_state") == s.filters[0].nees_per_state);
    CHECK_FALSE(h5::has_attr(g_ol.get(), "nees_per_state"));
    // the truth-free check on the same steps: the innovations against the covariance each filter expected for them
    INFO("NIS per output: ekf " << s.filters[0].nis_per_output << ", pf " << s.filters[1].nis_per_output);
    CHECK(s.filters[0].nis_per_output > 0.5);
    CHECK(s.filters[0].nis_per_output < 2.0);
    CHECK(s.filters[1].nis_per_output > 100);  // the collapsed cloud misjudges its innovations too (9696 here)
    CHECK(std::isnan(s.filters[2].nis_per_output));
    CHECK(std::isnan(s.filters[3].nis_per_output));
    CHECK(h5::get_attr_double(g_ekf.get(), "nis_per_output") == s.filters[0].nis_per_output);
    CHECK_FALSE(h5::has_attr(g_ol.get(), "nis_per_output"));
    // compare.csv: both figures by column name, nan for a filter that states no covariance
    std::ifstream csv(opt.out_dir + "/compare.csv");
    std::map<std::string, std::map<std::string, std::string>> rows;  // filter -> column -> cell
    std::string line, cell;
    std::vector<std::string> head;
    for (bool first = true; std::getline(csv, line); first = false) {
        std::vector<std::string> cells;
        std::istringstream in(line);
        while (std::getline(in, cell, ',')) cells.push_back(cell);
        if (first) head = cells;
        else
            for (std::size_t c = 0; c < cells.size() && c < head.size(); ++c) rows[cells[1]][head[c]] = cells[c];
    }
    CHECK(std::stod(rows["ekf"]["nees_per_state"]) == Approx(s.filters[0].nees_per_state).epsilon(1e-8));
    CHECK(std::stod(rows["ekf"]["nis_per_output"]) == Approx(s.filters[0].nis_per_output).epsilon(1e-8));
    CHECK(rows["open_loop"]["nees_per_state"] == "nan");
    CHECK(rows["open_loop"]["nis_per_output"] == "nan");
}

TEST_CASE("the recorded-data NIS note: beyond 3 or 1/3 and only over enough degrees of freedom", "[eval][nis]") {
    RecordedResult r;
    r.name = "ekf";
    r.nis_from = 2.0;
    CHECK(innovation_consistency_note(r).empty());  // NaN: no innovation covariance stated
    r.nis_dof = 100;
    r.nis_per_output = 9.0;  // innovations 3 times (RMS) what the filter expects
    const std::string over = innovation_consistency_note(r);
    CHECK(over.rfind("note: ekf: its innovations are about 3 times (RMS) what it expects (mean NIS per output 9 after "
                     "t = 2 s", 0) == 0);
    CHECK(over.find("overconfident") != std::string::npos);
    r.nis_per_output = 0.25;  // half
    const std::string under = innovation_consistency_note(r);
    CHECK(under.rfind("note: ekf: its innovations are about 2 times (RMS) smaller than it expects", 0) == 0);
    for (double q : {2.9, 0.34, 1.0}) {  // within the band
        r.nis_per_output = q;
        CHECK(innovation_consistency_note(r).empty());
    }
    r.nis_per_output = 9.0;
    r.nis_dof = 29;  // too few degrees of freedom to tell a filter from chance
    CHECK(innovation_consistency_note(r).empty());
    r.nis_dof = 30;
    CHECK_FALSE(innovation_consistency_note(r).empty());
}

TEST_CASE("compare and operate refuse a run directory in use before their runs, not after them", "[eval][compare][lock]") {
    TempDir d("lock-early");
    const std::string dir = d / "held";
    std::filesystem::create_directories(dir);
    // this process holds the directory as a running hinf would (io/run_lock.cpp: an flock on DIR/.hinf.lock)
    const int fd = ::open((dir + "/.hinf.lock").c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    REQUIRE(fd >= 0);
    REQUIRE(::flock(fd, LOCK_EX | LOCK_NB) == 0);
    // not --quiet: a refusal after the runs comes after their progress line ("compare 2/2 ... runs")
    const auto c = hinf::test::run_hinf("compare " + hinf::test::source_path("runs/missile_hinf.toml") +
                                        " --filters ekf --runs 2 --out " + dir);
    const std::string legacy = hinf::test::source_path("tests/corpus/legacy/gain_tv_mean");
    const auto o = hinf::test::run_hinf("operate " + legacy + ".toml --network " + legacy +
                                        "_full.h5 --runs 2 --mode measured --out " + dir);
    ::close(fd);
    for (const auto* r : {&c, &o}) {
        INFO(r->output);
        CHECK(r->status == 2);
        CHECK(r->output.find("is in use by another hinf process") != std::string::npos);
        CHECK(r->output.find(" runs |") == std::string::npos);  // no run was made
    }
    CHECK_FALSE(std::filesystem::exists(dir + "/compare.h5"));
    CHECK_FALSE(std::filesystem::exists(dir + "/operate.h5"));
}
