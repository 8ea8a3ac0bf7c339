// The line after a FAILed acceptance check ("acceptance: next: ..."): each branch from what the check measured.
// The level against rho* (hinf rho), the run's Adam updates, and what the worst-case search found: a ratio above a
// feasible rho (a higher level suggested), a divergence (said; on a discrete-time system with the direct gain head,
// the Kalman-form head offered), nothing found (no level advice); where the worst signals drove the true state far
// beyond the region training's estimates covered, that said (worst_outside_training).
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>

#include "config/game_level.hpp"
#include "eval/acceptance.hpp"
#include "eval/worst.hpp"

using namespace hinf;

namespace {

// x' = -x + v, y = x + n: rho* of this scalar system is a few tenths (hinf rho); 200 steps of 0.01 s
RunConfig scalar(const std::string& rho, const std::string& training = "") {
    return load_run_config(ConfigDoc::from_text(
        "[system]\nkind = \"expr\"\nstates = [\"x\"]\ndisturbances = 1\nmeasurements = 1\nf = [\"-x\"]\n"
        "g = [[\"1\"]]\nh = [\"x\"]\n[filter]\nvariant = \"gain\"\nrho = " + rho +
            "\nQ = [1.0]\nx0 = [1.0]\nxhat0 = [0.0]\ndt = 0.01\nt_final = 2\n[training]\n" + training +
            "[online]\ndisturbance_std = 1\nnoise_std = 1\n",
        "scalar.toml"));
}

bool has(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

}  // namespace

TEST_CASE("acceptance advice names a higher level when the search broke a feasible one", "[acceptance]") {
    const RunConfig c = scalar("2", "adam_steps = 200\n");  // 40 000 updates: not a short run
    const double star = game_level_rho_star(c);
    REQUIRE(star > 0);
    REQUIRE(star < 0.5);  // rho = 2 is feasible, so 4 rho* < 2 rho: twice rho is suggested
    AcceptanceSearch s;
    s.ran = true;
    s.ratio = 7.5;
    const std::string a = acceptance_advice(c, "run/best.h5", s);
    INFO(a);
    CHECK(a.rfind("acceptance: next:", 0) == 0);
    CHECK(has(a, "the worst-case search found a ratio of 7.5 above rho = 2"));
    CHECK(has(a, "--set filter.rho=4 (twice rho)"));
    CHECK(has(a, "a level kept is not a lower worst case"));  // the orbit: a higher level trained, a higher worst case
    CHECK_FALSE(has(a, "at or below rho*"));
    CHECK_FALSE(has(a, "Adam updates"));
    CHECK(has(a, "hinf compare CONFIG --network run/best.h5 --filters dnn,ekf,ukf"));
    CHECK_FALSE(has(a, "knot count"));
    s.small_signal = true;  // the ratio the linear start found: said as such, with the knot count to compare
    const std::string sm = acceptance_advice(c, "run/best.h5", s);
    INFO(sm);
    CHECK(has(sm, "found a ratio of 7.5 (for small signals) above rho = 2"));
    REQUIRE(c.storage_knots == 32);  // the gain variant's default on a continuous-time system
    CHECK(has(sm, "interpolated between its 32 knots"));
    CHECK(has(sm, "hinf sweep CONFIG --vary network.storage_knots=32,64,128 --worst"));
    CHECK(has(sm, "hinf sweep CONFIG --vary objective.h2_weight=0.1,0 --worst"));
    // a constant storage has no knots to count
    const RunConfig flat = load_run_config(ConfigDoc::from_text(
        "[system]\nkind = \"expr\"\nstates = [\"x\"]\ndisturbances = 1\nmeasurements = 1\nf = [\"-x\"]\n"
        "g = [[\"1\"]]\nh = [\"x\"]\n[filter]\nvariant = \"gain\"\nrho = 2\nQ = [1.0]\nx0 = [1.0]\nxhat0 = [0.0]\n"
        "dt = 0.01\nt_final = 2\n[network]\nstorage_knots = 0\n[training]\nadam_steps = 200\n[online]\n"
        "disturbance_std = 1\nnoise_std = 1\n",
        "flat.toml"));
    const std::string fa = acceptance_advice(flat, "run/best.h5", s);
    INFO(fa);
    CHECK_FALSE(has(fa, "knot count"));
    CHECK(has(fa, "objective.h2_weight=0.1,0"));  // the H2 term is still there to compare
    CHECK_FALSE(has(a, "H2 term"));  // a ratio found at the budget: neither cause named
    // neither knots nor an H2 term: nothing to name
    const RunConfig bare = load_run_config(ConfigDoc::from_text(
        "[system]\nkind = \"expr\"\nstates = [\"x\"]\ndisturbances = 1\nmeasurements = 1\nf = [\"-x\"]\n"
        "g = [[\"1\"]]\nh = [\"x\"]\n[filter]\nvariant = \"gain\"\nrho = 2\nQ = [1.0]\nx0 = [1.0]\nxhat0 = [0.0]\n"
        "dt = 0.01\nt_final = 2\n[network]\nstorage_knots = 0\n[training]\nadam_steps = 200\n[objective]\n"
        "h2_weight = 0\n[online]\ndisturbance_std = 1\nnoise_std = 1\n",
        "bare.toml"));
    const std::string ba = acceptance_advice(bare, "run/best.h5", s);
    INFO(ba);
    CHECK(has(ba, "found a ratio of 7.5 (for small signals)"));
    CHECK_FALSE(has(ba, "what was measured to move"));
    s.small_signal = false;

    // a level not far above rho* (1.8 rho*, above rho*_on = 1.58 rho* of this 2 s horizon): 4 rho* is the larger
    // suggestion
    const RunConfig near = scalar(std::to_string(1.8 * star), "adam_steps = 200\n");
    REQUIRE(near.rho > game_level_rho_run_on(near));
    const std::string b = acceptance_advice(near, "run/best.h5", s);
    INFO(b);
    CHECK(has(b, "(4 rho*, hinf rho)"));

    // the level broken, but far below the EKF's worst at a mean error near the EKF's: said, with the full search
    CHECK_FALSE(has(a, "more robust"));  // no EKF figure: nothing said
    s.ekf = 4 * 7.5;
    s.behind_ekf = 1.01;
    const std::string r = acceptance_advice(c, "run/best.h5", s);
    INFO(r);
    CHECK(has(r, "its worst case is 4 times lower (7.5 against 30,"));
    CHECK(has(r, "at 1.01 times the EKF's settled error: by this measurement the more robust of the two"));
    CHECK(has(r, "hinf worst CONFIG --network run/best.h5 --filters dnn,ekf,ukf --mode measured;"));
    CHECK(has(r, "higher level"));  // beside the level's advice, not in place of it
    s.ekf = 3.9 * 7.5;  // not far enough below
    CHECK_FALSE(has(acceptance_advice(c, "run/best.h5", s), "more robust"));
    s.ekf = 100;
    s.behind_ekf = 2.5;  // far behind in the mean: the EKF is the filter, said instead
    const std::string fb = acceptance_advice(c, "run/best.h5", s);
    CHECK_FALSE(has(fb, "more robust"));
    CHECK(has(fb, "the EKF or UKF is the filter for this system"));
    s.behind_ekf = 1.0;
    s.diverged = true;  // a filter that diverged under its worst signals is robust against nothing
    CHECK_FALSE(has(acceptance_advice(c, "run/best.h5", s), "more robust"));
    s.diverged = false;
    s.ekf = NAN;
    s.behind_ekf = NAN;

    // the search found nothing above rho (the Monte Carlo failed): no level advice
    s.ratio = 1.0;
    CHECK_FALSE(has(acceptance_advice(c, "run/best.h5", s), "higher level"));
    // no search ran
    CHECK_FALSE(has(acceptance_advice(c, "run/best.h5", AcceptanceSearch{}), "higher level"));
}

TEST_CASE("after a PASS far behind the EKF the note names a higher level and the comparison", "[acceptance]") {
    const RunConfig c = scalar("2");
    const double star = game_level_rho_star(c);
    REQUIRE(star > 0);
    const std::string a = acceptance_behind_note(c, "run/best.h5", 1.1, 1.69);
    INFO(a);
    // the larger of the two ratios first: a position close to the EKF's does not hide the other states
    CHECK(a.rfind("acceptance: note: the filter keeps rho = 2, but on these runs it settles at 1.69 times the EKF's "
                  "error (position 1.1x, all states Q-weighted 1.69x).", 0) == 0);
    CHECK(has(acceptance_behind_note(c, "run/best.h5", 2.5, 1.3), "settles at 2.5 times the EKF's error (position "
                                                                  "2.5x, all states Q-weighted 1.3x)"));
    CHECK(has(a, "--set filter.rho=4 (twice rho)"));  // 4 rho* < 2 rho here
    CHECK(has(a, "hinf compare CONFIG --network run/best.h5 --filters dnn,ekf,ukf"));
    const RunConfig near = scalar(std::to_string(1.25 * star));
    CHECK(has(acceptance_behind_note(near, "run/best.h5", 2.0, 2.0), "(4 rho*, hinf rho)"));
    // the states furthest behind, where the check found any
    CHECK(has(acceptance_behind_note(c, "run/best.h5", 1.1, 2.7, "om 2.8x, th 2.7x"),
              "(position 1.1x, all states Q-weighted 2.7x; furthest behind: om 2.8x, th 2.7x)."));
    CHECK(kBehindEkf == 1.25);
    // beyond kFarBehindEkf the note says, as the advice after a FAIL does, which filter to use meanwhile
    const std::string use_ekf = "the EKF or UKF is the filter for this system until a training does better";
    CHECK_FALSE(has(a, use_ekf));  // 1.69x
    CHECK(has(acceptance_behind_note(c, "run/best.h5", 2.5, 1.3), use_ekf));
    CHECK(has(acceptance_behind_note(c, "run/best.h5", 1.1, 7.0), use_ekf));
    CHECK_FALSE(has(acceptance_behind_note(c, "run/best.h5", kFarBehindEkf, 1.0), use_ekf));
}

TEST_CASE("acceptance advice says a divergence under the worst signals without offering a cure", "[acceptance]") {
    const RunConfig c = scalar("2");  // 200 steps x 30 Adam steps: a short run too
    AcceptanceSearch s;
    s.ran = true;
    s.ratio = 1e70;
    s.diverged = true;
    const std::string a = acceptance_advice(c, "run/best.h5", s);
    INFO(a);
    CHECK(has(a, "the filter diverged under the worst signals the search found"));
    CHECK_FALSE(has(a, "higher level"));
    CHECK(has(a, "this run made 6000 Adam updates (200 time steps x training.adam_steps = 30)"));
    CHECK_FALSE(has(a, "gain_head"));  // continuous time: no head to offer
}

TEST_CASE("acceptance advice after a divergence on the nominal noise says not to use the filter", "[acceptance]") {
    const RunConfig c = scalar("2");
    AcceptanceSearch s;
    s.ran = true;
    s.ratio = 1e70;
    s.diverged = true;
    s.nominal_diverged = 5;
    s.nominal_runs = 5;
    const std::string a = acceptance_advice(c, "run/best.h5", s);
    INFO(a);
    CHECK(has(a, "the filter diverged in 5 of the check's 5 runs on the [online] noise itself: do not use it"));
    CHECK(has(a, "No validated checkpoint"));
    CHECK_FALSE(has(a, "the filter diverged under the worst signals"));  // the nominal runs say more
    CHECK_FALSE(has(a, "higher level"));
    s.nominal_diverged = 0;
    CHECK_FALSE(has(acceptance_advice(c, "run/best.h5", s), "do not use it"));
}

TEST_CASE("acceptance advice far behind the EKF names the EKF before the level", "[acceptance]") {
    const RunConfig c = scalar("2", "adam_steps = 200\n");
    AcceptanceSearch s;
    s.ran = true;
    s.ratio = 7.5;  // above rho: the level advice follows
    s.behind_ekf = 9.68;
    const std::string a = acceptance_advice(c, "run/best.h5", s);
    INFO(a);
    CHECK(has(a, "on the check's runs it settles at 9.68 times the EKF's error: until a training does better, the "
                 "EKF or UKF is the filter for this system"));
    CHECK(a.find("9.68 times") < a.find("higher level"));
    s.behind_ekf = kFarBehindEkf;  // at the threshold, and NaN (a diverged run): not said
    CHECK_FALSE(has(acceptance_advice(c, "run/best.h5", s), "times the EKF's error"));
    s.behind_ekf = std::nan("");
    CHECK_FALSE(has(acceptance_advice(c, "run/best.h5", s), "times the EKF's error"));
    s.behind_ekf = 9.68;  // a divergence on the nominal noise says more: the settled figure is not repeated
    s.nominal_diverged = 1;
    s.nominal_runs = 5;
    const std::string b = acceptance_advice(c, "run/best.h5", s);
    CHECK(has(b, "do not use it"));
    CHECK_FALSE(has(b, "times the EKF's error"));
}

TEST_CASE("far behind the EKF with plain noise numbers, the advice and the note name the game in noise units",
          "[acceptance]") {
    // plain disturbance_std and noise_std: the game weighs their units alike, whatever the sensor's precision
    const RunConfig plain = scalar("2");
    std::string text = "[system]\nkind = \"expr\"\nstates = [\"x\"]\ndisturbances = 1\nmeasurements = 1\nf = [\"-x\"]\n"
                       "g = [[\"1\"]]\nh = [\"x\"]\n[filter]\nvariant = \"gain\"\nrho = 2\nQ = [1.0]\nx0 = [1.0]\n"
                       "xhat0 = [0.0]\ndt = 0.01\nt_final = 2\n[online]\ndisturbance_std = 1\nnoise_std = [0.25]\n";
    const RunConfig listed = load_run_config(ConfigDoc::from_text(text, "listed.toml"));
    REQUIRE_FALSE(listed.output_weight.empty());
    AcceptanceSearch s;
    s.ran = true;
    s.ratio = 1.0;
    s.behind_ekf = 9.68;
    const std::string units = "train the game in units of each channel's noise too, --set 'online.noise_std=[1]'";
    CHECK(has(acceptance_advice(plain, "run/best.h5", s), units));
    const std::string listed_advice = acceptance_advice(listed, "run/best.h5", s);
    REQUIRE(has(listed_advice, "times the EKF's error"));
    CHECK_FALSE(has(listed_advice, "units of each channel's noise"));
    s.behind_ekf = 1.5;  // not far behind: not said
    CHECK_FALSE(has(acceptance_advice(plain, "run/best.h5", s), "units of each channel's noise"));
    // the note after a PASS, likewise, its clauses joined by ';'
    const std::string note = acceptance_behind_note(plain, "run/best.h5", 2.5, 1.3);
    INFO(note);
    CHECK(has(note, "until a training does better; its game weighs a unit of disturbance like a unit of noise"));
    CHECK(note.back() == ')');
    CHECK_FALSE(has(acceptance_behind_note(plain, "run/best.h5", 1.3, 1.3), "units of each channel's noise"));
    const std::string listed_note = acceptance_behind_note(listed, "run/best.h5", 2.5, 1.3);
    REQUIRE(has(listed_note, "until a training does better"));  // the note is there, without the clause
    CHECK_FALSE(has(listed_note, "units of each channel's noise"));
}

TEST_CASE("acceptance advice offers the Kalman-form head after a divergence on a discrete-time system",
          "[acceptance][kalman]") {
    auto discrete = [](const std::string& head) {
        return load_run_config(ConfigDoc::from_text(
            "[system]\nkind = \"expr\"\ntime = \"discrete\"\nstates = [\"x\"]\ndisturbances = 1\nmeasurements = 1\n"
            "f = [\"0.9*x\"]\ng = [[\"1\"]]\nh = [\"x + 0.1*x^3\"]\n[filter]\nvariant = \"gain\"\nrho = 4\nQ = [1.0]\n"
            "x0 = [1.0]\nxhat0 = [0.0]\ndt = 1\nt_final = 50\n[network]\ngain_head = \"" + head + "\"\n"
            "[online]\ndisturbance_std = 1\nnoise_std = 1\n",
            "map.toml"));
    };
    AcceptanceSearch s;
    s.ran = true;
    s.ratio = 1e70;
    s.diverged = true;
    const std::string a = acceptance_advice(discrete("direct"), "run/best.h5", s);
    INFO(a);
    CHECK(has(a, "the filter diverged under the worst signals the search found"));
    CHECK(has(a, "--set network.gain_head=kalman"));
    // already the Kalman-form head, or no divergence: not offered
    CHECK_FALSE(has(acceptance_advice(discrete("kalman"), "run/best.h5", s), "gain_head"));
    s.diverged = false;
    s.ratio = 9.0;
    CHECK_FALSE(has(acceptance_advice(discrete("direct"), "run/best.h5", s), "gain_head"));
}

TEST_CASE("acceptance advice at a level below rho* names rho* and not a higher multiple of rho", "[acceptance]") {
    const RunConfig c = scalar("0.01", "adam_steps = 200\n");
    AcceptanceSearch s;
    s.ran = true;
    s.ratio = 3.0;
    const std::string a = acceptance_advice(c, "run/best.h5", s);
    INFO(a);
    CHECK(has(a, "rho = 0.01 is at or below rho* = "));
    CHECK_FALSE(has(a, "higher level"));
}

TEST_CASE("the true state far beyond training's region under the worst signals is named in the advice",
          "[acceptance]") {
    kern::GainSpec g;  // two states; boxes in x units: [-1, 3] (width 4) and [10, 20] (width 10)
    g.shift = {1.0, 15.0};
    g.spread = {2.0, 5.0};
    g.zlo = {-1.0, -1.0};
    g.zhi = {1.0, 1.0};
    const std::vector<std::string> names = {"p", "v"};
    // inside, and beyond by less than a width (p to 6.9: 3.9 past 3 with a width of 4): nothing said
    CHECK(worst_outside_training(g, names, {0.0, 12.0, 6.9, 19.0, -4.9, 10.0}, 2).empty());
    // v to 41 is 21 past 20 with a width of 10 (2.1 widths), p to 12 is 9 past 3 (2.25 widths): p is named
    CHECK(worst_outside_training(g, names, {0.0, 12.0, 12.0, 41.0}, 2) ==
          "p reached 12 where training's estimates spanned [-1, 3]");
    CHECK(worst_outside_training(g, names, {0.0, 12.0, 1.0, -15.0}, 2) ==
          "v reached -15 where training's estimates spanned [10, 20]");
    CHECK(worst_outside_training(g, names, {0.0, 12.0, NAN, 12.0}, 2) ==
          "p ran away where training's estimates spanned [-1, 3]");
    // with times (row k at 2 + 0.5 k): when a state first went more than a width beyond, which need not be the
    // furthest one; v leaves at row 1 (31: 1.1 widths), p at row 2 (further, 2.25 widths); at the same row the
    // first state is named
    CHECK(worst_outside_training(g, names, {0.0, 12.0, 1.0, 31.0, 12.0, 41.0}, 2, 2.0, 0.5) ==
          "p reached 12 where training's estimates spanned [-1, 3], first more than a width beyond at t = 2.5 (v)");
    CHECK(worst_outside_training(g, names, {0.0, 12.0, 12.0, 41.0}, 2, 2.0, 0.5) ==
          "p reached 12 where training's estimates spanned [-1, 3], first more than a width beyond at t = 2.5 (p)");
    CHECK(worst_outside_training(g, names, {0.0, 12.0, 8.0, 19.0, 12.0, 41.0}, 2, 0.0, 0.5) ==
          "p reached 12 where training's estimates spanned [-1, 3], first more than a width beyond at t = 0.5 (p)");
    kern::GainSpec none = g;  // a network without an input box: nothing to compare with
    none.zlo.clear();
    none.zhi.clear();
    CHECK(worst_outside_training(none, names, {0.0, 12.0, 100.0, 100.0}, 2).empty());

    const RunConfig c = scalar("2", "adam_steps = 200\n");
    AcceptanceSearch s;
    s.ran = true;
    s.ratio = 7.9;
    s.outside = "p reached 12 where training's estimates spanned [-1, 3]";
    const std::string a = acceptance_advice(c, "best.h5", s);
    CHECK(has(a, "the true state left the region training covered (p reached 12 where"));
    CHECK(has(a, "hinf worst --energy"));
    s.ratio = 1.5;  // the level kept: nothing to explain
    CHECK(!has(acceptance_advice(c, "best.h5", s), "left the region"));
    s.ratio = NAN;  // or diverged
    s.diverged = true;
    CHECK(has(acceptance_advice(c, "best.h5", s), "left the region"));
}

TEST_CASE("acceptance advice says when the level is below rho*_on and names a level above it", "[acceptance]") {
    // x' = v, y = x + n over 2 s: rho* = 0.619, rho*_on = 0.963 (tests/config/test_game_level.cpp); at rho = 0.8 the
    // game has a filter over the horizon, but not one a gain of the estimate alone can be
    const auto integrator = [](const std::string& rho) {
        return load_run_config(ConfigDoc::from_text(
            "[system]\nkind = \"expr\"\nstates = [\"x\"]\ndisturbances = 1\nmeasurements = 1\nf = [\"0\"]\n"
            "g = [[\"1\"]]\nh = [\"x\"]\n[filter]\nvariant = \"gain\"\nrho = " + rho +
                "\nQ = [1.0]\nx0 = [1.0]\nxhat0 = [0.0]\ndt = 0.01\nt_final = 2\n[online]\ndisturbance_std = 1\n"
                "noise_std = 1\n",
            "integrator.toml"));
    };
    AcceptanceSearch s;
    s.ran = true;
    s.ratio = 0.97;
    const RunConfig c = integrator("0.8");
    const double on = game_level_rho_run_on(c);
    REQUIRE(on > 0.95);
    REQUIRE(on < 0.97);
    const std::string a = acceptance_advice(c, "run/best.h5", s);
    INFO(a);
    CHECK(has(a, "[filter] rho = 0.8 is at or below rho*_on = "));
    char level[64];
    std::snprintf(level, sizeof level, "--set filter.rho=%.4g (1.25 rho*_on)", 1.25 * on);
    CHECK(has(a, level));
    CHECK_FALSE(has(a, "at or below rho* ="));
    CHECK_FALSE(has(a, "the worst-case search found a ratio of"));  // the level is the point, not another doubling
    // above rho*_on: the plain advice
    const std::string b = acceptance_advice(integrator("1.2"), "run/best.h5", s);
    INFO(b);
    CHECK_FALSE(has(b, "rho*_on"));
}

TEST_CASE("behind the EKF on both counts, other storages are tried from 1.5 times its error", "[acceptance]") {
    // the line choose_storage_far_behind trains other storages above (docs/method.md section 16.7, "Behind on both
    // counts"): the Chua circuit's check, 1.99x behind with a worst case 21.6 against the EKF's 13.7
    AcceptanceOutcome a;
    a.ran = true;
    CHECK(far_behind_line(a) == kFarBehindEkf);  // no search ran: the mean error alone
    a.worst_ratio = 19.7;
    a.worst_small_signal = 21.64;
    a.worst_ratio_ekf = 13.74;
    a.worst_small_signal_ekf = 11.73;
    CHECK(worst_above_ekf(a));
    CHECK(far_behind_line(a) == kFarBehindRecheck);
    // each side's larger figure counts: the EKF's small-signal ratio above the DNN filter's two
    a.worst_small_signal_ekf = 22.0;
    CHECK_FALSE(worst_above_ekf(a));
    CHECK(far_behind_line(a) == kFarBehindEkf);
    // a filter driven to divergence by its worst signals is above any finite worst case
    a.worst_diverged = true;
    CHECK(worst_above_ekf(a));
    // a small-signal figure not had: the figure at the budget stands alone on either side
    a.worst_diverged = false;
    a.worst_small_signal = NAN;
    a.worst_small_signal_ekf = NAN;
    CHECK(worst_above_ekf(a));  // 19.7 against 13.74
    a.worst_ratio = 13.0;
    CHECK_FALSE(worst_above_ekf(a));
    // no search for the EKF: no comparison
    a.worst_ratio = 19.7;
    a.worst_ratio_ekf = NAN;
    CHECK_FALSE(worst_above_ekf(a));
}

TEST_CASE("after another storage is kept, its worst case is set beside the replaced run's", "[acceptance]") {
    // storage_exchange_note: the kept run validates lower; whether its check's worst case rose says what it traded
    AcceptanceOutcome replaced, kept;
    CHECK(storage_exchange_note(replaced, kept, "run").empty());  // no search ran
    replaced.worst_ratio = 10.94;
    replaced.worst_small_signal = 4.225;
    kept.worst_ratio = 1.779;
    kept.worst_small_signal = 1.491;
    const std::string lower = storage_exchange_note(replaced, kept, "run");
    INFO(lower);
    CHECK(has(lower, "validates lower than the one it replaced (run/alternative), and its worst case found by its "
                     "check, 1.779, is not above that run's 10.94"));
    CHECK_FALSE(has(lower, "traded"));
    // the Brusselator's constant storage, by hand (docs/method.md section 16.7): lower in the mean, higher worst case
    replaced.worst_ratio = 6.26;
    replaced.worst_small_signal = NAN;
    kept.worst_ratio = 9.76;
    kept.worst_small_signal = 2.0;
    const std::string higher = storage_exchange_note(replaced, kept, "run");
    INFO(higher);
    CHECK(has(higher, "but its worst case found by its check, 9.76, is above that run's 6.26"));
    CHECK(has(higher, "traded the worst case for the mean error"));
    CHECK(has(higher, "--network run/best.h5 --network run/alternative/best.h5"));
    // driven to divergence by its worst signals: above any finite figure, said in words
    kept.worst_diverged = true;
    CHECK(has(storage_exchange_note(replaced, kept, "run"), "its worst case found by its check, divergence, is above"));
    kept.worst_ratio = NAN;  // the kept run's check had no search
    CHECK(storage_exchange_note(replaced, kept, "run").empty());
}
