// The linearised game's smallest level rho* (src/config/game_level.cpp, docs/method.md section 16.12) against closed
// forms, and the default rho = 1.25 rho* of a system of one's own that names none (written into the effective config;
// older checkpoints keep the 0.03 they trained with).
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "config/game_level.hpp"
#include "config/run_config.hpp"
#include "filters/factory.hpp"
#include "helpers.hpp"
#include "hinf/config.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"

using namespace hinf;
using hinf::test::run_hinf;

namespace {
// x' = v (or x+ = x + v), y = x + n, Q = 1: one state, one disturbance, one output
std::string integrator(const std::string& time, const std::string& dt, const std::string& t_final,
                       const std::string& rho_line) {
    return "[system]\nkind = \"expr\"\ntime = \"" + time + "\"\nstates = [\"x\"]\ndisturbances = 1\nmeasurements = 1\n"
           "f = [\"" + std::string(time == "discrete" ? "x" : "0") + "\"]\ng = [[\"1\"]]\nh = [\"x\"]\n[filter]\n" +
           rho_line + "Q = [1.0]\nx0 = [1.0]\nxhat0 = [0.0]\ndt = " + dt + "\nt_final = " + t_final +
           "\n[online]\ndisturbance_std = 0.1\nnoise_std = 0.1\n";
}
using hinf::test::config_from_text;
}  // namespace

TEST_CASE("rho* of a continuous integrator is the escape level of its Riccati equation", "[config][rho]") {
    // P' = 1 - P^2 (1 - 1/rho), P(0) = 0: for rho < 1, P = tan(b t)/b with b^2 = 1/rho - 1 escapes at t = pi/(2b); over
    // [0, T] a filter of level rho exists iff pi/(2b) > T, so rho* = 1/(1 + pi^2/(4 T^2)) (0.97592 at T = 10)
    const RunConfig c = config_from_text(integrator("continuous", "0.001", "10", "rho = 1\n"));
    const double T = 10, want = 1.0 / (1.0 + M_PI * M_PI / (4 * T * T));
    const GameLevel g = game_level_bound(c, 1e-5);
    REQUIRE(g.bracketed);
    CHECK(g.bound == Approx(want).epsilon(2e-3));
    // at rho = 0.9 (b = 1/3) the equation escapes at t = 3 pi / 2
    CHECK(game_level_lost_at(c, 0.9) == Approx(1.5 * M_PI).epsilon(2e-3));
    CHECK(game_level_lost_at(c, 1.0) < 0);
}

TEST_CASE("rho*_on of a continuous integrator is rho* of four horizons", "[config][rho]") {
    // time-invariant: running the walk on over the horizon's second half 6 times is walking 4 T, so rho*_on =
    // 1/(1 + pi^2/(4 (4T)^2)) (0.99846 at T = 10, against rho* = 0.97592): the level tends to Q = 1, the floor that
    // noise of low frequency passes into the estimate of a marginally stable measured state
    const RunConfig c = config_from_text(integrator("continuous", "0.001", "10", "rho = 1\n"));
    const double T = 10, want = 1.0 / (1.0 + M_PI * M_PI / (4 * 16 * T * T));
    const GameLevel star = game_level_bound(c, 1e-5);
    const GameLevel on = game_level_sustained(c, star.bound);
    REQUIRE(on.bracketed);
    // (near 1 the escape time moves fast with the level: the sampled recursion sits 0.5 % from the closed form)
    CHECK(on.bound == Approx(want).epsilon(6e-3));
    CHECK(on.bound > star.bound * 1.02);
    // a level between them holds over [0, T] and fails past it: at 0.99 (b^2 = 1/99) at pi sqrt(99)/2 = 15.6 s
    CHECK(game_level_lost_at(c, 0.99) < 0);
    CHECK(game_level_lost_at(c, 0.99, kRunOnRepeats) == Approx(M_PI * std::sqrt(99.0) / 2).epsilon(1e-2));
    CHECK(game_level_lost_at(c, 1.01, kRunOnRepeats) < 0);
}

TEST_CASE("rho*_on of a system whose game settles within the horizon is rho*", "[config][rho]") {
    // x+ = x + v: the discrete random walk's P settles within a few steps, so its level needs nothing more where the
    // run goes on
    const RunConfig walk = config_from_text(integrator("discrete", "1", "200", "rho = 3\n"));
    const GameLevel g = game_level_bound(walk);
    CHECK(game_level_sustained(walk, g.bound).bound == g.bound);
}

TEST_CASE("rho*_on of a system with an unseen unstable state is not bracketed and hinf rho says so", "[config][rho][cli]") {
    // a' = a + v1 grows unseen (y = b + n): over [0, T] its error's energy is finite, rho* ~ e^(2T) (2e6 at T = 8), but
    // over four horizons e^(8T) passes every level tried (1e15): no filter keeps a level where the run goes on
    const std::string text = "[system]\nkind = \"expr\"\nstates = [\"a\", \"b\"]\ndisturbances = 2\nmeasurements = 1\n"
                             "f = [\"a\", \"-b\"]\ng = [[\"1\", \"0\"], [\"0\", \"1\"]]\nh = [\"b\"]\n[filter]\n"
                             "Q = [1.0, 1.0]\nx0 = [0.0, 1.0]\nxhat0 = [0.0, 0.0]\ndt = 0.01\nt_final = 8\n"
                             "[online]\ndisturbance_std = 0.1\nnoise_std = 0.1\n";
    const RunConfig c = config_from_text(text);
    REQUIRE(c.rho_auto);
    REQUIRE(c.rho_bound > 1e5);
    CHECK(c.rho_bound < 1e8);
    CHECK(game_level_rho_run_on(c) == 0.0);
    hinf::test::TempDir d("rho-run-on-none");
    std::ofstream(d / "c.toml") << text;
    const auto r = run_hinf("rho " + (d / "c.toml"));
    INFO(r.output);
    REQUIRE(r.status == 0);
    CHECK(r.output.find("rho*_on: where the run goes on past t_final the game has no filter of any level tried") !=
          std::string::npos);
    CHECK(r.output.find("the outputs tell next to nothing about a") != std::string::npos);
}

TEST_CASE("a default level below rho*_on is said by train and by hinf rho", "[config][rho][cli]") {
    // the integrator over T = 2 s: rho* = 1/(1 + pi^2/16) = 0.619, the default 1.25 rho* = 0.773 is below rho*_on =
    // 1/(1 + pi^2/256) = 0.963; over T = 10 s the default 1.22 is above rho*_on = 0.998: no note
    hinf::test::TempDir d("rho-run-on");
    for (const char* t_final : {"2", "10"}) {
        std::ofstream(d / "c.toml") << integrator("continuous", "0.01", t_final, "");
        const RunConfig c = config_from_text(integrator("continuous", "0.01", t_final, ""));
        REQUIRE(c.rho_auto);
        CHECK(c.rho == kAutoRhoFactor * c.rho_bound);  // the default stays 1.25 rho* (section 16.12)
        const double run_on = game_level_rho_run_on(c);  // from the rho* loading walked
        CHECK(run_on >= c.rho_bound);
        const bool below = std::string(t_final) == "2";
        CHECK((run_on >= c.rho) == below);
        const auto r = hinf::test::run_hinf("train " + (d / "c.toml") + " --until 0.02 --quiet --force --out " +
                                            (d / "run"));
        INFO(r.output);
        REQUIRE(r.status == 0);
        char on[32];
        std::snprintf(on, sizeof on, "%.4g", run_on);
        CHECK((r.output.find(std::string("that level is at or below rho*_on = ") + on) != std::string::npos) == below);
        const auto rho = hinf::test::run_hinf("rho " + (d / "c.toml"));
        INFO(rho.output);
        REQUIRE(rho.status == 0);
        CHECK(rho.output.find("the game needs a higher level") != std::string::npos);  // an integrator never settles
        CHECK((rho.output.find("at or below rho*_on") != std::string::npos) == below);
    }
}

TEST_CASE("rho* walks at most the horizon's first kGameLevelMaxSteps steps", "[config][rho]") {
    // reading a config stays quick whatever its horizon: a longer one gives the rho* of its first part
    const RunConfig longer = config_from_text(integrator("continuous", "0.001", "30", "rho = 1\n"));  // 30000 steps
    const RunConfig first = config_from_text(integrator("continuous", "0.001", "20", "rho = 1\n"));   // 20000 steps
    REQUIRE(longer.steps_until() > kGameLevelMaxSteps);
    REQUIRE(first.steps_until() == kGameLevelMaxSteps);
    CHECK(game_level_bound(longer).bound == game_level_bound(first).bound);
}

TEST_CASE("a training at the default level says when rho* covered only the horizon's first part",
          "[config][rho][cli]") {
    hinf::test::TempDir d("rho-first-part");
    for (const char* t_final : {"30", "20"}) {  // 30000 steps, then 20000: walked whole
        std::ofstream(d / "c.toml") << integrator("continuous", "0.001", t_final, "");
        // the note is said before training; the validation runs after it (one run, no acceptance check) only cost
        // time: 30000 steps each, under the sanitizers a quarter of this test's
        const auto r = hinf::test::run_hinf("train " + (d / "c.toml") + " --until 0.002 --quiet --force --out " +
                                            (d / "run") + " --set training.select_runs=1 --set training.acceptance_runs=0");
        INFO(r.output);
        REQUIRE(r.status == 0);
        CHECK((r.output.find("over the horizon's first 20000 of 30000 steps") != std::string::npos) ==
              (std::string(t_final) == "30"));
    }
}

TEST_CASE("rho* of a discrete random walk is 2, above its one-step floor", "[config][rho]") {
    // P+ = (1/P + 1 - 1/rho)^-1 + 1 with the a-priori condition 1/P > 1/rho: the stationary P = 1/2 + sqrt(1/4 + 1/u),
    // u = 1 - 1/rho, equals rho exactly at rho = 2; below it the condition fails once P has settled, above it never
    const RunConfig c = config_from_text(integrator("discrete", "1", "200", "rho = 3\n"));
    const GameLevel g = game_level_bound(c, 1e-5);
    REQUIRE(g.bracketed);
    CHECK(g.bound == Approx(2.0).epsilon(1e-3));
    CHECK(g.bound > 1.0);  // the one-step floor lambda_max(B'Q B) = 1 (train refuses rho <= 1)
    CHECK(game_level_lost_at(c, 1.9) >= 0);
    CHECK(game_level_lost_at(c, 2.1) < 0);
}

TEST_CASE("a system of one's own that names no rho trains at 1.25 rho*, and says so in its config (and Q = I)",
          "[config][rho]") {
    const RunConfig given = config_from_text(integrator("continuous", "0.01", "10", "rho = 0.7\n"));
    CHECK_FALSE(given.rho_auto);
    CHECK(given.rho == 0.7);
    const RunConfig c = config_from_text(integrator("continuous", "0.01", "10", ""));
    REQUIRE(c.rho_auto);
    CHECK(c.rho_bound == game_level_bound(given).bound);
    CHECK(c.rho == kAutoRhoFactor * c.rho_bound);
    // the effective config names the value: a checkpoint carries it, and loading that text gives the same rho
    const RunConfig again = config_from_text(c.doc.text());
    CHECK_FALSE(again.rho_auto);
    CHECK(again.rho == c.rho);
    // the missiles keep their papers' 0.03 and Q = 1e-5 I; a system of one's own naming no Q weighs its states alike
    const RunConfig missile = config_from_text("[system]\nkind = \"missile\"\n");
    CHECK(missile.rho == 0.03);
    CHECK(missile.Q[0] == 1e-5);
    std::string no_q = integrator("continuous", "0.01", "10", "");
    no_q.replace(no_q.find("Q = [1.0]\n"), 10, "");
    const RunConfig own = config_from_text(no_q);
    CHECK(own.Q == std::vector<double>{1.0});
    CHECK(config_from_text(own.doc.text()).Q == std::vector<double>{1.0});
    CHECK(ConfigSection(own.doc, "filter").has("Q"));
}

TEST_CASE("compare and filter without glf skip rho* for a config naming no rho", "[config][rho]") {
    // rho* is a Riccati walk per level tried, n^3 a step (6 s for 100 states): only the GLF, of what compare and
    // filter build, designs at [filter] rho (a DNN filter reads its checkpoint's)
    CHECK_FALSE(filters_need_level("ekf,ukf,pf,open_loop,dnn"));
    CHECK(filters_need_level("ekf,glf"));
    CHECK_FALSE(filters_need_level("glfx"));
    const std::string text = integrator("continuous", "0.01", "10", "");
    const RunConfig skipped = load_run_config(ConfigDoc::from_text(text, "own.toml"), false);
    CHECK_FALSE(skipped.rho_auto);
    CHECK(skipped.rho == 0.0);
    CHECK(skipped.rho_unset.find("this command did not compute the default") != std::string::npos);
    CHECK_FALSE(ConfigSection(skipped.doc, "filter").has("rho"));
    CHECK(load_run_config(ConfigDoc::from_text(text, "own.toml")).rho_auto);  // the default computes it
    // end to end: compare runs the EKF and writes no level into its effective config; with glf it designs at 1.25 rho*
    hinf::test::TempDir d("rho_skip");
    const std::string path = (d / "own.toml");
    {
        std::ofstream(path) << text;
    }
    auto cmp = run_hinf("compare " + path + " --filters ekf --runs 1 --quiet --out " + (d / "cmp"));
    INFO(cmp.output);
    REQUIRE(cmp.status == 0);
    auto glf = run_hinf("compare " + path + " --filters ekf,glf --runs 1 --quiet --out " + (d / "glf"));
    INFO(glf.output);
    REQUIRE(glf.status == 0);
    const auto effective = [](const std::string& file) {
        h5::Handle f = h5::open_file(file, false);
        return h5::read_string(f.get(), "config");
    };
    CHECK(effective(d / "cmp/compare.h5").find("rho =") == std::string::npos);
    CHECK(effective(d / "glf/compare.h5").find("rho =") != std::string::npos);
}

TEST_CASE("a system whose game gives no level: train refuses a config naming no rho, the other filters run",
          "[config][rho]") {
    // g = 0: no disturbance reaches the state, so the game has a filter of every level
    const std::string path = test::source_path("tests/corpus/bad/rho_no_level.toml");
    const RunConfig c = load_run_config(ConfigDoc::from_file(path));
    CHECK(c.rho_auto);
    CHECK(c.rho == 0.0);
    CHECK(c.rho_unset.find("no default follows from it") != std::string::npos);
    CHECK_FALSE(ConfigSection(c.doc, "filter").has("rho"));
    hinf::test::TempDir d("rho_none");
    auto cmp = run_hinf("compare " + path + " --filters ekf,ukf --runs 1 --quiet --out " + (d / "cmp"));
    INFO(cmp.output);
    CHECK(cmp.status == 0);
    hinf::test::expect_one_line_error("compare " + path + " --filters glf --runs 1 --quiet --out " + (d / "glf"),
                                      "no default follows from it");
    hinf::test::expect_one_line_error("rho " + path + " --rho -1", "--rho -1: must be > 0");
}

TEST_CASE("a checkpoint of a system naming no rho (or no Q), written before the defaults, keeps what it trained with",
          "[config][rho][legacy]") {
    hinf::test::TempDir d("rho_legacy");
    for (const bool names_q : {true, false}) {
        INFO("the config names Q: " << names_q);
        std::string plain = integrator("continuous", "0.01", "0.2", "") +
                            "[network]\nhidden = [8]\n[training]\nsamples = 40\nbatch = 20\nadam_steps = 2\n"
                            "checkpoint_every = 10\nacceptance_runs = 0\nselect_every = 0\n";
        if (!names_q) plain.replace(plain.find("Q = [1.0]\n"), 10, "");
        // made here: a run at rho = 0.03 (and the missile's Q = 1e-5), its config put back to the text without them,
        // as the hinf before wrote it
        std::string with = plain;
        with.replace(with.find("[filter]\n"), 9, names_q ? "[filter]\nrho = 0.03\n" : "[filter]\nrho = 0.03\nQ = [1e-5]\n");
        const std::string tag = names_q ? "q" : "noq", run = d / ("run_" + tag);
        auto t = run_hinf("train " + hinf::test::write_file(d, tag + ".toml", with) + " --until 0.1 --out " + run +
                          " --quiet");
        INFO(t.output);
        REQUIRE(t.status == 0);
        const std::string ck = run + "/checkpoint.h5";
        {
            h5::Handle f = h5::open_file(ck, true);
            REQUIRE(H5Ldelete(f.get(), "config", H5P_DEFAULT) >= 0);
            h5::write_string(f.get(), "config", plain);
            REQUIRE(H5Adelete(f.get(), "config_hash") >= 0);
            h5::set_attr(f.get(), "config_hash", config_hash(plain));
            REQUIRE(H5Adelete(f.get(), "content_digest") >= 0);
            for (const char* name : {"/trajectory.h5", "/trajectory.ckpt.h5"})
                if (std::filesystem::exists(run + name))
                    h5::set_text(h5::open_file(run + name, true).get(), "config", plain);
        }
        std::vector<std::string> want = {"filter.rho=0.03"};
        if (!names_q) want.push_back("filter.Q=[1e-05]");
        CHECK(ckpt_as_trained(ck) == want);
        const RunConfig c = ckpt_config(ck);
        CHECK(c.rho == 0.03);
        CHECK(c.Q == std::vector<double>{names_q ? 1.0 : 1e-5});
        // without the record it would load at 1.25 rho* (and Q = I) and fail its scale check; with it, it resumes
        // and compares
        auto r = run_hinf("resume " + ck + " --until 0.2 --quiet");
        INFO(r.output);
        CHECK(r.status == 0);
        auto cmp = run_hinf("compare " + hinf::test::write_file(d, tag + "_plain.toml", plain) + " --network " + ck +
                            " --filters dnn --runs 1 --quiet --out " + (d / ("cmp_" + tag)));
        INFO(cmp.output);
        CHECK(cmp.status == 0);
    }
}

namespace {
// an oscillator whose stiffness s is estimated as a state: x' = v, v' = -s x - 0.2 v + w, s' = `ds`, with `gs` the
// disturbance's row for s
std::string oscillator(const std::string& time, const std::string& ds, const std::string& gs, const std::string& q) {
    const bool discrete = time == "discrete";
    return "[system]\nkind = \"expr\"\ntime = \"" + time + "\"\nstates = [\"x\", \"v\", \"s\"]\ndisturbances = 1\n"
           "measurements = 1\nf = [" + (discrete ? "\"x + 0.01*v\", \"v - 0.01*(s*x + 0.2*v)\", " : "\"v\", \"-s*x - 0.2*v\", ") +
           "\"" + ds + "\"]\ng = [[\"0\"], [\"1\"], [\"" + gs + "\"]]\nh = [\"x\"]\n[filter]\n" + q +
           "x0 = [1.0, 0.0, 2.0]\nxhat0 = [0.8, 0.2, 1.0]\ndt = 0.01\nt_final = 2\n[online]\ndisturbance_std = 0.2\n"
           "noise_std = 0.05\n";
}
}  // namespace

TEST_CASE("constant_states finds a parameter estimated as a state and nothing else", "[config][rho]") {
    CHECK(constant_states(config_from_text(oscillator("continuous", "0", "0", ""))) == std::vector<int>{2});
    CHECK(constant_states(config_from_text(oscillator("discrete", "s", "0", ""))) == std::vector<int>{2});
    // a disturbance that reaches it, a drift however small, or a discrete map that moves it: not constant
    CHECK(constant_states(config_from_text(oscillator("continuous", "0", "0.01", ""))).empty());
    CHECK(constant_states(config_from_text(oscillator("continuous", "1e-6*x", "0", ""))).empty());
    CHECK(constant_states(config_from_text(oscillator("discrete", "0.999*s", "0", ""))).empty());
    // a state with no drift that the disturbance drives (the integrator above) is not a parameter
    CHECK(constant_states(config_from_text(integrator("continuous", "0.01", "1", "rho = 1\n"))).empty());
}

TEST_CASE("train notes a constant state under the default Q and names the Q that leaves it out", "[config][rho][cli]") {
    hinf::test::TempDir d("constant-state");
    const std::string note = "state s is constant in the model";
    for (const bool q_named : {false, true}) {
        const std::string path = d / (q_named ? "named.toml" : "default.toml");
        std::ofstream(path) << oscillator("continuous", "0", "0", q_named ? "Q = [1.0, 1.0, 1.0]\n" : "");
        auto r = run_hinf("train " + path + " --until 0.03 --quiet --out " + (d / (q_named ? "named" : "default")));
        INFO(r.output);
        REQUIRE(r.status == 0);
        if (q_named) {
            CHECK(r.output.find(note) == std::string::npos);  // the user's own Q is the user's choice
        } else {
            CHECK(r.output.find(note) != std::string::npos);
            CHECK(r.output.find("--set 'filter.Q=[1, 1, 0]'") != std::string::npos);
        }
    }
}
