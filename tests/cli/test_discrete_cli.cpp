// Discrete-time systems end to end: compare, filter (recorded data) and worst run a small discrete config; the
// `gain` variant trains on it and its filter runs in compare with a filtered estimate; the other variants, their
// DNN filter and the GLF refuse it in one line (they are continuous-time only), as does a rho below the one-step
// game's floor.
#include <catch2/catch.hpp>
#include <cmath>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>

#include "helpers.hpp"
#include "hinf/h5.hpp"

using hinf::test::expect_one_line_error;
using hinf::test::run_hinf;
using hinf::test::TempDir;
using hinf::test::write_file;

namespace {

const char* kSmallUngm = R"toml([system]
kind = "expr"
time = "discrete"
states = ["x"]
measurements = 1
f = ["0.5*x + 25*x/(1 + x^2) + 8*cos(1.2*k)"]
g = [["1"]]
h = ["x^2/20"]
[filter]
x0 = [0.1]
xhat0 = [0.1]
dt = 1
t_final = 40
[online]
disturbance_std = 1
noise_std = 1
)toml";

// a linear discrete system for variant gain (tests/train/test_gain_discrete.cpp trains it longer)
const char* kLinearGain = R"toml([system]
kind = "expr"
time = "discrete"
states = ["a", "b"]
disturbances = 1
measurements = 1
f = ["1.05*a + 0.2*b", "-0.1*a + 0.9*b"]
g = [["0.5"], ["1"]]
h = ["a + c*b"]
[system.parameters]
c = 0.5
[filter]
variant = "gain"
Q = [1.0, 1.0]
x0 = [1, -1]
xhat0 = [0, 0]
dt = 1
t_final = 40
[online]
disturbance_std = 0.3
noise_std = 0.3
[network]
hidden = [8]
[training]
samples = 64
batch = 32
adam_steps = 2
acceptance_runs = 1
)toml";

}  // namespace

TEST_CASE("discrete systems through compare, filter and worst, and their refusals in one line", "[cli][discrete]") {
    TempDir d("cli-discrete");
    const std::string cfg = write_file(d, "ungm.toml", kSmallUngm);

    auto c = run_hinf("compare " + cfg + " --filters ekf,ukf,pf,open_loop --runs 3 --particles 200 --quiet --out " +
                      (d / "cmp"));
    INFO(c.output);
    REQUIRE(c.status == 0);
    CHECK(c.output.find("40 steps") != std::string::npos);
    {
        hinf::h5::Handle f = hinf::h5::open_file(d / "cmp/compare.h5", false);
        CHECK(hinf::h5::get_attr_string(f.get(), "system_time") == "discrete");
        // the published tables' metric: 10 log10 of the mean over runs of each run's MSE (states and steps)
        for (const char* name : {"ekf", "ukf", "pf", "open_loop"}) {
            INFO(name);
            hinf::h5::Handle g = hinf::h5::open_group(f.get(), name);
            for (const char* which : {"mse", "mse_filtered"}) {
                const std::vector<double> per_run = hinf::h5::read_doubles(g.get(), std::string(which) + "_per_run");
                REQUIRE(per_run.size() == 3u);
                const double mean = (per_run[0] + per_run[1] + per_run[2]) / 3.0;
                CHECK(hinf::h5::get_attr_double(g.get(), which) == Approx(mean).epsilon(1e-12));
                CHECK(hinf::h5::get_attr_double(g.get(), std::string(which) + "_db") ==
                      Approx(10.0 * std::log10(mean)).epsilon(1e-12));
            }
        }
        // the open-loop predictor has no measurement update: its filtered estimate is its prediction
        hinf::h5::Handle ol = hinf::h5::open_group(f.get(), "open_loop");
        CHECK(hinf::h5::get_attr_double(ol.get(), "mse_filtered") == hinf::h5::get_attr_double(ol.get(), "mse"));
    }
    CHECK(c.output.find("MSEf[dB]") != std::string::npos);

    // recorded data: y_k = k / 10 stamped every dt = 1 s
    std::ostringstream rec;
    rec << "t,y\n";
    for (int k = 0; k < 20; ++k) rec << k << ',' << 0.1 * k << '\n';
    const std::string csv = write_file(d, "rec.csv", rec.str());
    auto f = run_hinf("filter " + cfg + " --measurements " + csv + " --filters ekf,ukf,pf --particles 100 --quiet --out " +
                      (d / "flt"));
    INFO(f.output);
    REQUIRE(f.status == 0);
    CHECK(f.output.find("20 measurements") != std::string::npos);
    {
        hinf::h5::Handle e = hinf::h5::open_file(d / "flt/estimates.h5", false);
        hinf::h5::Handle g = hinf::h5::open_group(e.get(), "ekf");
        CHECK(hinf::h5::read_doubles(g.get(), "xhat_filtered").size() == 20u);
        CHECK(hinf::h5::get_attr_string(e.get(), "system_time") == "discrete");
    }

    auto w = run_hinf("worst " + cfg + " --filters ekf,open_loop --evals 8 --random-starts 1 --scenario-starts nominal "
                      "--quiet --out " + (d / "w"));
    INFO(w.output);
    REQUIRE(w.status == 0);

    // refusals: training but variant gain, a record sampled at another rate, the GLF, the DNN filter
    expect_one_line_error("train " + cfg + " --set filter.variant=dissipative --out " + (d / "t") + " --quiet",
                          "trains the continuous-time game; for a discrete-time system use [filter] variant");
    // variant gain trains the one-step inequality (rho above the floor lambda_max(B'QB) = 1.25) and filters
    const std::string gcfg = write_file(d, "linear_gain.toml", kLinearGain);
    // (a config naming no rho now trains at 1.25 rho*, above the floor: the refusal needs a rho named below it)
    expect_one_line_error("train " + gcfg + " --set filter.rho=0.03 --out " + (d / "t") + " --quiet",
                          "the discrete one-step game's floor");
    auto tg = run_hinf("train " + gcfg + " --set filter.rho=6 --out " + (d / "gnet") + " --quiet");
    INFO(tg.output);
    REQUIRE(tg.status == 0);
    auto cg = run_hinf("compare " + gcfg + " --filters dnn,ekf --network " + (d / "gnet/checkpoint.h5") +
                       " --runs 2 --quiet --out " + (d / "gcmp"));
    INFO(cg.output);
    REQUIRE(cg.status == 0);
    {
        hinf::h5::Handle f = hinf::h5::open_file(d / "gcmp/compare.h5", false);
        hinf::h5::Handle g = hinf::h5::open_group(f.get(), "dnn_gain_measured");
        CHECK(std::isfinite(hinf::h5::get_attr_double(g.get(), "mse_filtered")));
        CHECK(hinf::h5::get_attr_double(g.get(), "mse_filtered") != hinf::h5::get_attr_double(g.get(), "mse"));
    }
    // the gain network filters with the model in its checkpoint (c = 0.5), whatever the config's parameters say
    std::ostringstream grec;
    grec << "t,y\n";
    for (int k = 0; k < 30; ++k) grec << k << ',' << std::sin(0.3 * k) << '\n';
    const std::string gcsv = write_file(d, "grec.csv", grec.str());
    std::vector<double> xh[2];
    for (int i = 0; i < 2; ++i) {
        const std::string out = d / ("gflt" + std::to_string(i));
        auto gf = run_hinf("filter " + gcfg + " --measurements " + gcsv + " --filters dnn --network " +
                           (d / "gnet/checkpoint.h5") + (i == 1 ? " --set system.parameters.c=0.9" : "") +
                           " --quiet --out " + out);
        INFO(gf.output);
        REQUIRE(gf.status == 0);
        hinf::h5::Handle e = hinf::h5::open_file(out + "/estimates.h5", false);
        hinf::h5::Handle g = hinf::h5::open_group(e.get(), "dnn_gain_measured");
        xh[i] = hinf::h5::read_doubles(g.get(), "xhat");
    }
    REQUIRE(xh[0].size() == 60u);
    CHECK(hinf::test::bitwise_equal(xh[0], xh[1]));
    // the same system written in continuous time: the one-step predictor's gain means something else there
    std::string cont_text = kLinearGain;
    cont_text.erase(cont_text.find("time = \"discrete\"\n"), 18);
    const std::string gcont = write_file(d, "linear_gain_cont.toml", cont_text);
    expect_one_line_error("compare " + gcont + " --filters dnn --network " + (d / "gnet/checkpoint.h5") +
                              " --runs 1 --quiet --out " + (d / "gc"),
                          "is a discrete-time one-step predictor");
    std::ostringstream fast;
    fast << "t,y\n";
    for (int k = 0; k < 5; ++k) fast << 0.5 * k << ",1\n";
    expect_one_line_error("filter " + cfg + " --measurements " + write_file(d, "fast.csv", fast.str()) +
                              " --filters ekf --quiet --out " + (d / "f2"),
                          "set dt to the record's period");
    expect_one_line_error("compare " + cfg + " --filters ekf,glf --runs 1 --quiet --out " + (d / "g"),
                          "the GLF design is for continuous-time systems");
    const std::string cont = write_file(d, "cont.toml",
                                        "[system]\nkind = \"expr\"\nstates = [\"x\"]\nmeasurements = 1\nf = [\"-x\"]\n"
                                        "g = [[\"1\"]]\nh = [\"x\"]\n[filter]\nx0 = [1]\nxhat0 = [0]\ndt = 0.01\nt_final = 0.03\n"
                                        "[online]\ndisturbance_std = 1\nnoise_std = 1\n[network]\nhidden = [8]\n[training]\nsamples = 50\nbatch = 20\nadam_steps = 2\n");
    auto t = run_hinf("train " + cont + " --out " + (d / "net") + " --quiet");
    INFO(t.output);
    REQUIRE(t.status == 0);
    expect_one_line_error("compare " + cfg + " --filters dnn --network " + (d / "net/checkpoint.h5") +
                              " --runs 1 --quiet --out " + (d / "dn"),
                          "is a continuous-time (Euler-sampled) filter");
    expect_one_line_error("operate " + cfg + " --network " + (d / "net/checkpoint.h5") + " --runs 1 --quiet --out " +
                              (d / "op"),
                          "is a continuous-time (Euler-sampled) filter");
}

TEST_CASE("the benchmark configs run: runs/ungm.toml and scripts/benchmark-lorenz on one cell", "[cli][discrete][benchmarks]") {
    TempDir d("cli-bench");
    auto u = run_hinf("compare " + hinf::test::source_path("runs/ungm.toml") +
                      " --filters ekf,ukf,pf --particles 100 --runs 2 --until 50 --quiet --out " + (d / "ungm"));
    INFO(u.output);
    REQUIRE(u.status == 0);
    // one cell of the Lorenz process-mismatch table: EKF told J = 2, q tuned over a two-value grid
    auto l = hinf::test::run_command("cd " + hinf::test::source_path("") + " && /usr/bin/python3 scripts/benchmark-lorenz"
                                     " --hinf " + std::string(HINF_CLI_PATH) + " --table process --rows ekf_J2 --columns 0"
                                     " --runs 1 --tune-runs 1 --grid 1,10 --out " + (d / "lorenz"));
    INFO(l.output);
    REQUIRE(l.status == 0);
    CHECK(l.output.find("baseline.parameters.c3=0") != std::string::npos);
    CHECK(l.output.find("| EKF (told J = 2) | -10.36 / ") != std::string::npos);
    std::ifstream csv(d / "lorenz/lorenz_process.csv");
    std::string header, row;
    std::getline(csv, header);
    std::getline(csv, row);
    CHECK(header.rfind("table,row,column_db,published_db,hinf_db", 0) == 0);
    CHECK(row.rfind("process,ekf_J2,0,-10.36,", 0) == 0);
}

TEST_CASE("scripts/benchmark-lorenz's DNN row tunes rho and the training seed and the told q together", "[cli][discrete][benchmarks]") {
    // two candidates (seeds 1 and 2 at q_told = 0.5 q), each trained for 10 steps: the script must pass the seed and
    // the told q to hinf train, score both on validation (and, with --dnn-test-all, on the test runs), and keep the
    // one with the lower validation MSE
    TempDir d("cli-bench-dnn");
    auto l = hinf::test::run_command("cd " + hinf::test::source_path("") + " && /usr/bin/python3 scripts/benchmark-lorenz"
                                     " --hinf " + std::string(HINF_CLI_PATH) + " --table observation --rows dnn_rotH --dnn"
                                     " --columns 0 --runs 1 --tune-runs 1 --dnn-rho-grid 16 --dnn-seeds 1,2 --dnn-q-grid 0.5"
                                     " --dnn-test-all --dnn-train-set filter.t_final=0.2 --out " + (d / "lorenz"));
    INFO(l.output);
    REQUIRE(l.status == 0);
    CHECK(l.output.find("--set training.seed=2") != std::string::npos);
    CHECK(l.output.find("--set filter.t_final=0.2") != std::string::npos);
    // 0 dB: r = 1, q = 0.1, so the told q is 0.05
    CHECK(l.output.find("--set online.disturbance_std=0.050000000000000003") != std::string::npos);
    std::smatch m;
    std::map<int, double> val;
    std::string rest = l.output;
    const std::regex cand("rho = 16, seed (\\d), q_told = 0\\.5 q: (-?[0-9.]+) dB \\(0 diverged\\), test -?[0-9.]+ dB");
    while (std::regex_search(rest, m, cand)) {
        val[std::stoi(m[1])] = std::stod(m[2]);
        rest = m.suffix();
    }
    REQUIRE(val.size() == 2);
    REQUIRE(val[1] != val[2]);
    const int kept = val[1] < val[2] ? 1 : 2;
    CHECK(l.output.find("seed " + std::to_string(kept) + ", q_told = 0.5 q, 0 diverged") != std::string::npos);
    std::ifstream csv(d / "lorenz/lorenz_observation.csv");
    std::string header, row;
    std::getline(csv, header);
    std::getline(csv, row);
    CHECK(header.find(",training_seed,dnn_q_multiple") != std::string::npos);
    CHECK(row.rfind("observation,dnn_rotH,0,nan,", 0) == 0);
    CHECK(row.find("," + std::to_string(kept) + ",0.5") != std::string::npos);

    // bad input: one line and a non-zero exit, never a traceback
    const std::string script = "cd " + hinf::test::source_path("") + " && /usr/bin/python3 scripts/benchmark-lorenz --hinf " +
                               std::string(HINF_CLI_PATH) + " --out " + (d / "bad");
    auto no_dnn = hinf::test::run_command(script + " --table observation --dnn-seeds 1,2");
    CHECK(no_dnn.status != 0);
    CHECK(no_dnn.output.find("--dnn-seeds: for the DNN row only; add --dnn") != std::string::npos);
    auto bad_seed = hinf::test::run_command(script + " --dnn --table observation --dnn-seeds 1,x");
    CHECK(bad_seed.status != 0);
    CHECK(bad_seed.output.find("--dnn-seeds '1,x' must be comma-separated integers >= 0") != std::string::npos);
    auto bad_set = hinf::test::run_command(script + " --table observation --rows dnn_rotH --dnn --columns 0 --runs 1"
                                                    " --tune-runs 1 --dnn-rho-grid 16 --dnn-train-set filter.nokey=1");
    CHECK(bad_set.status != 0);
    CHECK(bad_set.output.find("failed with exit status 2 (its message is above)") != std::string::npos);
    CHECK(bad_set.output.find("Traceback") == std::string::npos);
    // a row no table has (it once ran nothing and ended in a traceback writing an empty CSV)
    auto bad_row = hinf::test::run_command(script + " --table observation --rows dnn --dnn");
    CHECK(bad_row.status != 0);
    CHECK(bad_row.output.find("--rows dnn: not a row of the observation table (rows: ekf_trueH, ekf_rotH, ukf_rotH, "
                              "dnn_rotH)") != std::string::npos);
    CHECK(bad_row.output.find("Traceback") == std::string::npos);
}
