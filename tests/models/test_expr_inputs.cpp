// Known inputs of expression systems ([system] inputs): the table's hold and interpolation, a file read from the
// config's directory and carried in the effective config (a checkpoint needs no file), the one-line errors, the
// same bits as the expression of t it tabulates through truth, EKF and UKF, and a record beyond the table refused.
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "helpers.hpp"
#include "hinf/config.hpp"
#include "hinf/h5.hpp"
#include "models/expr_system.hpp"

using namespace hinf;
using hinf::test::TempDir;
using hinf::test::write_file;

namespace {

ExprSpec input_spec(bool linear) {
    ExprSpec s;
    s.states = {"x"};
    s.f = {{"f", "u*x + u"}};
    s.g = {{{"g", "1"}}};
    s.h = {{"h", "x"}};
    s.where = "t.toml: [system]";
    s.inputs = {"u"};
    s.input_t = {0.0, 0.03, 0.07};
    s.input_values = {1.0, 2.0, 4.0};
    s.input_linear = linear;
    return s;
}

double u_at(const ExprSystem& sys, double t) {
    double u = 0;
    sys.inputs_at(t, &u);
    return u;
}

// a continuous first-order system driven by a known input; `drive` is the input's expression
std::string driven_config(const std::string& drive, const std::string& extra = "") {
    return "[system]\nkind = \"expr\"\nstates = [\"x\"]\nmeasurements = 1\nf = [\"-x + " + drive +
           "\"]\ng = [[\"1\"]]\nh = [\"x\"]\n" + extra +
           "[filter]\nx0 = [0.5]\nxhat0 = [0.0]\ndt = 0.01\nt_final = 2\nrho = 2\n"
           "[online]\ndisturbance_std = 0.3\nnoise_std = 0.05\n";
}

// u(t_k) = sin(t_k) at t_k = k dt, printed with 17 digits (the same doubles back)
std::string sine_table(int rows) {
    std::ostringstream out;
    out.precision(17);
    out << "# a known input\ntime,u\n";
    for (int k = 0; k < rows; ++k) out << double(k) * 0.01 << "," << std::sin(double(k) * 0.01) << "\n";
    return out.str();
}

}  // namespace

TEST_CASE("known inputs: a row holds from its time (t = k dt a bit early included), linear between rows, ends held",
          "[model][expr][inputs]") {
    const ExprSystem held(input_spec(false)), linear(input_spec(true));
    CHECK(held.time_span() == std::make_pair(0.0, 0.07));
    CHECK(u_at(held, -1.0) == 1.0);
    CHECK(u_at(held, 0.0) == 1.0);
    CHECK(u_at(held, 0.02) == 1.0);
    CHECK(u_at(held, 0.03) == 2.0);
    CHECK(u_at(held, std::nextafter(0.03, 0.0)) == 2.0);  // the last bit early: the row already holds
    CHECK(u_at(held, 0.03 - 1e-6) == 1.0);                // well before it: the row before
    CHECK(u_at(held, 0.05) == 2.0);
    CHECK(u_at(held, 0.07) == 4.0);
    CHECK(u_at(held, 9.0) == 4.0);
    CHECK(u_at(linear, -1.0) == 1.0);
    CHECK(u_at(linear, 0.05) == Approx(3.0).epsilon(1e-15));
    CHECK(u_at(linear, 0.015) == Approx(1.5).epsilon(1e-15));
    CHECK(u_at(linear, 0.07) == 4.0);
    CHECK(u_at(linear, 9.0) == 4.0);
    // f = u x + u and its Jacobian u: the input enters as a signal of t, never differentiated in x
    const double x = 2.0;
    double f = 0, J = 0;
    held.drift(&f, &x, 0.05, 1);
    held.drift_jacobian(&J, &x, 0.05);
    CHECK(f == 6.0);
    CHECK(J == 2.0);
    linear.drift(&f, &x, 0.05, 1);
    CHECK(f == Approx(9.0).epsilon(1e-15));
    // the same values from a batch split over threads
    std::vector<double> xs(1000, x), fs(1000);
    held.drift(fs.data(), xs.data(), 0.05, 1000);
    for (double v : fs) CHECK(v == 6.0);
    // GiNaC's Jacobian names the input, not a derivative of it
    CHECK(held.compiled("df") == std::vector<std::string>{"u"});
}

TEST_CASE("known inputs from a file: read from the config's directory, carried in the effective config",
          "[model][expr][inputs]") {
    TempDir d("inputs-file");
    std::filesystem::create_directory(d / "sub");
    write_file(d, "sub/u.csv", sine_table(201));
    const std::string cfg = write_file(d, "sub/c.toml", driven_config("u", "inputs = \"u.csv\"\n"));
    // from another working directory: the path is the config's
    const RunConfig a = load_run_config(ConfigDoc::from_file(cfg));
    const std::string text = a.doc.text();
    CHECK(text.find("u.csv") == std::string::npos);
    CHECK(text.find("inputs") != std::string::npos);
    // the effective config loads without the file, to the same system
    std::filesystem::remove(d / "sub/u.csv");
    const RunConfig b = load_run_config(ConfigDoc::from_text(text, "checkpoint.h5:/config"));
    for (int k = 0; k <= 200; ++k) {
        const double t = double(k) * 0.01, x = 0.3;
        double fa = 0, fb = 0;
        a.system->drift(&fa, &x, t, 1);
        b.system->drift(&fb, &x, t, 1);
        REQUIRE(fa == fb);
        REQUIRE(fa == -x + std::sin(t));
    }
    CHECK(b.doc.text() == text);
    // --set system.inputs=FILE on a command line: a file in the working directory, when none is beside the config
    write_file(d, "w.csv", sine_table(201));
    const std::string in_d = "cd " + d.path.string() + " && " + std::string(HINF_CLI_PATH) + " rho sub/c.toml ";
    auto r = hinf::test::run_command(in_d + "--set system.inputs=w.csv");
    INFO(r.output);
    CHECK(r.status == 0);
    r = hinf::test::run_command(in_d + "--set system.inputs=none.csv");
    CHECK(r.status == 2);
    CHECK(r.output.find("sub/none.csv") != std::string::npos);
}

TEST_CASE("known inputs: a bad table is one line naming the file, the line and the fix", "[model][expr][inputs]") {
    TempDir d("inputs-bad");
    struct Case {
        std::string csv, extra, fragment;
    };
    const Case cases[] = {
        {"0,1\n1,2\n", "", "needs a header row naming its columns"},
        {"t\n0\n1\n", "", "needs a header row naming its columns"},
        {"t,u\n0,1\n0,2\n3,1\n", "", "line 3: time 0 is not after the row before it"},
        {"t,u\n0,1\n1,\n3,1\n", "", "line 3, column 2: '' is not a finite number"},
        {"t,u\n0,1\n1,nan\n3,1\n", "", "is not a finite number"},
        {"t,u\n0,1\n1,2,3\n3,1\n", "", "line 3: 3 columns, the header names 2"},
        {"t,u\n0,1\n1,2\n", "", "covers [0, 1] s, the run needs [0, 2] s"},
        {"t,u\n0.5,1\n3,2\n", "", "covers [0.5, 3] s, the run needs [0, 2] s"},
        {"t,u\n0,1\n", "", "1 row(s) of values; a table of inputs needs at least 2"},
        {"time,t\n0,1\n3,2\n", "", "column 2 is named t"},
        {"t,u,u\n0,1,1\n3,2,2\n", "", "two columns are named 'u'"},
        {"t,x\n0,1\n3,2\n", "", "'x' is defined twice"},
        {"t,u v\n0,1\n3,2\n", "", "input 'u v' is not a name"},
        {"t,sin\n0,1\n3,2\n", "", "input 'sin' is reserved"},
        {"t,u\n0,1\n3,2\n", "input_interpolation = \"cubic\"\n", "is not one of"},
    };
    int i = 0;
    for (const Case& c : cases) {
        const std::string name = "case" + std::to_string(++i);
        write_file(d, name + ".csv", c.csv);
        const std::string cfg =
            write_file(d, name + ".toml", driven_config("u", "inputs = \"" + name + ".csv\"\n" + c.extra));
        INFO(c.csv);
        REQUIRE_THROWS_WITH(load_run_config(ConfigDoc::from_file(cfg)), Catch::Contains(c.fragment));
    }
    // no file, an inline table without times, interpolation with no table: the config's own lines
    const std::string missing = write_file(d, "missing.toml", driven_config("u", "inputs = \"nope.csv\"\n"));
    REQUIRE_THROWS_WITH(load_run_config(ConfigDoc::from_file(missing)),
                        Catch::Contains("[system] inputs file") && Catch::Contains("nope.csv") &&
                            Catch::Contains("No such file"));
    REQUIRE_THROWS_WITH(load_run_config(ConfigDoc::from_text(driven_config("u", "inputs = { s = [0, 3], u = [1, 2] }\n"),
                                                             "t.toml")),
                        Catch::Contains("has no column t"));
    REQUIRE_THROWS_WITH(load_run_config(ConfigDoc::from_text(
                            driven_config("sin(t)", "input_interpolation = \"linear\"\n"), "t.toml")),
                        Catch::Contains("applies to a table of known inputs"));
}

TEST_CASE("a held table of sin(t_k) runs truth, EKF and UKF to the bits of the expression sin(t)",
          "[cli][expr][inputs]") {
    TempDir d("inputs-bits");
    write_file(d, "u.csv", sine_table(201));
    // continuous time (forward Euler), and a discrete map whose u_k is the row at t_k = k dt
    for (const std::string time : {"continuous", "discrete"}) {
        INFO(time);
        const std::string kind = "time = \"" + time + "\"\n";
        const std::string table = write_file(d, time + "_table.toml", driven_config("u", kind + "inputs = \"u.csv\"\n"));
        const std::string expr = write_file(d, time + "_expr.toml", driven_config("sin(t)", kind));
        for (const auto& [cfg, out] : {std::make_pair(table, d / (time + "_a")), std::make_pair(expr, d / (time + "_b"))}) {
            auto r = hinf::test::run_hinf("compare " + cfg + " --filters ekf,ukf --runs 3 --quiet --out " + out);
            INFO(r.output);
            REQUIRE(r.status == 0);
        }
        h5::Handle a = h5::open_file(d / (time + "_a/compare.h5"), false);
        h5::Handle b = h5::open_file(d / (time + "_b/compare.h5"), false);
        for (const std::string set : {"ekf/xhat", "ukf/xhat", "ekf/mse_per_run", "ukf/mse_per_run"}) {
            INFO(set);
            const std::vector<double> xa = h5::read_doubles(a.get(), set), xb = h5::read_doubles(b.get(), set);
            REQUIRE(xa.size() == xb.size());
            CHECK(xa == xb);
        }
    }
    const std::string table = d / "continuous_table.toml";
    // a record past the table's last row is refused before any filtering, naming both spans
    std::ostringstream rec;
    for (int k = 1; k <= 300; ++k) rec << double(k) * 0.01 << "," << 0.1 << "\n";
    const std::string record = write_file(d, "rec.csv", rec.str());
    hinf::test::expect_one_line_error("filter " + table + " --measurements " + record + " --filters ekf --out " + (d / "f"),
                                      "beyond its table of known inputs");
    // a table of a record shorter than the config's t_final: hinf filter checks the record's times alone
    write_file(d, "short.csv", sine_table(101));
    const std::string short_record = write_file(d, "short_rec.csv", rec.str().substr(0, rec.str().find("\n1.01")));
    auto f = hinf::test::run_hinf("filter " + table + " --set system.inputs=short.csv --measurements " + short_record +
                                  " --filters ekf --quiet --out " + (d / "g"));
    INFO(f.output);
    CHECK(f.status == 0);
    hinf::test::expect_one_line_error("compare " + table + " --set system.inputs=short.csv --filters ekf --out " + (d / "h"),
                                      "covers [0, 1] s, the run needs [0, 2] s");
}

TEST_CASE("hinf filter takes the known inputs a record carries: CSV columns, HDF5 datasets, the same bits as a table",
          "[cli][expr][inputs]") {
    TempDir d("inputs-record");
    write_file(d, "u.csv", sine_table(201));
    const std::string cfg = write_file(d, "c.toml", driven_config("u", "inputs = \"u.csv\"\n"));
    // a record of 150 rows made under u = cos(t), not the config's sin(t): as a table beside it, as a column of a
    // log (before the output: any order), and as a dataset of an HDF5 record
    const int K = 150;
    std::vector<double> t(K), y(K), u(K);
    std::ostringstream table, log;
    table.precision(17);
    log.precision(17);
    table << "t,u\n";
    log << "time,u,y\n";
    for (int k = 0; k < K; ++k) {
        t[k] = double(k + 1) * 0.01;
        u[k] = std::cos(t[k]);
        y[k] = 0.5 + 0.3 * std::sin(3 * t[k]);
        table << t[k] << "," << u[k] << "\n";
        log << t[k] << "," << u[k] << "," << y[k] << "\n";
    }
    std::ostringstream rec;
    rec.precision(17);
    for (int k = 0; k < K; ++k) rec << t[k] << "," << y[k] << "\n";
    write_file(d, "cos.csv", table.str());
    const std::string plain = write_file(d, "rec.csv", rec.str()), with_u = write_file(d, "log.csv", log.str());
    {
        h5::Handle h = h5::create_file(d / "log.h5");
        h5::write_doubles(h.get(), "t", t.data(), {hsize_t(K)});
        h5::write_doubles(h.get(), "y", y.data(), {hsize_t(K)});
        h5::write_doubles(h.get(), "u", y.data(), {hsize_t(K)});  // a top-level dataset named u is not the input
        h5::Handle g = h5::create_group(h.get(), "inputs");
        h5::write_doubles(g.get(), "u", u.data(), {hsize_t(K)});
    }
    std::vector<std::vector<double>> xhat;
    for (const std::string& args : {"--set system.inputs=cos.csv --measurements " + plain, "--measurements " + with_u,
                                   "--measurements " + (d / "log.h5"), "--measurements " + plain}) {
        const std::string out = d / ("f" + std::to_string(xhat.size()));
        auto f = hinf::test::run_hinf("filter " + cfg + " " + args + " --filters ekf,ukf --out " + out);
        INFO(args << "\n" << f.output);
        REQUIRE(f.status == 0);
        CHECK((f.output.find("known inputs u: the record's own") != std::string::npos) == (xhat.size() == 1 || xhat.size() == 2));
        h5::Handle h = h5::open_file(out + "/estimates.h5", false);
        std::vector<double> x = h5::read_doubles(h.get(), "ekf/xhat"), v = h5::read_doubles(h.get(), "ukf/xhat");
        x.insert(x.end(), v.begin(), v.end());
        xhat.push_back(x);
    }
    CHECK(xhat[1] == xhat[0]);
    CHECK(xhat[2] == xhat[0]);
    REQUIRE(xhat[3].size() == xhat[0].size());
    CHECK(xhat[3] != xhat[0]);  // the config's own table, sin(t): other estimates
    // the result file carries the inputs it was made with: filtering with its config needs no log
    {
        h5::Handle h = h5::open_file(d / "f1/estimates.h5", false);
        const RunConfig c = load_run_config(ConfigDoc::from_text(h5::read_string(h.get(), "config"), "estimates.h5:/config"),
                                            false, false);
        const ExprSystem* sys = expr_system_of(*c.system);
        REQUIRE(sys);
        for (int k = 0; k < K; ++k) REQUIRE(u_at(*sys, t[k]) == u[k]);
    }
    // a table named on the command line wins over the record's own (what other inputs would have given), said
    {
        auto f = hinf::test::run_hinf("filter " + cfg + " --set system.inputs=u.csv --measurements " + with_u +
                                      " --filters ekf,ukf --out " + (d / "f4"));
        INFO(f.output);
        REQUIRE(f.status == 0);
        CHECK(f.output.find("known inputs u: --set system.inputs=u.csv, not the record's own") != std::string::npos);
        h5::Handle h = h5::open_file(d / "f4/estimates.h5", false);
        std::vector<double> x = h5::read_doubles(h.get(), "ekf/xhat"), v = h5::read_doubles(h.get(), "ukf/xhat");
        x.insert(x.end(), v.begin(), v.end());
        CHECK(x == xhat[3]);
    }
    // hinf's own records carry their run's inputs (group inputs): compare.h5's run 0, made under cos(t), filtered under
    // a config whose table is sin(t) reads cos(t), the same bits as naming that table
    {
        std::ostringstream cos_table;
        cos_table.precision(17);
        cos_table << "t,u\n";
        for (int k = 0; k <= 200; ++k) cos_table << double(k) * 0.01 << "," << std::cos(double(k) * 0.01) << "\n";
        write_file(d, "cos2.csv", cos_table.str());
        auto c = hinf::test::run_hinf("compare " + cfg + " --set system.inputs=cos2.csv --filters ekf --runs 1 --quiet "
                                      "--out " + (d / "c"));
        INFO(c.output);
        REQUIRE(c.status == 0);
        const std::string record = d / "c/compare.h5";
        {
            h5::Handle h = h5::open_file(record, false);
            const std::vector<double> tc = h5::read_doubles(h.get(), "t"), uc = h5::read_doubles(h.get(), "inputs/u");
            REQUIRE(uc.size() == tc.size());
            for (std::size_t k = 0; k < tc.size(); ++k) REQUIRE(uc[k] == std::cos(tc[k]));
        }
        std::vector<std::vector<double>> x;
        for (const std::string set : {"", " --set system.inputs=cos2.csv"}) {
            const std::string out = d / ("fc" + std::to_string(x.size()));
            auto f = hinf::test::run_hinf("filter " + cfg + set + " --measurements " + record + " --filters ekf --quiet "
                                          "--out " + out);
            INFO(f.output);
            REQUIRE(f.status == 0);
            h5::Handle h = h5::open_file(out + "/estimates.h5", false);
            x.push_back(h5::read_doubles(h.get(), "ekf/xhat"));
            CHECK(h5::exists(h.get(), "inputs/u"));  // estimates.h5 is a record too
        }
        CHECK(x[0] == x[1]);
        // scripts/plot draws both records, their inputs group no filter
        for (const std::string& file : {record, std::string(d / "fc0/estimates.h5")}) {
            auto p = hinf::test::run_command("/usr/bin/python3 " + hinf::test::source_path("scripts/plot") + " " + file +
                                             " --out " + (d / "plots"));
            INFO(p.output);
            CHECK(p.status == 0);
        }
    }
    const std::string gap = write_file(d, "gap.csv", "t,y,u\n0.01,0.1,0.5\n0.02,0.1,\n0.03,0.1,0.5\n");
    hinf::test::expect_one_line_error("filter " + cfg + " --measurements " + gap + " --filters ekf --out " + (d / "e2"),
                                      "line 3, column 3: '' is not a number (known input u has no gaps: fill them)");
    const std::string bare = write_file(d, "bare.csv", "0.01,0.1,0.5\n0.02,0.1,0.5\n");
    hinf::test::expect_one_line_error("filter " + cfg + " --measurements " + bare + " --filters ekf --out " + (d / "e5"),
                                      "to carry the known inputs the record needs a header naming its columns");
    write_file(d, "uw.csv", "t,u,w\n0,1,2\n2,1,2\n");
    const std::string two = write_file(d, "two.toml", driven_config("u + w", "inputs = \"uw.csv\"\n"));
    const std::string half = write_file(d, "half.csv", "t,y,u\n0.01,0.1,0.5\n0.02,0.1,0.5\n");
    hinf::test::expect_one_line_error("filter " + two + " --measurements " + half + " --filters ekf --out " + (d / "e3"),
                                      "line 1: has known input(s) of the system but not w: give every known input its "
                                      "column, or none");
    hinf::test::expect_one_line_error("filter " + cfg + " --measurements " + half + " --set system.inputs=uw.csv "
                                          "--filters ekf --out " + (d / "e4"),
                                      "but not w");
}

TEST_CASE("the recorded-voltage motor example loads its table from beside it", "[model][expr][inputs]") {
    const RunConfig c =
        load_run_config(ConfigDoc::from_file(hinf::test::source_path("examples/systems/dc_motor_recorded.toml")));
    const auto* sys = dynamic_cast<const ExprSystem*>(c.system.get());
    REQUIRE(sys);
    CHECK(sys->inputs() == std::vector<std::string>{"V"});
    CHECK(sys->time_span() == std::make_pair(0.0, 20.0));
    CHECK(u_at(*sys, 1.5) == -6.3);  // examples/systems/dc_motor_voltage.csv: the row at t = 1 s, held
    // the current's drift (V - Rw cur - Kt omega) / L at rest is V / L
    const double x[3] = {0.0, 0.0, 0.0};
    double f[3];
    sys->drift(f, x, 1.5, 1);
    CHECK(f[2] == Approx(-6.3 / 0.5).epsilon(1e-15));
}

TEST_CASE("a trained gain network filters with the run's known inputs, not its training table", "[cli][expr][inputs]") {
    TempDir d("inputs-network");
    write_file(d, "u.csv", sine_table(201));
    const std::string cfg = write_file(
        d, "c.toml",
        driven_config("u", "inputs = \"u.csv\"\n") +
            "[network]\nhidden = [8, 8]\nprecision = \"double\"\n[training]\nsamples = 64\nbatch = 32\nadam_steps = 3\n");
    auto t = hinf::test::run_hinf("train " + cfg + " --until 0.3 --quiet --out " + (d / "run"));
    INFO(t.output);
    REQUIRE(t.status == 0);
    std::ostringstream rec;
    rec.precision(17);
    for (int k = 1; k <= 150; ++k) rec << double(k) * 0.01 << "," << 0.5 * std::sin(double(k) * 0.01) << "\n";
    const std::string record = write_file(d, "rec.csv", rec.str());
    // the training's table under another file name: the same values, the same bits; another table: other estimates
    write_file(d, "same.csv", sine_table(201));
    std::ostringstream other;
    other << "t,u\n0,3\n2,3\n";
    write_file(d, "other.csv", other.str());
    std::vector<std::vector<double>> xhat;
    for (const std::string table : {"u.csv", "same.csv", "other.csv"}) {
        const std::string out = d / ("f_" + table);
        auto f = hinf::test::run_hinf("filter " + cfg + " --set system.inputs=" + table + " --network " + (d / "run") +
                                      "/checkpoint.h5 --measurements " + record + " --quiet --out " + out);
        INFO(f.output);
        REQUIRE(f.status == 0);
        h5::Handle h = h5::open_file(out + "/estimates.h5", false);
        xhat.push_back(h5::read_doubles(h.get(), "dnn_gain_measured/xhat"));
    }
    CHECK(xhat[0] == xhat[1]);
    REQUIRE(xhat[0].size() == xhat[2].size());
    CHECK(xhat[0] != xhat[2]);
    // a network trained with known inputs and a config without them (or the other way round): one line
    const std::string plain = write_file(d, "plain.toml", driven_config("sin(t)"));
    hinf::test::expect_one_line_error("filter " + plain + " --network " + (d / "run") + "/checkpoint.h5 --measurements " +
                                          record + " --out " + (d / "p"),
                                      "was trained with the known inputs (u), the config's system has (none)");
}
