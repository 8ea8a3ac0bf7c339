// `hinf export --c`: the exported C99 filter, compiled with `cc -std=c99 -O2 ... -lm` and nothing else, reproduces
// `hinf filter`'s DNN estimates on a record: to round-off of double arithmetic for a double network, to the float
// network's round-off (amplified by the gain, then contracting) for a float one; built-in and expression systems,
// both training variants, discrete-time systems, and an ensemble's mean gain. Bad use is one line.
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <iterator>
#include <sstream>
#include <tuple>

#include "helpers.hpp"
#include "hinf/h5.hpp"

using hinf::test::expect_one_line_error;
using hinf::test::run_command;
using hinf::test::run_hinf;
using hinf::test::TempDir;
using hinf::test::write_file;

namespace {

// operate.h5's t and y as CSV rows "t,y_1,...,y_m" (17 digits: the same doubles)
std::string record_csv(const TempDir& d, const std::string& operate_h5) {
    hinf::h5::Handle f = hinf::h5::open_file(operate_h5, false);
    std::vector<hsize_t> dims;
    std::vector<double> t = hinf::h5::read_doubles(f.get(), "t");
    std::vector<double> y = hinf::h5::read_doubles(f.get(), "y", &dims);
    const std::size_t m = y.size() / t.size();
    std::ostringstream out;
    out.precision(17);
    for (std::size_t k = 0; k < t.size(); ++k) {
        out << t[k];
        for (std::size_t j = 0; j < m; ++j) out << ',' << y[k * m + j];
        out << '\n';
    }
    return write_file(d, "record.csv", out.str());
}

struct Compared {
    double max_abs = 0, scale = 0, final_abs = 0;
    std::size_t rows = 0, compared = 0;  // rows the C printed; rows compared (before a divergence)
};

// trains (members > 1: that many networks, training seeds 1, 2, ..., run as one --ensemble), records with operate
// (measured, the first network), runs `hinf filter` and the exported C on the record, compares
Compared export_and_compare(const TempDir& d, const std::string& cfg, const std::string& train_args,
                            const std::string& label, int members = 1) {
    std::string nets, ensemble = members > 1 ? " --ensemble" : "";
    for (int s = 1; s <= members; ++s) {
        const std::string run = members > 1 ? "run" + std::to_string(s) : "run";
        auto t = run_hinf("train " + cfg + " --out " + (d / run) + " --quiet --set training.seed=" + std::to_string(s) +
                          " " + train_args);
        INFO(t.output);
        REQUIRE(t.status == 0);
        nets += " " + (d / run) + "/checkpoint.h5";
    }
    const std::string net = nets.substr(1, nets.find(".h5") + 2);  // the first
    auto o = run_hinf("operate " + cfg + " --network " + net + " --mode measured --runs 1 --quiet --out " + (d / "op"));
    INFO(o.output);
    REQUIRE(o.status == 0);
    const std::string csv = record_csv(d, d / "op/operate.h5");
    std::string flags;
    for (std::size_t at = 0; at < nets.size();) {
        const std::size_t next = nets.find(' ', at + 1);
        flags += " --network" + nets.substr(at, next - at);
        at = next == std::string::npos ? nets.size() : next;
    }
    auto f = run_hinf("filter " + cfg + flags + ensemble + " --measurements " + csv + " --quiet --out " + (d / "flt"));
    INFO(f.output);
    REQUIRE(f.status == 0);
    auto e = run_hinf("export" + nets + ensemble + " --c " + (d / "c"));
    INFO(e.output);
    REQUIRE(e.status == 0);
    // no include path but the exported pair's, no library but libm; warnings are errors
    auto cc = run_command("cc -std=c99 -O2 -Wall -Wextra -pedantic -Werror -I " + (d / "c") + " -o " + (d / "run_record") +
                          " " + hinf::test::source_path("tests/export/run_record.c") + " " + (d / "c/hinf_filter.c") +
                          " -lm");
    INFO(cc.output);
    REQUIRE(cc.status == 0);
    auto r = run_command(d / "run_record" + std::string(" ") + csv);
    REQUIRE(r.status == 0);

    hinf::h5::Handle h = hinf::h5::open_file(d / "flt/estimates.h5", false);
    hinf::h5::Handle g = hinf::h5::open_group(h.get(), label);
    std::vector<hsize_t> dims;
    std::vector<double> xhat = hinf::h5::read_doubles(g.get(), "xhat", &dims);
    std::vector<double> final = hinf::h5::read_doubles(g.get(), "xhat_final");
    const std::vector<double> times = hinf::h5::read_doubles(h.get(), "t");
    // hinf freezes a filter that leaves the plausible range (docs/compare.md); the exported C has no such check
    const double diverged_at = hinf::h5::get_attr_double(g.get(), "diverged_at");
    const std::size_t K = dims[0], n = dims[1];
    std::istringstream in(r.output);
    std::string line;
    Compared c;
    for (std::size_t k = 0; k <= K; ++k) {
        REQUIRE(std::getline(in, line));
        const bool last = k == K;
        if (last) REQUIRE(line.rfind("final,", 0) == 0);
        if (diverged_at >= 0 && (last || times[k] > diverged_at)) {  // after hinf's divergence: frozen there
            ++c.rows;
            continue;
        }
        std::istringstream row(last ? line.substr(6) : line);
        for (std::size_t i = 0; i < n; ++i) {
            std::string cell;
            REQUIRE(std::getline(row, cell, ','));
            const double want = last ? final[i] : xhat[k * n + i];
            const double diff = std::fabs(std::stod(cell) - want);
            c.max_abs = std::max(c.max_abs, diff);
            c.scale = std::max(c.scale, std::fabs(want));
            if (last) c.final_abs = std::max(c.final_abs, diff);
        }
        ++c.rows;
        ++c.compared;
    }
    REQUIRE(std::getline(in, line));
    CHECK(line.rfind("us_per_step ", 0) == 0);
    return c;
}

}  // namespace

TEST_CASE("exported C filter of a double network on a built-in system matches hinf filter to double round-off",
          "[export]") {
    // gain: the time-varying storage S(t) (its default) and the constant S (storage_knots = 0)
    const std::tuple<const char*, const char*, const char*> cases[] = {
        {"missile", "dissipative", ""}, {"missile", "paper", ""}, {"maneuvering_missile", "dissipative", ""},
        {"missile", "gain", ""}, {"missile", "gain", "storage_knots = 0\n"},
        // a tight input box (the central 40 % of the training estimates): the C holds z where hinf does
        {"missile", "gain", "input_box = 0.3\n"},
        // graded knots (network.knot_ratio): the C looks the interval up in its table of knot times
        {"missile", "gain", "knot_ratio = 10\n"},
        // outputs of different noise ([online] noise_std list): C weighs y and C(x^) as hinf's model does
        {"missile", "gain", "[online]\nnoise_std = [20.0, 40.0, 10.0, 5.0, 2.0, 8.0]\n"}};
    for (const auto& [kind, variant, network] : cases) {
        SECTION(std::string(kind) + " " + variant + " " + network) {
            TempDir d("export-missile");
            const std::string cfg = write_file(d, "tiny.toml",
                                               "[system]\nkind = \"" + std::string(kind) +
                                                   "\"\n[filter]\nt_final = 3.0\nvariant = \"" + std::string(variant) +
                                                   "\"\n[network]\nhidden = [8, 8]\nprecision = \"double\"\n" + network +
                                                   "[training]\nsamples = 50\nbatch = 20\nadam_steps = 2\n"
                                                   "checkpoint_every = 5\n");
            Compared c = export_and_compare(d, cfg, "--until 0.1", std::string("dnn_") + variant + "_measured");
            INFO("max |C - hinf| " << c.max_abs << " over states up to " << c.scale);
            CHECK(c.rows == 301);
            // the tiny `paper` network leaves the plausible range after ~0.3 s: compared up to there
            CHECK(c.compared >= 20);
            CHECK(c.scale > 100);  // the missile's positions: a real trajectory was compared
            CHECK(c.max_abs <= 1e-11 * c.scale);
            const std::string code = hinf::test::read_text(d / "c/hinf_filter.c");
            CHECK((code.find("_zlo[a]") != std::string::npos) == (std::string(variant) == "gain"));
            CHECK((code.find("_knot_t[") != std::string::npos) ==
                  (std::string(network).find("knot_ratio") != std::string::npos));
            CHECK((code.find("_output_weight[j] * y[j]") != std::string::npos) ==
                  (std::string(network).find("noise_std") != std::string::npos));
        }
    }
}

TEST_CASE("exported C filter of a float expression-system network matches hinf filter to float round-off",
          "[export][gain]") {
    // dissipative, and gain (the default: S(t), one output for two states, K(x^, t) through dC/dx)
    for (const std::string variant : {"dissipative", "gain"}) {
        SECTION(variant) {
            TempDir d("export-expr");
            const std::string cfg = hinf::test::source_path("runs/vanderpol.toml");
            Compared c = export_and_compare(d, cfg,
                                            "--until 0.3 --set filter.variant=" + variant +
                                                " --set training.samples=400 --set training.batch=200 "
                                                "--set training.adam_steps=5",
                                            "dnn_" + variant + "_measured");
            INFO("max |C - hinf| " << c.max_abs << " over states up to " << c.scale << ", after the last step "
                                   << c.final_abs);
            CHECK(c.rows == 2001);
            CHECK(c.compared == 2001);
            // the float network's round-off (~1e-7 relative) is amplified by the first large gain steps, then contracts
            CHECK(c.max_abs <= 1e-4 * c.scale);
            CHECK(c.final_abs <= 1e-6 * c.scale);
        }
    }
}

TEST_CASE("exported C filter with noise and disturbance std lists or covariances matches hinf filter to double round-off",
          "[export][gain][channels]") {
    // an expression system with two inputs and two outputs of different stds, uncorrelated (lists) and correlated
    // (noise_cov: correlation 0.3; disturbance_cov: 0.5): C weighs y, C(x^), dC/dx and B
    struct Case {
        const char* name;
        const char* online;
        const char* weigh_y;  // how the step weighs y
        double W21, W22, U21, U22;  // y~ = W y, B~ = B U (W11 = 1/0.05, U11 = 0.5)
    };
    const double l22 = std::sqrt(0.16 - 0.12 * 0.12);  // the noise covariance's Cholesky factor [[0.05, 0], [0.12, l22]]
    const Case cases[] = {
        {"lists", "disturbance_std = [0.5, 2.0]\nnoise_std = [0.05, 0.4]\n", "_output_weight[j] * y[j]", 0.0, 2.5, 0.0,
         2.0},
        {"covariances", "disturbance_cov = [[0.25, 0.5], [0.5, 4.0]]\nnoise_cov = [[0.0025, 0.006], [0.006, 0.16]]\n",
         "_weigh(e)", -0.12 / (0.05 * l22), 1.0 / l22, 1.0, std::sqrt(3.0)}};
    for (const Case& cs : cases) {
        SECTION(cs.name) {
            TempDir d("export-weighted");
            const std::string cfg = write_file(
                d, "weighted.toml",
                "[system]\nkind = \"expr\"\nstates = [\"p\", \"w\"]\ndisturbances = 2\nmeasurements = 2\n"
                "f = [\"w\", \"-p - 0.3*w + 0.1*sin(p)\"]\ng = [[\"0.2\", \"0\"], [\"1\", \"0.5\"]]\n"
                "h = [\"p + 0.1*p^3\", \"w\"]\n[filter]\nrho = 3\nQ = [1.0, 1.0]\nx0 = [1.5, 0.0]\nxhat0 = [0.5, 0.5]\n"
                "dt = 0.01\nt_final = 2\n[network]\nhidden = [8, 8]\nprecision = \"double\"\n[training]\nsamples = 64\n"
                "batch = 32\nadam_steps = 3\ncheckpoint_every = 5\n[online]\n" + std::string(cs.online));
            Compared c = export_and_compare(d, cfg, "--until 0.1", "dnn_gain_measured");
            INFO("max |C - hinf| " << c.max_abs << " over states up to " << c.scale);
            CHECK(c.rows == 201);
            CHECK(c.compared == 201);
            CHECK(c.max_abs <= 1e-11 * c.scale);
            const std::string code = hinf::test::read_text(d / "c/hinf_filter.c");
            CHECK(code.find("_disturbance_scale[") != std::string::npos);
            CHECK(code.find(cs.weigh_y) != std::string::npos);

            // The step's gain law does not read B, so the comparison above cannot see a wrong B~: the system
            // functions the step calls, at one state, against the weighted system written out by hand from the
            // config above. Outputs: y~ = W y with W = [[20, 0], [W21, W22]]; inputs: B~ = B U with
            // U = [[0.5, 0], [U21, U22]]. At x = (1, 2), t = 0.3:
            //   A = (w, -p - 0.3 w + 0.1 sin p) = (2, -1.6 + 0.1 sin 1)
            //   B~ = [[0.2, 0], [1, 0.5]] U = [[0.1, 0], [0.5 + 0.5 U21, 0.5 U22]]
            //   C = (p + 0.1 p^3, w) = (1.1, 2),  dC/dx = [[1 + 0.3 p^2, 0], [0, 1]] = [[1.3, 0], [0, 1]]
            auto cc = run_command("cc -std=c99 -O2 -Wall -Wextra -pedantic -Werror -Wno-unused-function -I " +
                                  (d / "c") + " -o " + (d / "probe") + " " +
                                  hinf::test::source_path("tests/export/probe_system.c") + " -lm");
            INFO(cc.output);
            REQUIRE(cc.status == 0);
            auto p = run_command(d / "probe" + std::string(" 0.3 1 2"));
            INFO(p.output);
            REQUIRE(p.status == 0);
            const std::vector<std::pair<std::string, std::vector<double>>> want = {
                {"A", {2.0, -1.6 + 0.1 * std::sin(1.0)}},
                {"B", {0.1, 0.0, 0.5 + 0.5 * cs.U21, 0.5 * cs.U22}},
                {"C", {22.0, cs.W21 * 1.1 + cs.W22 * 2.0}},
                {"H", {26.0, 0.0, cs.W21 * 1.3, cs.W22}}};
            std::istringstream in(p.output);
            for (const auto& [name, values] : want) {
                std::string line;
                REQUIRE(std::getline(in, line));
                std::istringstream cells(line);
                std::string cell;
                REQUIRE(std::getline(cells, cell, ','));
                CHECK(cell == name);
                for (double v : values) {
                    REQUIRE(std::getline(cells, cell, ','));
                    INFO(name << ": " << cell << " against " << v);
                    CHECK(std::fabs(std::stod(cell) - v) <= 1e-13 * (1 + std::fabs(v)));
                }
                CHECK_FALSE(std::getline(cells, cell, ','));
            }
        }
    }
}

TEST_CASE("exported C filter of a discrete-time system matches hinf filter to double round-off",
          "[export][gain][discrete]") {
    // the one-step predictor x^ <- f(x^, k) + K e of a map that reads the step index k (t = k dt), one output for
    // two states; an ensemble of two is the same step with the mean gain; the Kalman-form head (method.md 16.16)
    // K = F P H'(H P H' + R)^-1 needs the map's Jacobian in the C too
    struct Case {
        int members;
        std::string head;
    };
    for (const Case& cs : {Case{1, "direct"}, Case{2, "direct"}, Case{1, "kalman"}}) {
        const int members = cs.members;
        SECTION(std::to_string(members) + " network(s), gain_head " + cs.head) {
            TempDir d("export-discrete");
            const std::string cfg = write_file(
                d, "d.toml",
                "[system]\nkind = \"expr\"\ntime = \"discrete\"\nstates = [\"p\", \"v\"]\ndisturbances = 1\n"
                "measurements = 1\nf = [\"p + 0.1*v\", \"0.9*v - 0.05*sin(p) + 0.1*cos(0.3*k)\"]\ng = [[\"0\"], [\"1\"]]\n"
                "h = [\"p + 0.05*p^3\"]\n[filter]\nQ = [1.0, 1.0]\nx0 = [1.0, 0.0]\nxhat0 = [0.0, 0.0]\ndt = 0.5\n"
                "t_final = 50.0\n[network]\ngain_head = \"" + cs.head + "\"\nhidden = [8, 8]\nprecision = \"double\"\n"
                "[training]\nsamples = 64\n"
                "batch = 32\nadam_steps = 3\ncheckpoint_every = 5\n[online]\ndisturbance_std = 0.1\nnoise_std = 0.2\n");
            Compared c = export_and_compare(d, cfg, "--until 5", members > 1 ? "dnn_gain_ensemble" : "dnn_gain_measured",
                                            members);
            INFO("max |C - hinf| " << c.max_abs << " over states up to " << c.scale);
            CHECK(c.rows == 101);
            // the tiny networks' ensemble diverges after ~40 s (|x^| >= 1e12, hinf freezes it): compared up to there
            CHECK(c.compared >= (members > 1 ? 50u : 101u));
            CHECK(c.scale > 0.1);
            CHECK(c.max_abs <= 1e-11 * c.scale);
            const std::string code = hinf::test::read_text(d / "c/hinf_filter.c");
            CHECK(code.find("const double k = nearbyint(hinf_t_ / (0.5));") != std::string::npos);
            CHECK(code.find("s->xhat[i] = a[i] + ke;") != std::string::npos);
            CHECK((code.find("hinf_filter_drift_jacobian(F, xhat, t);") != std::string::npos) == (cs.head == "kalman"));
        }
    }
}

TEST_CASE("exported C filter of a system with known inputs carries their table and matches hinf filter",
          "[export][gain][inputs]") {
    // a motor driven by a recorded voltage staircase ([system] inputs), held and interpolated: the C looks the table
    // up as hinf does; built with -DPREFIX_EXTERNAL_INPUTS it leaves the table out for the caller's own u(t)
    for (const std::string interpolation : {"hold", "linear"}) {
        SECTION(interpolation) {
            TempDir d("export-inputs");
            std::ostringstream table;
            table << "t,volt\n";
            for (int r = 0; r <= 40; ++r) table << 0.05 * r << "," << (r % 7 < 3 ? 6.0 : -4.0) + 0.25 * r << "\n";
            write_file(d, "volt.csv", table.str());
            const std::string cfg = write_file(
                d, "m.toml",
                "[system]\nkind = \"expr\"\nstates = [\"w\", \"i\"]\ndisturbances = 2\nmeasurements = 1\n"
                "f = [\"(0.5*i - 0.2*w)/0.05\", \"(volt - i - 0.5*w)/0.3\"]\ng = [[\"1\", \"0\"], [\"0\", \"1\"]]\n"
                "h = [\"w\"]\ninputs = \"volt.csv\"\ninput_interpolation = \"" + interpolation + "\"\n"
                "[filter]\nx0 = [0.0, 0.0]\nxhat0 = [1.0, 0.5]\ndt = 0.01\nt_final = 2.0\nrho = 2\n"
                "[network]\nhidden = [8, 8]\nprecision = \"double\"\n"
                "[training]\nsamples = 64\nbatch = 32\nadam_steps = 3\ncheckpoint_every = 5\n"
                "[online]\ndisturbance_std = 0.5\nnoise_std = 0.05\n");
            Compared c = export_and_compare(d, cfg, "--until 0.3", "dnn_gain_measured");
            INFO("max |C - hinf| " << c.max_abs << " over states up to " << c.scale);
            CHECK(c.rows == 201);
            CHECK(c.compared == 201);
            CHECK(c.scale > 1);
            CHECK(c.max_abs <= 1e-11 * c.scale);
            const std::string code = hinf::test::read_text(d / "c/hinf_filter.c");
            CHECK(code.find("static const double hinf_filter_input_t[41]") != std::string::npos);
            CHECK((code.find("double w = (t - hinf_filter_input_t[j])") != std::string::npos) ==
                  (interpolation == "linear"));
            CHECK(hinf::test::read_text(d / "c/hinf_filter.h").find("hinf_filter_EXTERNAL_INPUTS") != std::string::npos);
            // live inputs: the caller's function, no table
            write_file(d, "live.c", "void hinf_filter_inputs_at(double t, double* u);\n"
                                    "void hinf_filter_inputs_at(double t, double* u) { u[0] = 12.0 * t; }\n");
            auto cc = run_command("cc -std=c99 -O2 -Wall -Wextra -pedantic -Werror -Dhinf_filter_EXTERNAL_INPUTS -I " +
                                  (d / "c") + " -o " + (d / "live") + " " +
                                  hinf::test::source_path("tests/export/run_record.c") + " " + (d / "c/hinf_filter.c") +
                                  " " + (d / "live.c") + " -lm");
            INFO(cc.output);
            CHECK(cc.status == 0);
            auto nm = run_command("nm " + (d / "live"));
            CHECK(nm.output.find("hinf_filter_input_t") == std::string::npos);
        }
    }
}

TEST_CASE("exported C filter with an angle output matches hinf filter across the bearing's +-pi cut",
          "[export][gain][angles]") {
    // a target passing the negative x axis of a radar (bearing from +pi to -pi at step 15): the step wraps the
    // bearing's innovation in the user's units, then weighs it as the outputs are (docs/formats.md angle_outputs)
    const char* onlines[] = {"noise_std = 5.0\n", "noise_std = [5.0, 0.005]\n", "noise_cov = [[25.0, 0.01], [0.01, 2.5e-5]]\n"};
    for (const char* online : onlines) {
        SECTION(online) {
            TempDir d("export-angles");
            const std::string cfg = write_file(
                d, "cut.toml",
                "[system]\nkind = \"expr\"\ntime = \"discrete\"\nstates = [\"px\", \"py\", \"vx\", \"vy\"]\n"
                "disturbances = 2\nmeasurements = 2\nf = [\"px + vx\", \"py + vy\", \"vx\", \"vy\"]\n"
                "g = [[\"0.5\", \"0\"], [\"0\", \"0.5\"], [\"1\", \"0\"], [\"0\", \"1\"]]\n"
                "h = [\"sqrt(px^2 + py^2)\", \"atan2(py, px)\"]\nangle_outputs = [2]\n[filter]\nrho = 2000\n"
                "x0 = [-1000.0, 150.0, 0.0, -10.0]\nxhat0 = [-990.0, 140.0, 1.0, -9.0]\ndt = 1.0\nt_final = 40\n"
                "[network]\nhidden = [8, 8]\nprecision = \"double\"\n[training]\nsamples = 64\nbatch = 32\n"
                "adam_steps = 3\ncheckpoint_every = 5\n[online]\ndisturbance_std = 0.2\n" + std::string(online));
            Compared c = export_and_compare(d, cfg, "--until 10", "dnn_gain_measured");
            INFO("max |C - hinf| " << c.max_abs << " over states up to " << c.scale);
            CHECK(c.rows == 41);
            CHECK(c.compared == 41);
            CHECK(c.max_abs <= 1e-11 * c.scale);
            const std::string code = hinf::test::read_text(d / "c/hinf_filter.c");
            CHECK(code.find("e[1] = remainder(e[1], 6.2831853071795862);") != std::string::npos);
            // the record crosses the cut: its bearings take both signs near pi
            hinf::h5::Handle f = hinf::h5::open_file(d / "op/operate.h5", false);
            const std::vector<double> y = hinf::h5::read_doubles(f.get(), "y");
            bool above = false, below = false;
            for (std::size_t k = 1; k < y.size(); k += 2) {
                above = above || y[k] > 3.0;
                below = below || y[k] < -3.0;
            }
            CHECK((above && below));
        }
    }
}

TEST_CASE("exported C filter of a gain network that sees an angle as (cos, sin) matches hinf filter",
          "[export][gain][angles]") {
    // a phase-locked loop whose phase winds past training's estimates (network.angle_inputs = "periodic", the
    // default; the frequency's input held in its box): the C forms the same input row as hinf
    TempDir d("export-angle-inputs");
    const std::string cfg = write_file(
        d, "pll.toml",
        "[system]\nkind = \"expr\"\nstates = [\"phi\", \"w\"]\ndisturbances = 2\nmeasurements = 1\n"
        "f = [\"w\", \"0\"]\ng = [[\"1\", \"0\"], [\"0\", \"1\"]]\nh = [\"sin(phi)\"]\nangle_states = [1]\n"
        "[filter]\nrho = 0.5\nx0 = [0.0, 6.0]\nxhat0 = [0.4, 5.5]\ndt = 0.01\nt_final = 2.0\n"
        "[network]\nhidden = [8, 8]\nprecision = \"double\"\n[training]\nsamples = 64\nbatch = 32\n"
        "adam_steps = 3\ncheckpoint_every = 50\nacceptance_runs = 0\nselect_every = 0\n"
        "[online]\ndisturbance_std = [0.05, 0.3]\nnoise_std = 0.1\n");
    Compared c = export_and_compare(d, cfg, "--until 0.5", "dnn_gain_measured");
    INFO("max |C - hinf| " << c.max_abs << " over states up to " << c.scale);
    CHECK(c.rows == 201);
    CHECK(c.compared == 201);
    CHECK(c.max_abs <= 1e-11 * c.scale);
    const std::string code = hinf::test::read_text(d / "c/hinf_filter.c");
    CHECK(code.find("z[0] = cos(xhat[0]);") != std::string::npos);
    CHECK(code.find("z[1] = sin(xhat[0]);") != std::string::npos);
    CHECK(code.find("_zhi[1]") != std::string::npos);  // the frequency, held in its box, is the third entry
}

TEST_CASE("exported C ensemble of gain networks matches hinf filter --ensemble to double round-off",
          "[export][gain][ensemble]") {
    // two and three members of one model (training seeds 1, 2, 3): the C's mean gain is filters/dnn.cpp's
    for (const int members : {2, 3}) {
        SECTION(std::to_string(members) + " networks") {
            TempDir d("export-ensemble");
            const std::string cfg = write_file(d, "tiny.toml",
                                               "[system]\nkind = \"missile\"\n[filter]\nt_final = 3.0\nvariant = \"gain\"\n"
                                               "[network]\nhidden = [8, 8]\nprecision = \"double\"\n[training]\nsamples = 50\n"
                                               "batch = 20\nadam_steps = 2\ncheckpoint_every = 5\n");
            Compared c = export_and_compare(d, cfg, "--until 0.1", "dnn_gain_ensemble", members);
            INFO("max |C - hinf| " << c.max_abs << " over states up to " << c.scale);
            CHECK(c.rows == 301);
            CHECK(c.compared == 301);
            CHECK(c.scale > 100);
            CHECK(c.max_abs <= 1e-11 * c.scale);
            const std::string code = hinf::test::read_text(d / "c/hinf_filter.c");
            for (int e = 0; e < members; ++e)
                CHECK(code.find("hinf_filter_m" + std::to_string(e) + "_theta[") != std::string::npos);
            CHECK(code.find("hinf_filter_m" + std::to_string(members) + "_") == std::string::npos);
            // the ensemble is not its first member: that network alone filters the record elsewhere
            auto f = run_hinf("filter " + cfg + " --network " + (d / "run1/checkpoint.h5") + " --measurements " +
                              (d / "record.csv") + " --quiet --out " + (d / "one"));
            REQUIRE(f.status == 0);
            hinf::h5::Handle h1 = hinf::h5::open_file(d / "one/estimates.h5", false);
            hinf::h5::Handle hE = hinf::h5::open_file(d / "flt/estimates.h5", false);
            const std::vector<double> one = hinf::h5::read_doubles(
                hinf::h5::open_group(h1.get(), "dnn_gain_measured").get(), "xhat");
            const std::vector<double> ens = hinf::h5::read_doubles(
                hinf::h5::open_group(hE.get(), "dnn_gain_ensemble").get(), "xhat");
            REQUIRE(one.size() == ens.size());
            double apart = 0;
            for (std::size_t i = 0; i < one.size(); ++i) apart = std::max(apart, std::fabs(one[i] - ens[i]));
            INFO("the first member alone against the ensemble: " << apart);
            CHECK(apart > 1e3 * c.max_abs);
        }
    }
}

TEST_CASE("hinf export: bad use is one line", "[export][cli]") {
    TempDir d("export-bad");
    expect_one_line_error("export " + (d / "missing.h5") + " --c " + (d / "c"), "missing.h5");
    const std::string cfg = write_file(d, "tiny.toml", hinf::test::tiny_missile_config());
    REQUIRE(run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet").status == 0);
    expect_one_line_error("export " + (d / "run/checkpoint.h5") + " --c " + (d / "c") + " --name 2bad",
                          "is not a C identifier");
    // a state named like a C keyword cannot become a C local
    const std::string kw = write_file(d, "kw.toml",
                                      "[system]\nkind = \"expr\"\nstates = [\"int\"]\nmeasurements = 1\nf = [\"-int\"]\n"
                                      "g = [[\"1\"]]\nh = [\"int\"]\n[filter]\nQ = [1.0]\nx0 = [1.0]\nxhat0 = [0.0]\n"
                                      "dt = 0.01\nt_final = 0.02\n[network]\nhidden = [4]\n[training]\nsamples = 20\nbatch = 10\n"
                                      "adam_steps = 1\ncheckpoint_every = 1\n[online]\ndisturbance_std = 1\nnoise_std = 1\n");
    auto t = run_hinf("train " + kw + " --out " + (d / "kw") + " --quiet");
    INFO(t.output);
    REQUIRE(t.status == 0);
    expect_one_line_error("export " + (d / "kw/checkpoint.h5") + " --c " + (d / "c"), "the state 'int' is a C keyword");
    // ensembles: several checkpoints without --ensemble, --ensemble with one, a member of another model or variant
    auto g = run_hinf("train " + cfg + " --set filter.variant=gain --out " + (d / "gain") + " --quiet");
    REQUIRE(g.status == 0);
    const std::string gain = d / "gain/checkpoint.h5";
    expect_one_line_error("export " + gain + " " + gain + " --c " + (d / "c"), "add --ensemble");
    expect_one_line_error("export " + gain + " --ensemble --c " + (d / "c"), "two or more networks");
    expect_one_line_error("export " + gain + " " + (d / "kw/checkpoint.h5") + " --ensemble --c " + (d / "c"),
                          "trained on another model");
    expect_one_line_error("export " + gain + " " + (d / "run/checkpoint.h5") + " --ensemble --c " + (d / "c"),
                          "only variant \"gain\" networks");
    // the output directory is --out, as in every other command (--c, the first name, stays); none given: one line
    expect_one_line_error("export " + gain, "--out is required");
    auto out = run_hinf("export " + gain + " --out " + (d / "out"));
    INFO(out.output);
    REQUIRE(out.status == 0);
    REQUIRE(run_hinf("export " + gain + " --c " + (d / "c")).status == 0);
    CHECK(hinf::test::read_text(d / "out/hinf_filter.c") == hinf::test::read_text(d / "c/hinf_filter.c"));
}
