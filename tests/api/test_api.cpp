// The public facade (include/hinf/hinf.hpp): training through the library with a progress callback, filters by
// name giving `hinf filter`'s bits on the same record, step() against run(), and bad use as one-line hinf::Error.
// (python/tests covers the same through the Python module; this runs under the sanitizers too.)
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <iterator>
#include <sstream>

#include "helpers.hpp"
#include "hinf/h5.hpp"
#include "hinf/hinf.hpp"

using hinf::test::one_line_error;
using hinf::test::run_hinf;
using hinf::test::TempDir;
using hinf::test::write_file;

namespace {

// the one line a library call's bad argument gives, "" when it gives none; it names the library's argument, never
// the program's flag (the checks behind compare and worst are shared with the program)
std::string library_error(const std::function<void()>& call) {
    try {
        call();
    } catch (const hinf::Error& e) {
        return e.what();
    }
    return "";
}
bool names_argument(const std::string& what, const std::string& fragment) {
    INFO(what);
    return what.find(fragment) != std::string::npos && what.find("--") == std::string::npos &&
           what.find('\n') == std::string::npos;
}

const char* kTinyMissile =
    "[system]\nkind = \"missile\"\n[filter]\nt_final = 2.0\n[network]\nhidden = [8]\n[training]\nsamples = 50\n"
    "batch = 20\nadam_steps = 2\ncheckpoint_every = 3\n";

// a noisy record of the config's own system, and its CSV (17 digits: the same doubles)
void simulate(const hinf::Config& cfg, std::int64_t K, std::vector<double>* t, std::vector<double>* y,
              std::string* csv) {
    const int m = cfg.outputs();
    std::vector<double> x = cfg.initial_state();
    std::ostringstream out;
    out.precision(17);
    for (std::int64_t k = 0; k < K; ++k) {
        const double tk = 1.5 + double(k) * cfg.dt();
        std::vector<double> c = cfg.measure(x, tk);
        t->push_back(tk);
        out << tk;
        for (int j = 0; j < m; ++j) {
            y->push_back(c[j] + 20.0 * std::sin(0.7 * double(k * m + j)));  // deterministic "noise"
            out << ',' << y->back();
        }
        out << '\n';
        x = cfg.advance(x, {5.0 * std::cos(0.3 * double(k))}, tk, cfg.dt());
    }
    *csv = out.str();
}

}  // namespace

TEST_CASE("library: train with a callback, then every filter gives hinf filter's bits", "[api]") {
    TempDir d("api");
    const std::string path = write_file(d, "tiny.toml", kTinyMissile);
    const hinf::Config cfg = hinf::Config::load(path);
    REQUIRE(cfg.states() == 6);
    REQUIRE(cfg.system() == "missile");

    hinf::TrainSettings s;
    s.out_dir = d / "run";
    s.until = 0.06;
    std::vector<std::int64_t> steps;
    s.on_progress = [&](const hinf::TrainProgress& p) { steps.push_back(p.step); };
    const hinf::TrainReport r = hinf::train(cfg, s);
    CHECK_FALSE(r.diverged);
    CHECK(r.last_step == 6);
    CHECK(steps == std::vector<std::int64_t>{1, 2, 3, 4, 5, 6});

    std::vector<double> t, y;
    std::string csv;
    simulate(cfg, 120, &t, &y, &csv);
    const std::string record = write_file(d, "record.csv", csv);
    auto cli = run_hinf("filter " + path + " --network " + r.checkpoint + " --measurements " + record +
                        " --filters dnn,ekf,ukf,pf,open_loop --particles 200 --quiet --out " + (d / "flt"));
    INFO(cli.output);
    REQUIRE(cli.status == 0);

    hinf::FilterOptions o;
    o.networks = {hinf::TrainedNetwork::load(r.checkpoint)};
    o.particles = 200;
    std::vector<hinf::Filter> filters = hinf::Filter::create_all(cfg, "dnn,ekf,ukf,pf,open_loop", o);
    REQUIRE(filters.size() == 5);
    hinf::h5::Handle f = hinf::h5::open_file(d / "flt/estimates.h5", false);
    for (hinf::Filter& filter : filters) {
        INFO(filter.name());
        const hinf::FilterTrace tr = filter.run(t, y);
        hinf::h5::Handle g = hinf::h5::open_group(f.get(), filter.name());
        CHECK(hinf::test::bitwise_equal(tr.xhat, hinf::h5::read_doubles(g.get(), "xhat")));
        CHECK(hinf::test::bitwise_equal(tr.innovation, hinf::h5::read_doubles(g.get(), "innovation")));
        CHECK(hinf::test::bitwise_equal(tr.xhat_final, hinf::h5::read_doubles(g.get(), "xhat_final")));
        if (filter.has_covariance())
            CHECK(hinf::test::bitwise_equal(tr.covariance, hinf::h5::read_doubles(g.get(), "P")));
        // one step at a time: the record's interval is the config's dt here up to its last bit, so to round-off
        filter.reset();
        for (std::size_t k = 0; k < t.size(); ++k) {
            const std::vector<double> xh = filter.estimate();
            for (int i = 0; i < 6; ++i)
                CHECK(xh[i] == Approx(tr.xhat[k * 6 + i]).epsilon(1e-9).margin(1e-9));
            filter.step(&y[k * 6], t[k]);
        }
    }
}

TEST_CASE("library: bad use throws hinf::Error with one line", "[api]") {
    TempDir d("api-bad");
    const hinf::Config cfg = hinf::Config::from_text(kTinyMissile, "tiny.toml");
    CHECK(one_line_error([&] { hinf::Config::load(d / "missing.toml"); }, "missing.toml"));
    CHECK(one_line_error([&] { hinf::Config::from_text("[filter]\nrho = -1\n", "bad.toml"); }, "rho"));
    CHECK(one_line_error([&] { hinf::Filter::create(cfg, "kalman"); }, "unknown filter 'kalman'"));
    CHECK(one_line_error([&] { hinf::Filter::create(cfg, "dnn"); }, "needs a trained network"));
    CHECK(one_line_error([&] { hinf::Filter::create(cfg, "ekf,ukf"); }, "use create_all"));
    hinf::Filter ekf = hinf::Filter::create(cfg, "ekf");
    CHECK(one_line_error([&] { ekf.step(std::vector<double>(3, 0.0), 0.0); }, "has 3 values, expected 6"));
    CHECK(one_line_error([&] { ekf.run({0.0, 0.01}, std::vector<double>(6, 0.0)); }, "expected times x outputs = 12"));
    CHECK(one_line_error([&] { ekf.run({0.0, 0.0}, std::vector<double>(12, 0.0)); }, "time must increase strictly"));
    CHECK(one_line_error([&] { hinf::TrainedNetwork::load(d / "missing.h5"); }, "missing.h5"));
    CHECK(one_line_error([&] { hinf::train(cfg, hinf::TrainSettings{}); }, "out_dir is required"));
    // a network trained for another system with the same state count
    const hinf::Config other = hinf::Config::from_text(
        "[system]\nkind = \"expr\"\nstates = [\"a\", \"b\", \"c\", \"d\", \"e\", \"f\"]\nmeasurements = 6\n"
        "f = [\"-a\", \"-b\", \"-c\", \"-d\", \"-e\", \"-f\"]\ng = [[\"1\"], [\"0\"], [\"0\"], [\"0\"], [\"0\"], [\"0\"]]\n"
        "h = [\"a\", \"b\", \"c\", \"d\", \"e\", \"f\"]\n[filter]\nQ = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0]\nx0 = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0]\n"
        "xhat0 = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\ndt = 0.01\nt_final = 0.02\n[network]\nhidden = [4]\n[training]\nsamples = 20\nbatch = 10\n"
        "adam_steps = 1\ncheckpoint_every = 1\n[online]\ndisturbance_std = 1\nnoise_std = 1\n",
        "other.toml");
    hinf::TrainSettings s;
    s.out_dir = d / "other";
    REQUIRE_FALSE(hinf::train(other, s).diverged);
    hinf::FilterOptions o;
    o.networks = {hinf::TrainedNetwork::load(d / "other/checkpoint.h5")};
    CHECK(one_line_error([&] { hinf::Filter::create(cfg, "dnn", o); }, "was trained for the system 'expr'"));
    CHECK(one_line_error([&] { hinf::train(other, s); }, "already holds a run"));
    // export: several checkpoints need ensemble = true; an ensemble member of another model is refused
    const std::string ck = d / "other/checkpoint.h5";
    CHECK(one_line_error([&] { hinf::export_c99({ck, ck}, d / "c"); }, "ensemble=True from the library"));
    CHECK(one_line_error([&] { hinf::export_c99({ck}, d / "c", "hinf_filter", true); }, "two or more networks"));
}

TEST_CASE("library: export_c99 writes the files hinf export writes", "[api][export]") {
    TempDir d("api-export");
    const hinf::Config cfg = hinf::Config::from_text(
        "[system]\nkind = \"expr\"\nstates = [\"a\", \"b\"]\nmeasurements = 1\nf = [\"b\", \"-a - 0.5*b\"]\n"
        "g = [[\"0\"], [\"1\"]]\nh = [\"a\"]\n[filter]\nQ = [1.0, 1.0]\nx0 = [1.0, 0.0]\nxhat0 = [0.0, 0.0]\ndt = 0.01\n"
        "t_final = 0.05\n[network]\nhidden = [4]\n[training]\nsamples = 20\nbatch = 10\nadam_steps = 1\n"
        "checkpoint_every = 5\n[online]\ndisturbance_std = 1\nnoise_std = 1\n",
        "osc.toml");
    hinf::TrainSettings s;
    s.out_dir = d / "run";
    REQUIRE_FALSE(hinf::train(cfg, s).diverged);
    const std::string ck = d / "run/checkpoint.h5";
    const hinf::ExportReport r = hinf::export_c99({ck, ck}, d / "lib", "osc", true);
    CHECK(r.networks == 2);
    CHECK(r.variant == "gain");
    CHECK(r.files == std::vector<std::string>{d / "lib/osc.h", d / "lib/osc.c"});
    auto e = run_hinf("export " + ck + " " + ck + " --ensemble --name osc --c " + (d / "cli"));
    INFO(e.output);
    REQUIRE(e.status == 0);
    for (const char* name : {"osc.h", "osc.c"}) {
        std::ifstream a(d / (std::string("lib/") + name)), b(d / (std::string("cli/") + name));
        const std::string ta((std::istreambuf_iterator<char>(a)), std::istreambuf_iterator<char>());
        const std::string tb((std::istreambuf_iterator<char>(b)), std::istreambuf_iterator<char>());
        CHECK(!ta.empty());
        CHECK(ta == tb);
    }
}

TEST_CASE("library: a gain run keeps its best validated checkpoint and ends with the acceptance check, as hinf train",
          "[api][select][acceptance]") {
    TempDir d("apiselect");
    const std::string path = write_file(d, "vdp.toml", hinf::test::tiny_vdp_gain_config("0.3", "select_runs = 2\n"));
    const hinf::Config cfg = hinf::Config::load(path);
    hinf::TrainSettings s;
    s.out_dir = d / "run";
    s.until = 0.15;  // stopped before t_final: a selection so far, no acceptance check
    hinf::TrainReport r = hinf::train(cfg, s);
    REQUIRE_FALSE(r.diverged);
    CHECK(r.acceptance.empty());
    s.until = -1;
    r = hinf::resume(r.checkpoint, s);  // continues the selection, then the check at t_final
    REQUIRE_FALSE(r.diverged);
    REQUIRE(r.best_checkpoint == d / "run/best.h5");
    CHECK(r.best_step > 0);
    CHECK(r.best_step % 10 == 0);  // validated checkpoints only (checkpoint_every = 10)
    CHECK(r.knot_runaway_step == -1);  // no knot ran away (tests/train/test_gain_scaling.cpp has one that does)
    CHECK(r.knot_runaway_knot == -1);
    REQUIRE((r.acceptance == "pass" || r.acceptance == "fail"));
    CHECK(r.acceptance_checkpoint == r.best_checkpoint);
    CHECK(r.acceptance_line.rfind("acceptance (5 measured runs", 0) == 0);
    CHECK(std::isfinite(r.acceptance_rmse_settled));  // the check's runs against the EKF (outside the verdict)
    CHECK(std::isfinite(r.acceptance_rmse_settled_ekf));
    CHECK(std::isfinite(r.acceptance_rms_q_settled));  // all states, Q-weighted
    CHECK(r.acceptance_rms_q_settled_ekf > 0);
    CHECK(r.acceptance_line.find(" against the EKF's ") != std::string::npos);
    hinf::h5::Handle f = hinf::h5::open_file(r.best_checkpoint, false);
    CHECK(hinf::h5::get_attr_string(f.get(), "acceptance_verdict") == r.acceptance);
    CHECK(hinf::h5::get_attr_int(f.get(), "select_step") == r.best_step);
    // the program gives the same selection and verdict for the same config in one run
    auto cli = run_hinf("train " + path + " --out " + (d / "cli") + " --quiet");
    INFO(cli.output);
    REQUIRE(cli.status == 0);
    hinf::h5::Handle g = hinf::h5::open_file(d / "cli/best.h5", false);
    CHECK(hinf::h5::get_attr_int(g.get(), "select_step") == r.best_step);
    CHECK(hinf::h5::get_attr_string(g.get(), "acceptance_verdict") == r.acceptance);
    CHECK(cli.output.find(r.acceptance_line.substr(0, 60)) != std::string::npos);
}

TEST_CASE("library: constant_storage_violation says what hinf rho says about a discrete system's storage", "[api]") {
    // the coordinated turn: no constant storage (docs/method.md section 16.8); the radar: one; continuous: nothing
    const hinf::Config turn = hinf::Config::load(hinf::test::source_path("examples/systems/coordinated_turn.toml"));
    CHECK(turn.constant_storage_violation() > 0.05);
    const hinf::Config radar = hinf::Config::load(hinf::test::source_path("examples/systems/radar.toml"));
    CHECK(radar.constant_storage_violation() <= 0);
    CHECK(std::isnan(hinf::Config::from_text(kTinyMissile, "tiny.toml").constant_storage_violation()));
}

TEST_CASE("library: unseen_share says what hinf rho says about the states the outputs tell nothing about", "[api]") {
    // the DC motor's encoder: the current's effect on the angle is masked by the disturbance on the speed (0.95 when
    // written); Van der Pol's position sensor sees the velocity
    const hinf::Config motor = hinf::Config::load(hinf::test::source_path("examples/systems/dc_motor.toml"));
    const std::vector<double> m = motor.unseen_share();
    REQUIRE(m.size() == 3u);
    CHECK(m[0] < 0.1);
    CHECK(m[2] >= 0.9);
    for (double r : hinf::Config::load(hinf::test::source_path("runs/vanderpol.toml")).unseen_share()) CHECK(r < 0.1);
}

TEST_CASE("library: a config's known inputs, by name and value, as f reads them", "[api][inputs]") {
    const hinf::Config motor = hinf::Config::load(hinf::test::source_path("examples/systems/dc_motor_recorded.toml"));
    CHECK(motor.input_names() == std::vector<std::string>{"V"});
    CHECK(motor.inputs_at(1.5) == std::vector<double>{-6.3});  // examples/systems/dc_motor_voltage.csv, held
    CHECK(motor.inputs_at(20.0) == std::vector<double>{-12.0});  // the last row
    CHECK(motor.advance({0.0, 0.0, 0.0}, {}, 1.5, 0.01)[2] == Approx(0.01 * -6.3 / 0.5).epsilon(1e-15));
    CHECK(hinf::Config::from_text(kTinyMissile, "tiny.toml").input_names().empty());
    CHECK(hinf::Config::from_text(kTinyMissile, "tiny.toml").inputs_at(0.0).empty());
    // another run's inputs (a record's, on its own times) in place of the table: u(t) and the filters follow them
    const std::vector<double> t = {0.5, 1.0, 1.5, 2.0}, v = {3.0, 4.0, 5.0, 6.0};
    const hinf::Config rec = motor.with_inputs(t, v);
    CHECK(rec.inputs_at(1.2) == std::vector<double>{4.0});
    CHECK(rec.inputs_at(0.0) == std::vector<double>{3.0});  // before the first row: the first row holds
    CHECK(rec.input_names() == motor.input_names());
    CHECK(motor.inputs_at(1.5) == std::vector<double>{-6.3});  // the config it came from is unchanged
    std::vector<double> tk, y;
    for (int k = 0; k < 100; ++k) {
        tk.push_back(0.5 + 0.01 * k);
        y.push_back(0.1 * k * 0.01);
    }
    hinf::FilterOptions o;
    const hinf::FilterTrace a = hinf::Filter::create(motor, "ekf", o).run(tk, y);
    const hinf::FilterTrace b = hinf::Filter::create(rec, "ekf", o).run(tk, y);
    REQUIRE(a.xhat.size() == b.xhat.size());
    CHECK(a.xhat != b.xhat);
    for (int k = 100; k < 201; ++k) {  // a record beyond the table (to 2.5 s) is refused by run
        tk.push_back(0.5 + 0.01 * k);
        y.push_back(0.0);
    }
    CHECK_THROWS_WITH(hinf::Filter::create(rec, "ekf", o).run(tk, y), Catch::Contains("beyond its table of known inputs"));
    hinf::TrainSettings settings;
    settings.out_dir = "/nonexistent/never-written";
    CHECK_THROWS_WITH(hinf::train(rec, settings), Catch::Contains("covers [0.5, 2] s, the run needs [0, 20] s"));
    CHECK_THROWS_WITH(motor.with_inputs({0.0, 1.0}, {1.0}), Catch::Contains("with_inputs: the values"));
    CHECK_THROWS_WITH(motor.with_inputs({1.0, 0.5}, {1.0, 2.0}), Catch::Contains("not after the row before it"));
    CHECK_THROWS_WITH(hinf::Config::from_text(kTinyMissile, "tiny.toml").with_inputs({0.0, 1.0}, {1.0, 2.0}),
                      Catch::Contains("has no known inputs"));
}

TEST_CASE("library: a Filter is told the P0 hinf filter tells it (options, then [baseline] initial_std, then the error)",
          "[api]") {
    const std::string text =
        "[system]\nkind = \"expr\"\nstates = [\"w1\", \"w2\"]\ndisturbances = 1\nmeasurements = 1\n"
        "f = [\"-w1*w2\", \"w1\"]\ng = [[\"1\"], [\"0\"]]\nh = [\"w1\"]\n"
        "[filter]\nrho = 2\nx0 = [1.0, 0.5]\nxhat0 = [0.8, 0.5]\ndt = 0.01\nt_final = 1\n"
        "[online]\ndisturbance_std = 0.1\nnoise_std = 0.1\n";
    auto p0 = [](const hinf::Config& cfg, const std::vector<double>& sd) {
        hinf::FilterOptions o;
        o.initial_std = sd;
        return hinf::Filter::create(cfg, "ekf", o).covariance();  // before any step: P0
    };
    const hinf::Config plain = hinf::Config::from_text(text);
    std::vector<double> P = p0(plain, {});
    REQUIRE(P.size() == 4u);
    CHECK(P[0] == Approx(0.04).epsilon(1e-12));  // (x0 - x^0)^2 of w1, no floor of 1
    CHECK(P[3] == 0.0);                           // w2 starts known
    const hinf::Config told = hinf::Config::from_text(text + "[baseline]\ninitial_std = [0.5, 0.25]\n");
    P = p0(told, {});  // the config's initial_std, which Filter::create ignored before 2026-11-30
    CHECK(P[0] == Approx(0.25).epsilon(1e-12));
    CHECK(P[3] == Approx(0.0625).epsilon(1e-12));
    P = p0(told, {0.1, 0.2});  // the option over the config
    CHECK(P[0] == Approx(0.01).epsilon(1e-12));
    CHECK(P[3] == Approx(0.04).epsilon(1e-12));
}

TEST_CASE("library: compare runs hinf compare's Monte Carlo and returns its table", "[api]") {
    TempDir d("api-compare");
    const hinf::Config cfg = hinf::Config::from_text(kTinyMissile, "tiny.toml");
    hinf::CompareSettings s;
    s.out_dir = d / "cmp";
    s.filters = "ekf,ukf,open_loop";
    s.runs = 2;
    const hinf::CompareReport r = hinf::compare(cfg, s);
    CHECK(r.file == d / "cmp/compare.h5");
    CHECK(std::ifstream(r.file).good());
    CHECK(r.runs == 2);
    CHECK(r.steps == 200);
    CHECK(r.streams_identical);
    REQUIRE(r.filters.size() == 3u);
    CHECK(r.filters[0].name == "ekf");
    CHECK(r.filters[2].name == "open_loop");
    for (const auto& f : r.filters) CHECK(std::isfinite(f.rmse_position));
    // told the true statistics, the EKF tracks; the open loop does not
    CHECK(r.filters[0].rmse_position < r.filters[2].rmse_position);
    s.runs = 0;
    CHECK(one_line_error([&] { hinf::compare(cfg, s); }, "runs must be >= 1"));
    s.runs = 1;
    s.filters = "kalman";
    CHECK(one_line_error([&] { hinf::compare(cfg, s); }, "kalman"));
    s.filters = "dnn";
    CHECK(one_line_error([&] { hinf::compare(cfg, s); }, "network"));
    // the shared checks name the library's arguments
    CHECK(names_argument(library_error([&] { hinf::compare(cfg, s); }), "filters dnn needs a trained network in networks"));
    s.filters = "kalman";
    CHECK(names_argument(library_error([&] { hinf::compare(cfg, s); }), "filters: unknown filter 'kalman'"));
    s.filters = "ekf";
    s.scenario = "storm";
    CHECK(names_argument(library_error([&] { hinf::compare(cfg, s); }), "scenario 'storm' is not one of"));
    s.scenario = "nominal";
    s.ensemble = true;
    CHECK(names_argument(library_error([&] { hinf::compare(cfg, s); }), "ensemble averages DNN filters: add dnn to filters"));
}

TEST_CASE("library: worst runs hinf worst's search and returns each filter's worst", "[api]") {
    TempDir d("api-worst");
    const hinf::Config cfg = hinf::Config::from_text(kTinyMissile, "tiny.toml");
    hinf::WorstSettings s;
    s.out_dir = d / "worst";
    s.filters = "ekf,open_loop";
    s.until = 0.5;
    s.evals = 6;
    s.random_starts = 1;
    s.linear_pieces = 2;
    const hinf::WorstReport r = hinf::worst(cfg, s);
    CHECK(r.file == d / "worst/worst.h5");
    CHECK(std::ifstream(r.file).good());
    CHECK(r.steps == 50);
    CHECK(r.energy > 0);
    REQUIRE(r.filters.size() == 2u);
    CHECK(r.filters[0].name == "ekf");
    for (const auto& f : r.filters) {
        CHECK(f.ratio > 0);
        CHECK_FALSE(f.found_from.empty());
    }
    // its signals replayed against another filter set: each set scores its own filter as the search did
    hinf::WorstSettings rs;
    rs.out_dir = d / "replay";
    rs.filters = "ukf,ekf";
    const hinf::ReplayReport p = hinf::replay_worst(cfg, r.file, rs);
    CHECK(p.file == d / "replay/replay.h5");
    CHECK(std::ifstream(p.file).good());
    CHECK(p.steps == 50);
    CHECK(p.sets == std::vector<std::string>{"ekf", "open_loop"});
    CHECK(p.filters == std::vector<std::string>{"ukf", "ekf"});
    REQUIRE(p.ratio.size() == 4u);
    REQUIRE(p.diverged.size() == 4u);
    CHECK(p.ratio[0 * 2 + 1] == r.filters[0].ratio);  // set 0 (found for the EKF), filter 1 (the EKF)
    for (double e : p.energy) CHECK(e == Approx(r.energy).epsilon(1e-9));
    CHECK(names_argument(library_error([&] { hinf::replay_worst(cfg, d / "missing.h5", rs); }), "missing.h5"));
    const hinf::Config coarse = hinf::Config::from_text(kTinyMissile, "tiny.toml", {"filter.dt=0.02"});
    CHECK(names_argument(library_error([&] { hinf::replay_worst(coarse, r.file, rs); }),
                         "worst_file " + r.file + ": its signals are sampled at dt"));
    hinf::WorstSettings none = rs;
    none.filters = "";
    CHECK(names_argument(library_error([&] { hinf::replay_worst(cfg, r.file, none); }), "filters: no filter named"));
    s.energy = -1;
    CHECK(one_line_error([&] { hinf::worst(cfg, s); }, "energy must be a finite number > 0"));
    s.energy = NAN;
    s.filters = "dnn";
    CHECK(one_line_error([&] { hinf::worst(cfg, s); }, "network"));
    // the shared checks name the library's arguments
    s.filters = "ekf";
    s.evals = 0;
    CHECK(names_argument(library_error([&] { hinf::worst(cfg, s); }), "evals must be >= 1 (got 0)"));
    s.evals = 6;
    s.random_starts = -1;
    CHECK(names_argument(library_error([&] { hinf::worst(cfg, s); }), "random_starts must be >= 0"));
    s.random_starts = 1;
    s.linear_pieces = -1;
    CHECK(names_argument(library_error([&] { hinf::worst(cfg, s); }), "linear_pieces must be in [0, 1000]"));
    s.linear_pieces = 2;
    s.energy = -1;
    CHECK(names_argument(library_error([&] { hinf::worst(cfg, s); }), "energy must be a finite number > 0"));
}
