// The gain variant end to end (docs/method.md section 14): train a tiny Van der Pol filter with a position-only
// sensor (m < n), run it through operate, compare, filter and worst in measured mode; --mode oracle is refused in
// one line; a checkpoint whose config was changed is refused.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <utility>

#include "helpers.hpp"
#include "eval/acceptance.hpp"
#include "hinf/h5.hpp"

using hinf::test::run_hinf;

namespace {

// The acceptance figures of a checkpoint's root attributes.
struct Acceptance {
    std::string verdict;
    double rho = 0, ratio = 0, ratio_minus_v0 = 0, worst_ratio = 0, worst_ratio_ekf = 0, small = 0, small_ekf = 0;
    std::int64_t diverged_runs = 0, worst_evals = 0, worst_diverged = 0;
};

Acceptance read_acceptance(const std::string& checkpoint, double rho) {
    hinf::h5::Handle f = hinf::h5::open_file(checkpoint, false);
    const hid_t r = f.get();
    Acceptance a;
    a.rho = rho;
    a.verdict = hinf::h5::get_attr_string(r, "acceptance_verdict");
    a.ratio = hinf::h5::get_attr_double(r, "acceptance_attenuation_ratio");
    a.ratio_minus_v0 = hinf::h5::get_attr_double(r, "acceptance_attenuation_ratio_minus_v0");
    a.diverged_runs = hinf::h5::get_attr_int(r, "acceptance_diverged_runs");
    a.worst_ratio = hinf::h5::get_attr_double(r, "acceptance_worst_ratio");
    a.worst_ratio_ekf = hinf::h5::get_attr_double(r, "acceptance_worst_ratio_ekf");
    a.small = hinf::h5::get_attr_double(r, "acceptance_worst_small_signal");
    a.small_ekf = hinf::h5::get_attr_double(r, "acceptance_worst_small_signal_ekf");
    a.worst_evals = hinf::h5::get_attr_int(r, "acceptance_worst_evals");
    a.worst_diverged = hinf::h5::get_attr_int(r, "acceptance_worst_diverged");
    return a;
}

// docs/method.md section 16.5: the Monte Carlo's bound, and (when a search ran) the worst ratio found <= rho and the
// small-signal worst ratio <= rho (docs/compare.md "The linear start")
bool mc_passes(const Acceptance& a) {
    const double ratio = std::isfinite(a.ratio_minus_v0) ? a.ratio_minus_v0 : a.ratio;
    return a.diverged_runs == 0 && ratio <= a.rho;
}
bool worst_passes(const Acceptance& a) {
    return a.worst_evals == 0 || (a.worst_diverged == 0 && a.worst_ratio <= a.rho && !(a.small > a.rho));
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// a filter's figure in a worst.h5: the largest ratio found at the budget or, where larger, for small signals (the
// linear start's), as hinf sweep --worst reports it
double searched(hid_t filter_group) {
    const double ratio = hinf::h5::get_attr_double(filter_group, "ratio");
    const double linear = hinf::h5::get_attr_double(filter_group, "linear_gain");
    return linear > ratio ? linear : ratio;
}

const std::string kVdp = hinf::test::tiny_vdp_gain_config("0.5");
}  // namespace

TEST_CASE("the acceptance check's small-signal figure is hinf worst's, pieces and all", "[cli][gain]") {
    // docs/method.md section 16.9, "Pieces the check cannot resolve": within half its search's steps the check had
    // stopped at 20 or 40 pieces a channel (40 here). Over 2 s (200 steps) the EKF's doubling goes further.
    hinf::test::TempDir d("gaincli-linear");
    const std::string cfg = d / "vdp.toml";
    std::ofstream(cfg) << hinf::test::tiny_vdp_gain_config("2");
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet");
    INFO(t.output);
    REQUIRE(t.status == 0);
    auto lin = run_hinf("worst " + cfg + " --network " + (d / "run/best.h5") + " --filters dnn,ekf --mode measured "
                        "--random-starts 0 --scenario-starts none --no-game-start --no-cross-starts --evals 1 --quiet "
                        "--out " + (d / "lin"));
    INFO(lin.output);
    REQUIRE(lin.status == 0);
    hinf::h5::Handle check = hinf::h5::open_file(d / "run/acceptance/worst.h5", false);
    hinf::h5::Handle full = hinf::h5::open_file(d / "lin/worst.h5", false);
    for (const char* filter : {"filters/dnn_gain_measured", "filters/ekf"}) {
        INFO(filter);
        hinf::h5::Handle c = hinf::h5::open_group(check.get(), filter), f = hinf::h5::open_group(full.get(), filter);
        CHECK(same_bits(hinf::h5::get_attr_double(c.get(), "linear_gain"), hinf::h5::get_attr_double(f.get(), "linear_gain")));
        CHECK(hinf::h5::get_attr_int(c.get(), "linear_pieces") == hinf::h5::get_attr_int(f.get(), "linear_pieces"));
    }
    hinf::h5::Handle ekf = hinf::h5::open_group(check.get(), "filters/ekf");
    CHECK(hinf::h5::get_attr_int(ekf.get(), "linear_pieces") > 40);
    hinf::h5::Handle ck = hinf::h5::open_file(d / "run/best.h5", false);  // the figure the verdict read
    hinf::h5::Handle dnn = hinf::h5::open_group(check.get(), "filters/dnn_gain_measured");
    CHECK(same_bits(hinf::h5::get_attr_double(ck.get(), "acceptance_worst_small_signal"),
                    hinf::h5::get_attr_double(dnn.get(), "linear_gain")));
}

TEST_CASE("gain variant: train, operate, compare, filter and worst run it in measured mode only", "[cli][gain]") {
    hinf::test::TempDir d("gaincli");
    const std::string cfg = d / "vdp.toml", net = d / "run/checkpoint.h5";
    std::ofstream(cfg) << kVdp;
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet");
    INFO(t.output);
    REQUIRE(t.status == 0);
    CHECK(t.output.find("acceptance (5 measured runs") != std::string::npos);
    CHECK(t.output.find("worst ratio found") != std::string::npos);
    {  // the acceptance's worst-case search: its figures in the checkpoint, its search in acceptance/worst.h5
        // a gain run keeps its best validated checkpoint by default (training.select_every, method.md 16.9), and
        // the acceptance check judges that one
        const Acceptance a = read_acceptance(d / "run/best.h5", 0.5);
        CHECK(a.worst_evals > 0);
        CHECK(std::isfinite(a.worst_ratio));
        CHECK(a.worst_ratio > 0);
        CHECK(std::isfinite(a.worst_ratio_ekf));
        CHECK(std::isfinite(a.small));
        CHECK(std::isfinite(a.small_ekf));
        CHECK(a.verdict == (mc_passes(a) && worst_passes(a) ? "pass" : "fail"));
        hinf::h5::Handle w = hinf::h5::open_file(d / "run/acceptance/worst.h5", false);
        CHECK(hinf::h5::get_attr_string(w.get(), "format") == "hinf-worst");
        hinf::h5::Handle g = hinf::h5::open_group(w.get(), "filters/dnn_gain_measured");
        CHECK(same_bits(hinf::h5::get_attr_double(g.get(), "ratio"), a.worst_ratio));
        // the small-signal figure is the search's linear start, and the search goes on from its signals at the budget
        // (the start that found the two tanks' worst case, docs/method.md section 16.9)
        CHECK(same_bits(hinf::h5::get_attr_double(g.get(), "linear_gain"), a.small));
        // training.acceptance_worst_evals' default, 600, dealt over the four starts; a cross start gets as many again
        const std::string starts = hinf::h5::get_attr_string(g.get(), "starts");
        CHECK(starts.rfind("random:0,random:1,scenario:energy_pulse,linear", 0) == 0);
        CHECK(hinf::h5::get_attr_int(w.get(), "evals") == 150);
        CHECK(a.worst_evals <= 150 * (1 + std::count(starts.begin(), starts.end(), ',')));
        CHECK(hinf::h5::exists(w.get(), "filters/ekf"));
    }
    {  // the Monte Carlo's runs against the EKF: the figures `hinf compare` gives on the same seed and run count, bit
       // for bit (t_final 0.5 s leaves the default 5 s no window, so the check judges the run's second half, t >= 0.25
       // s, as compare does when told so), in the line and the checkpoint
        CHECK(t.output.find("position RMSE") != std::string::npos);
        const std::size_t vs = t.output.find(" against the EKF's ");
        REQUIRE(vs != std::string::npos);
        CHECK(t.output.find("position RMSE after t = 0.25 s ") != std::string::npos);
        CHECK(t.output.find("over the whole runs") != std::string::npos);  // and the whole run's beside it
        auto c = run_hinf("compare " + cfg + " --network " + (d / "run/best.h5") + " --filters dnn,ekf --runs 5 --out " +
                          (d / "vs") + " --quiet --set online.settle_time=0.25");
        INFO(c.output);
        REQUIRE(c.status == 0);
        hinf::h5::Handle ck = hinf::h5::open_file(d / "run/best.h5", false);
        hinf::h5::Handle cmp = hinf::h5::open_file(d / "vs/compare.h5", false);
        hinf::h5::Handle own = hinf::h5::open_file(d / "run/acceptance/compare.h5", false);
        for (const auto& [filter, attr] : {std::pair<std::string, std::string>{"dnn_gain_measured", "acceptance_rmse_position_settled"},
                                           {"ekf", "acceptance_rmse_position_settled_ekf"}}) {
            INFO(filter);
            hinf::h5::Handle g = hinf::h5::open_group(cmp.get(), filter);
            hinf::h5::Handle h = hinf::h5::open_group(own.get(), filter);
            const double want = hinf::h5::get_attr_double(g.get(), "rmse_position_settled");
            CHECK(std::isfinite(want));
            CHECK(same_bits(hinf::h5::get_attr_double(ck.get(), attr.c_str()), want));
            CHECK(same_bits(hinf::h5::get_attr_double(h.get(), "rmse_position_settled"), want));
        }
        // all states weighted by the config's Q = I, sqrt(sum_j (mean_j^2 + std_j^2)) over t >= 0.25 s (the
        // selection's score as an RMS), from the same comparison's per-state figures
        for (const auto& [filter, attr] :
             {std::pair<std::string, std::string>{"dnn_gain_measured", "acceptance_rms_q_settled"},
              {"ekf", "acceptance_rms_q_settled_ekf"}}) {
            INFO(filter);
            hinf::h5::Handle g = hinf::h5::open_group(cmp.get(), filter);
            const std::vector<double> mean = hinf::h5::read_doubles(g.get(), "error_mean_settled"),
                                      sd = hinf::h5::read_doubles(g.get(), "error_std_settled");
            REQUIRE(mean.size() == 2);
            const double want = std::sqrt(mean[0] * mean[0] + sd[0] * sd[0] + mean[1] * mean[1] + sd[1] * sd[1]);
            CHECK(std::isfinite(want));
            CHECK(hinf::h5::get_attr_double(ck.get(), attr.c_str()) == Approx(want).epsilon(1e-12));
        }
        CHECK(t.output.find("), all states Q-weighted ") != std::string::npos);
        CHECK(hinf::h5::get_attr_double(ck.get(), "acceptance_settle_time") == 0.25);
    }
    {  // a settle_time the config names is kept, though no step reaches it: the check judges the whole run
        auto w = run_hinf("train " + cfg + " --out " + (d / "named") + " --quiet --set online.settle_time=5");
        INFO(w.output);
        REQUIRE(w.status == 0);
        CHECK(w.output.find(" against the EKF's ") != std::string::npos);
        CHECK(w.output.find(" after t = ") == std::string::npos);
        hinf::h5::Handle ck = hinf::h5::open_file(d / "named/best.h5", false);
        CHECK(hinf::h5::get_attr_double(ck.get(), "acceptance_settle_time") == 0.0);
    }
    auto op = run_hinf("operate " + cfg + " --network " + net + " --mode measured --runs 2 --out " + (d / "op"));
    INFO(op.output);
    CHECK(op.status == 0);
    {  // operate --ensemble of two copies of one network: that network's figures, the check against both storages
        auto ope = run_hinf("operate " + cfg + " --network " + net + " --network " + net +
                            " --ensemble --mode measured --runs 2 --out " + (d / "ope"));
        INFO(ope.output);
        REQUIRE(ope.status == 0);
        CHECK(ope.output.find("an ensemble of 2 networks") != std::string::npos);
        CHECK(ope.output.find("V(x~(0)) undefined for an ensemble") != std::string::npos);
        hinf::h5::Handle a = hinf::h5::open_file(d / "op/operate.h5", false), b = hinf::h5::open_file(d / "ope/operate.h5", false);
        CHECK(hinf::h5::get_attr_int(b.get(), "ensemble_size") == 2);
        for (const char* key : {"attenuation_ratio", "rmse_position", "online_check_violation_fraction",
                                "online_hji_violation_fraction"})
            CHECK(hinf::h5::get_attr_double(a.get(), key) == hinf::h5::get_attr_double(b.get(), key));
        CHECK(std::isnan(hinf::h5::get_attr_double(b.get(), "attenuation_ratio_minus_v0")));
        auto two = run_hinf("operate " + cfg + " --network " + net + " --network " + net + " --mode measured --runs 2 --out " +
                            (d / "ope2"));
        CHECK(two.status == 2);
        CHECK(two.output.find("add --ensemble") != std::string::npos);
        auto one = run_hinf("operate " + cfg + " --network " + net + " --ensemble --mode measured --runs 2 --out " +
                            (d / "ope3"));
        CHECK(one.status == 2);
        CHECK(one.output.find("two or more networks") != std::string::npos);
        auto re = run_hinf("operate " + cfg + " --network " + net + " --network " + net +
                           " --ensemble --set online.retrain=true --mode measured --runs 2 --out " + (d / "ope4"));
        CHECK(re.status == 2);
        CHECK(re.output.find("retrains one network") != std::string::npos);
    }
    auto orc = run_hinf("operate " + cfg + " --network " + net + " --mode oracle --runs 2 --out " + (d / "op2"));
    CHECK(orc.status == 2);
    CHECK(orc.output.find("--mode oracle is meaningless") != std::string::npos);
    auto cmp = run_hinf("compare " + cfg + " --network " + net + " --filters dnn,ukf --runs 2 --out " + (d / "cmp"));
    INFO(cmp.output);
    CHECK(cmp.status == 0);
    CHECK(cmp.output.find("dnn_gain_measured") != std::string::npos);
    CHECK(cmp.output.find("note: dnn_gain_measured: ") == std::string::npos);  // the config's start: inside the box
    {  // every run started far beyond the box of training's estimates (method.md 16.10): said once, with the count,
       // by compare and operate (the retraining filter too), and kept in their files
        const std::string far0 = " --set filter.xhat0=[400,-400] --runs 2 --quiet";
        auto c = run_hinf("compare " + cfg + " --network " + net + " --filters dnn,ekf --out " + (d / "cmpfar") + far0);
        INFO(c.output);
        REQUIRE(c.status == 0);
        CHECK(c.output.find("note: dnn_gain_measured: in 2 of 2 run(s) (the first: run 0), its estimate went far "
                            "beyond the region its network was trained on (w reached ") != std::string::npos);
        CHECK(c.output.find("note: ekf: ") == std::string::npos);
        hinf::h5::Handle f = hinf::h5::open_file(d / "cmpfar/compare.h5", false);
        hinf::h5::Handle g = hinf::h5::open_group(f.get(), "dnn_gain_measured");
        CHECK(hinf::h5::get_attr_int(g.get(), "note_runs") == 2);
        CHECK(hinf::h5::get_attr_int(g.get(), "note_first_run") == 0);
        CHECK(c.output.find(hinf::h5::get_attr_string(g.get(), "note")) != std::string::npos);
        hinf::h5::Handle e = hinf::h5::open_group(f.get(), "ekf");
        CHECK_FALSE(hinf::h5::has_attr(e.get(), "note"));
        for (const std::string retrain : {"false", "true"}) {
            auto o = run_hinf("operate " + cfg + " --network " + net + " --mode measured --out " + (d / "opfar") +
                              far0 + " --set online.retrain=" + retrain);
            INFO(o.output);
            REQUIRE(o.status == 0);
            CHECK(o.output.find("note: dnn: in 2 of 2 run(s) (the first: run 0), its estimate went far beyond")
                  != std::string::npos);
            hinf::h5::Handle h = hinf::h5::open_file(d / "opfar/operate.h5", false);
            CHECK(hinf::h5::get_attr_int(h.get(), "note_runs") == 2);
        }
        CHECK_FALSE(hinf::h5::has_attr(hinf::h5::open_file(d / "op/operate.h5", false).get(), "note"));
    }
    {  // --ensemble of two copies of one network: one filter, dnn_gain_ensemble, with that network's figures
        auto ens = run_hinf("compare " + cfg + " --network " + net + " --network " + net +
                            " --ensemble --filters dnn,ukf --runs 2 --out " + (d / "cmpe"));
        INFO(ens.output);
        CHECK(ens.status == 0);
        CHECK(ens.output.find("dnn_gain_ensemble") != std::string::npos);
        CHECK(ens.output.find("dnn_gain_measured") == std::string::npos);
        // the filter's row of compare.csv as named fields
        auto row = [](const std::string& csv, const std::string& filter) {
            for (const auto& r : hinf::test::read_csv_rows(csv))
                if (r.at("filter") == filter) return r;
            return std::map<std::string, std::string>();
        };
        auto one = row(d / "cmp/compare.csv", "dnn_gain_measured"), two = row(d / "cmpe/compare.csv", "dnn_gain_ensemble");
        REQUIRE(one.size() > 20);
        REQUIRE(two.size() == one.size());
        for (const auto& [key, value] : one)  // every figure but the timing and the name, to the last digit written
            if (key != "us_per_step" && key != "filter") CHECK(two[key] == value);
        auto alone = run_hinf("compare " + cfg + " --network " + net + " --ensemble --filters dnn --runs 2 --out " +
                              (d / "cmpe1"));
        CHECK(alone.status == 2);
        CHECK(alone.output.find("two or more networks") != std::string::npos);
    }
    auto cmpo = run_hinf("compare " + cfg + " --network " + net + " --filters dnn --mode oracle --runs 2 --out " +
                         (d / "cmp2"));
    CHECK(cmpo.status == 2);
    auto w = run_hinf("worst " + cfg + " --network " + net + " --filters dnn,ukf --evals 10 --random-starts 1 --scenario-starts none --out " +
                      (d / "worst"));
    INFO(w.output);
    CHECK(w.status == 0);
    CHECK(w.output.find("dnn_gain_measured") != std::string::npos);
    CHECK(w.output.find("left the region training covered") == std::string::npos);  // the nominal energy: inside
    // a budget 2e5 times the nominal one drives w beyond training's estimates by several of the box's widths
    // (11.8 against [-1.7, 1.0] when written): said, with the state, as the acceptance's advice says it
    auto far = run_hinf("worst " + cfg + " --network " + net + " --filters dnn --evals 10 --random-starts 1 "
                        "--scenario-starts none --energy 30000 --quiet --out " + (d / "worstfar"));
    INFO(far.output);
    CHECK(far.status == 0);
    CHECK(far.output.find("note: under dnn_gain_measured's worst signals the true state left the region training "
                          "covered (") != std::string::npos);
    CHECK(far.output.find("where training's estimates spanned [") != std::string::npos);
    {  // recorded measurements (hinf filter): the gain filter runs on y alone
        std::ofstream rec(d / "rec.csv");
        rec << "t,y0\n";
        for (int k = 0; k < 50; ++k) rec << 0.01 * k << "," << 2.0 - 0.001 * k << "\n";
    }
    auto fl = run_hinf("filter " + cfg + " --measurements " + (d / "rec.csv") + " --network " + net +
                       " --filters dnn --out " + (d / "filt"));
    INFO(fl.output);
    CHECK(fl.status == 0);
    CHECK(fl.output.find("dnn_gain_measured") != std::string::npos);
    CHECK(fl.output.find("note: dnn_gain_measured: ") == std::string::npos);  // the record's estimates stay inside
    {  // started far beyond the box of training's estimates (docs/method.md 16.10): one note line, kept in the file
        auto far_start = run_hinf("filter " + cfg + " --measurements " + (d / "rec.csv") + " --network " + net +
                                  " --filters dnn,ekf --initial-estimate 400,-400 --out " + (d / "filtfar"));
        INFO(far_start.output);
        CHECK(far_start.status == 0);
        const std::string line = "note: dnn_gain_measured: ";
        const std::size_t at = far_start.output.find(line);
        REQUIRE(at != std::string::npos);
        CHECK(far_start.output.find(line, at + 1) == std::string::npos);
        CHECK(far_start.output.find("If the system does go there, train over it") != std::string::npos);
        // no line for the EKF: the excursion note is the gain filter's, and the record's settled window holds too
        // few degrees of freedom for its innovation check (kNisMinDof)
        CHECK(far_start.output.find("note: ekf: ") == std::string::npos);
        hinf::h5::Handle f = hinf::h5::open_file(d / "filtfar/estimates.h5", false);
        hinf::h5::Handle g = hinf::h5::open_group(f.get(), "dnn_gain_measured");
        REQUIRE(hinf::h5::has_attr(g.get(), "note"));
        const std::string note = hinf::h5::get_attr_string(g.get(), "note");
        CHECK(note.find(" reached ") != std::string::npos);
        CHECK(far_start.output.find(note) != std::string::npos);  // the file keeps what was printed
        hinf::h5::Handle e = hinf::h5::open_group(f.get(), "ekf");
        CHECK_FALSE(hinf::h5::has_attr(e.get(), "note"));
    }
    // resume continues the same run
    auto r = run_hinf("resume " + net + " --quiet");
    CHECK(r.status == 0);
}

TEST_CASE("training.require_acceptance: a filter that fails its validation Monte Carlo exits 5", "[cli][gain]") {
    hinf::test::TempDir d("gainacc");
    const std::string cfg = d / "vdp.toml";
    std::ofstream(cfg) << kVdp;
    // no initial error (V(x~(0)) = 0) and rho far below any filter's ratio: the check must fail
    const std::string sets = " --set filter.xhat0=[2.0,0.0] --set filter.rho=1e-9 --set training.require_acceptance=true";
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet" + sets);
    INFO(t.output);
    CHECK(t.status == 5);
    CHECK(t.output.find("FAIL") != std::string::npos);
    CHECK(t.output.find("the check's worst-case search is short") == std::string::npos);  // only after a PASS
    CHECK(t.output.find("failed its acceptance check") != std::string::npos);
    // what to try, under the FAIL line: a level below rho* (hinf rho) and 50 steps x 2 Adam steps (a short run), each
    // with its fix, then the comparison with the Bayesian filters on the judged checkpoint
    const std::size_t next = t.output.find("acceptance: next:");
    REQUIRE(next != std::string::npos);
    const std::string advice = t.output.substr(next, t.output.find('\n', next) - next);
    CHECK(advice.find("rho = 1e-09 is at or below rho* = ") != std::string::npos);
    CHECK(advice.find("--set filter.rho=") != std::string::npos);
    CHECK(advice.find("this run made 100 Adam updates (50 time steps x training.adam_steps = 2)") != std::string::npos);
    CHECK(advice.find("--set training.adam_steps=600") != std::string::npos);
    CHECK(advice.find("hinf compare " + cfg + " --network " + (d / "run/best.h5") + " --filters dnn,ekf,ukf") !=
          std::string::npos);
    // a level this 0.5 s training meets at a fifth of the noise: exit 0, no advice. The check's search found 3.6
    // (hinf worst's full search 3.5); at the config's noise the search from the small-signal direction drives it out
    // of its training's region and it diverges, which the check's search before 2026-12-06 (no such start) missed
    auto ok = run_hinf("train " + cfg + " --out " + (d / "run2") +
                       " --quiet --set filter.rho=5 --set training.require_acceptance=true --set online.settle_time=0.25"
                       " --set online.disturbance_std=0.2 --set online.noise_std=0.04");
    INFO(ok.output);
    CHECK(ok.status == 0);
    {  // with a settled window the line also gives the whole runs' figures, the transient from x^0 included (method.md
       // 16.4): the comparison's rmse_position of each filter, as printed
        hinf::h5::Handle own = hinf::h5::open_file(d / "run2/acceptance/compare.h5", false);
        hinf::h5::Handle gd = hinf::h5::open_group(own.get(), "dnn_gain_measured"), ge = hinf::h5::open_group(own.get(), "ekf");
        char want[96];
        std::snprintf(want, sizeof want, "; over the whole runs %.4g against %.4g, ",
                      hinf::h5::get_attr_double(gd.get(), "rmse_position"), hinf::h5::get_attr_double(ge.get(), "rmse_position"));
        CHECK(ok.output.find(" after t = 0.25 s ") != std::string::npos);
        CHECK(ok.output.find(want) != std::string::npos);
    }
    CHECK(ok.output.find("PASS") != std::string::npos);
    CHECK(ok.output.find("acceptance: next:") == std::string::npos);
    // the short search's PASS is no proof: the full search's command, on the checkpoint judged
    CHECK(ok.output.find("acceptance: note: the check's worst-case search is short (") != std::string::npos);
    CHECK(ok.output.find("run the full search: hinf worst " + cfg + " --network " + (d / "run2/best.h5") +
                         " --filters dnn,ekf,ukf --mode measured") != std::string::npos);
    // after a PASS: a note naming a higher level exactly when the filter settles above 1.25 times the EKF's error on
    // the check's runs, in position or over all states Q-weighted (the line's "(1.69x)" and "(2.1x)"; method.md
    // 16.12, "Kept, and behind the EKF")
    const std::string key = "on the same runs (";
    const std::size_t at = ok.output.find(key);
    REQUIRE(at != std::string::npos);
    const double behind = std::atof(ok.output.c_str() + at + key.size());
    INFO("behind the EKF " << behind);
    REQUIRE(behind > 0);
    const std::string qkey = "all states Q-weighted ";  // "... against ... (2.1x)": the larger ratio decides
    const std::size_t qat = ok.output.find(qkey, at);
    REQUIRE(qat != std::string::npos);
    const std::size_t open = ok.output.find('(', qat);
    REQUIRE(open != std::string::npos);
    const double behind_q = std::atof(ok.output.c_str() + open + 1);
    INFO("all states behind the EKF " << behind_q);
    REQUIRE(behind_q > 0);
    const std::size_t note = ok.output.find("acceptance: note: the filter keeps rho = 5, but on these runs it settles at ");
    CHECK((note != std::string::npos) == (std::max(behind, behind_q) > 1.25));
    if (note != std::string::npos) {
        CHECK(ok.output.find("--set filter.rho=10 (twice rho)", note) != std::string::npos);
        CHECK(ok.output.find("; furthest behind: ", note) != std::string::npos);  // Q = I: a state is behind
    }
}

TEST_CASE("acceptance: the worst-case search alone fails a filter whose Monte Carlo passes, and 0 evaluations skip it",
          "[cli][gain][acceptance]") {
    hinf::test::TempDir d("gainworst");
    const std::string cfg = d / "vdp.toml";
    std::ofstream(cfg) << kVdp;
    // no initial error (the search's condition too) and a small rho: the Monte Carlo's random noise stays below it
    // (ratio ~2e-3 when written), the searched worst signals do not (~2e-2)
    const std::string sets =
        " --set filter.rho=0.01 --set filter.xhat0=[2.0,0.0] --set training.require_acceptance=true";
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet" + sets);
    INFO(t.output);
    const Acceptance a = read_acceptance(d / "run/best.h5", 0.01);
    CHECK(mc_passes(a));
    CHECK(a.worst_evals > 0);
    CHECK(a.worst_ratio > 0.01);
    CHECK(a.verdict == "fail");
    CHECK(t.status == 5);
    CHECK(t.output.find("failed its acceptance check") != std::string::npos);

    // training.acceptance_worst_evals = 0: the same training, the Monte Carlo alone decides
    auto off = run_hinf("train " + cfg + " --out " + (d / "off") + " --quiet" + sets +
                        " --set training.acceptance_worst_evals=0");
    INFO(off.output);
    CHECK(off.status == 0);
    CHECK(off.output.find("worst-case search off") != std::string::npos);
    const Acceptance b = read_acceptance(d / "off/best.h5", 0.01);
    CHECK(b.worst_evals == 0);
    CHECK(std::isnan(b.worst_ratio));
    CHECK(b.verdict == "pass");
    CHECK(same_bits(b.ratio, a.ratio));  // the same network and Monte Carlo
    CHECK_FALSE(std::filesystem::exists(d / "off/acceptance/worst.h5"));
}

TEST_CASE("acceptance: the worst-case search gives the same bits on 1 and 2 threads", "[cli][gain][acceptance]") {
    hinf::test::TempDir d("gainworstthr");
    const std::string cfg = d / "vdp.toml";
    std::ofstream(cfg) << kVdp;
    auto one = run_hinf("train " + cfg + " --out " + (d / "one") + " --quiet --threads 1");
    auto two = run_hinf("train " + cfg + " --out " + (d / "two") + " --quiet --threads 2");
    INFO(one.output << two.output);
    REQUIRE(one.status == 0);
    REQUIRE(two.status == 0);
    const Acceptance a = read_acceptance(d / "one/best.h5", 0.5);
    const Acceptance b = read_acceptance(d / "two/best.h5", 0.5);
    CHECK(a.worst_evals > 0);
    CHECK(a.worst_evals == b.worst_evals);
    CHECK(same_bits(a.worst_ratio, b.worst_ratio));
    CHECK(same_bits(a.worst_ratio_ekf, b.worst_ratio_ekf));
    CHECK(a.verdict == b.verdict);
}

namespace {
struct SelectRow {
    std::int64_t step = 0;
    double score = 0, diff = 0, se = 0;
    int lowest = 0, kept = 0;
};
std::vector<SelectRow> read_select_csv(const std::string& path) {  // step,t,score,diff,se,lowest,kept
    std::ifstream in(path);
    std::vector<SelectRow> rows;
    std::string line;
    std::getline(in, line);
    REQUIRE(line == "step,t,score,diff,se,lowest,kept");
    while (std::getline(in, line)) {
        std::vector<std::string> cell;
        std::istringstream ls(line);
        for (std::string c; std::getline(ls, c, ',');) cell.push_back(c);
        REQUIRE(cell.size() == 7);
        SelectRow r;
        r.step = std::stoll(cell[0]);
        r.score = std::strtod(cell[2].c_str(), nullptr);  // strtod reads "nan" and "inf"
        r.diff = std::strtod(cell[3].c_str(), nullptr);
        r.se = std::strtod(cell[4].c_str(), nullptr);
        r.lowest = std::stoi(cell[5]);
        r.kept = std::stoi(cell[6]);
        rows.push_back(r);
    }
    return rows;
}
// select.csv against the rule row by row; returns {the last kept row, the lowest row}
std::pair<std::size_t, std::size_t> check_select_rows(const std::vector<SelectRow>& rows, bool one_se) {
    std::size_t arg = 0, kept = 0;
    for (std::size_t r = 0; r < rows.size(); ++r) {
        INFO("row " << r);
        const bool lowest = r == 0 ? std::isfinite(rows[r].score) : rows[r].score < rows[arg].score;
        CHECK(rows[r].lowest == (lowest ? 1 : 0));
        CHECK(rows[r].kept == ((lowest || (one_se && rows[r].diff <= rows[r].se)) ? 1 : 0));
        if (lowest) arg = r;
        if (rows[r].kept == 1) kept = r;
    }
    return {kept, arg};
}
// the run of `cfg` stopped at `until` and resumed in `dir`: its select.csv
std::vector<SelectRow> split_and_resume(const std::string& cfg, const std::string& dir, const std::string& args,
                                        const std::string& until) {
    auto half = run_hinf("train " + cfg + " --out " + dir + args + " --until " + until);
    INFO(half.output);
    REQUIRE(half.status == 0);
    auto rest = run_hinf("resume " + dir + "/checkpoint.h5 --quiet");
    INFO(rest.output);
    REQUIRE(rest.status == 0);
    return read_select_csv(dir + "/select.csv");
}
std::string content_digest(const std::string& checkpoint) {  // the digest of the network, optimiser and state
    hinf::h5::Handle f = hinf::h5::open_file(checkpoint, false);
    return hinf::h5::get_attr_string(f.get(), "content_digest");
}
}  // namespace

TEST_CASE("training.select_every keeps the best validated checkpoint as best.h5, and a resumed run keeps the same one",
          "[cli][gain][select]") {
    hinf::test::TempDir d("gainselect");
    const std::string cfg = d / "vdp.toml";
    std::ofstream(cfg) << hinf::test::tiny_vdp_gain_config("0.5", "select_every = 10\nselect_runs = 2\n");
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet --set training.acceptance_worst_evals=0");
    INFO(t.output);
    REQUIRE(t.status == 0);
    CHECK(t.output.find("select: best validated checkpoint at step") != std::string::npos);
    // one validation per 10 steps; the lowest is the running minimum, and the rule (select_rule = "one_se", the
    // default) keeps a row when it is the lowest so far or its paired excess over that lowest is within one
    // standard error; best.h5 is the last kept row
    const std::vector<SelectRow> rows = read_select_csv(d / "run/select.csv");
    REQUIRE(rows.size() == 5);
    const auto [kept, arg] = check_select_rows(rows, true);
    double lowest = rows[0].score;
    for (std::size_t r = 0; r < rows.size(); ++r) {
        INFO("row " << r);
        CHECK(rows[r].step == std::int64_t(10 * (r + 1)));
        if (r > 0 && std::isfinite(rows[r].score)) {  // the paired mean difference equals the difference of means
            CHECK(rows[r].se >= 0);
            CHECK(rows[r].diff == Approx(rows[r].score - lowest).epsilon(1e-9).margin(1e-15));
        }
        lowest = std::min(lowest, rows[r].score);
    }
    hinf::h5::Handle b = hinf::h5::open_file(d / "run/best.h5", false);
    const std::int64_t step = hinf::h5::get_attr_int(b.get(), "select_step");
    CHECK(step == rows[kept].step);
    CHECK(same_bits(hinf::h5::get_attr_double(b.get(), "select_score"), rows[kept].score));
    CHECK(hinf::h5::get_attr_int(b.get(), "select_lowest_step") == rows[arg].step);
    CHECK(same_bits(hinf::h5::get_attr_double(b.get(), "select_lowest_score"), rows[arg].score));
    CHECK(hinf::h5::get_attr_doubles(b.get(), "select_run_scores").size() == 2);
    CHECK(hinf::h5::get_attr_string(b.get(), "select_rule") == "one_se");
    // the acceptance check ran on best.h5 (its attributes are there)
    CHECK(hinf::h5::has_attr(b.get(), "acceptance_verdict"));
    // best.h5 holds the network of that step: the same training stopped there gives the same parameters
    auto stop = run_hinf("train " + cfg + " --out " + (d / "stop") + " --quiet --until " +
                         std::to_string(0.01 * double(step)) + " --set training.acceptance_worst_evals=0");
    INFO(stop.output);
    REQUIRE(stop.status == 0);
    CHECK(content_digest(d / "run/best.h5") == content_digest(d / "stop/checkpoint.h5"));
    // interrupted at t = 0.25 (between validations) and resumed: the same validation curve and the same best.h5
    const std::vector<SelectRow> again =
        split_and_resume(cfg, d / "split", " --quiet --set training.acceptance_worst_evals=0", "0.25");
    REQUIRE(again.size() == rows.size());
    for (std::size_t r = 0; r < rows.size(); ++r) {
        CHECK(again[r].step == rows[r].step);
        CHECK(same_bits(again[r].score, rows[r].score));
    }
    CHECK(content_digest(d / "split/best.h5") == content_digest(d / "run/best.h5"));
}

TEST_CASE("training.select_rule one_se keeps a later checkpoint within one paired standard error, also when resumed",
          "[cli][gain][select]") {
    // a learning rate of 1e-12: the network barely moves, so the validations differ by rounding-size amounts; on this
    // machine's Release build the rule meets every case (lowest, within one standard error, beyond it), but which
    // case a row meets depends on rounding, so the checks are the rule's invariants (select_keeps has unit checks)
    hinf::test::TempDir d("gainselect_se");
    const std::string cfg = d / "vdp.toml";
    std::ofstream(cfg) << hinf::test::tiny_vdp_gain_config("0.5", "select_every = 10\nselect_runs = 3\nlearning_rate = 1e-12\n");
    const std::string quiet = " --quiet --set training.acceptance_worst_evals=0 --set training.acceptance_runs=0";
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + quiet);
    INFO(t.output);
    REQUIRE(t.status == 0);
    const std::vector<SelectRow> rows = read_select_csv(d / "run/select.csv");
    REQUIRE(rows.size() == 5);
    const auto [kept, arg] = check_select_rows(rows, true);
    hinf::h5::Handle b = hinf::h5::open_file(d / "run/best.h5", false);
    CHECK(hinf::h5::get_attr_int(b.get(), "select_step") == rows[kept].step);
    CHECK(hinf::h5::get_attr_int(b.get(), "select_lowest_step") == rows[arg].step);
    CHECK(hinf::h5::get_attr_doubles(b.get(), "select_lowest_run_scores").size() == 3);
    if (kept != arg) CHECK(t.output.find("within one paired standard error of the lowest") != std::string::npos);
    // split between validations and resumed: the same rows and the same best.h5 (the lowest's per-run scores
    // travel in best.h5)
    const std::vector<SelectRow> again = split_and_resume(cfg, d / "split", quiet, "0.15");
    REQUIRE(again.size() == rows.size());
    for (std::size_t r = 0; r < rows.size(); ++r) {
        CHECK(same_bits(again[r].score, rows[r].score));
        CHECK(again[r].kept == rows[r].kept);
    }
    CHECK(content_digest(d / "split/best.h5") == content_digest(d / "run/best.h5"));
    // select_rule = "lowest": the same validations, and best.h5 is the lowest
    auto low = run_hinf("train " + cfg + " --out " + (d / "low") + quiet + " --set training.select_rule=lowest");
    INFO(low.output);
    REQUIRE(low.status == 0);
    const std::vector<SelectRow> lrows = read_select_csv(d / "low/select.csv");
    REQUIRE(lrows.size() == rows.size());
    for (std::size_t r = 0; r < rows.size(); ++r) CHECK(same_bits(lrows[r].score, rows[r].score));
    const auto [lkept, larg] = check_select_rows(lrows, false);
    CHECK(lkept == arg);
    CHECK(larg == arg);
    hinf::h5::Handle lb = hinf::h5::open_file(d / "low/best.h5", false);
    CHECK(hinf::h5::get_attr_int(lb.get(), "select_step") == rows[arg].step);
}

TEST_CASE("paired_difference: the mean run-by-run difference and its standard error, NaN without two finite pairs",
          "[select]") {
    const hinf::PairedDifference d = hinf::paired_difference({3.0, 5.0, 4.0}, {1.0, 2.0, 3.0});  // differences 2, 3, 1
    CHECK(d.mean == Approx(2.0));
    CHECK(d.se == Approx(std::sqrt(1.0 / 3.0)));  // sample sd 1, over sqrt(3)
    CHECK(hinf::paired_difference({1.0, 2.0}, {1.0, 2.0}).se == 0.0);
    CHECK(std::isnan(hinf::paired_difference({1.0}, {0.0}).mean));              // one run: no standard error
    CHECK(std::isnan(hinf::paired_difference({1.0, 2.0}, {0.0}).mean));         // different runs
    CHECK(std::isnan(hinf::paired_difference({1.0, INFINITY}, {0.0, 1.0}).se));  // a diverged run
    CHECK(std::isnan(hinf::paired_difference({1.0, 2.0}, {}).mean));             // no lowest yet
    // the rule: the lowest is always kept; within one standard error only under one_se
    CHECK(hinf::select_keeps("lowest", 1.0, true, d));
    CHECK(hinf::select_keeps("one_se", 1.0, true, hinf::PairedDifference{}));
    CHECK(hinf::select_keeps("one_se", 1.0, false, hinf::PairedDifference{0.5, 0.5}));
    CHECK(hinf::select_keeps("one_se", 1.0, false, hinf::PairedDifference{0.0, 0.0}));  // the same scores: the later
    CHECK_FALSE(hinf::select_keeps("one_se", 1.0, false, hinf::PairedDifference{0.6, 0.5}));
    CHECK_FALSE(hinf::select_keeps("lowest", 1.0, false, hinf::PairedDifference{0.0, 0.5}));
    CHECK_FALSE(hinf::select_keeps("one_se", INFINITY, false, hinf::PairedDifference{0.0, 0.5}));
    CHECK_FALSE(hinf::select_keeps("one_se", 1.0, false, hinf::PairedDifference{}));  // no per-run scores: strict
}

TEST_CASE("hinf sweep ends each value as hinf train does: best.h5 and the acceptance verdict per value, and exit 5 "
          "when no value passes under training.require_acceptance", "[cli][gain][sweep]") {
    hinf::test::TempDir d("gainsweep");
    const std::string cfg = d / "vdp.toml";
    std::ofstream(cfg) << kVdp;
    // rho far below any filter's ratio fails (as in the require_acceptance test above), rho = 5 passes
    const std::string sets = " --set filter.xhat0=[2.0,0.0] --set training.require_acceptance=true"
                             " --set training.acceptance_worst_evals=240";  // the budget is not what is tested
    auto sw = run_hinf("sweep " + cfg + " --vary filter.rho=1e-9,5 --out " + (d / "sweep") + sets);
    INFO(sw.output);
    CHECK(sw.status == 0);  // one value passed
    // a line after each value: what it ended with, how many are done, the time left
    CHECK(sw.output.find("sweep: filter.rho=1e-9 trained: status 0, training ") != std::string::npos);
    CHECK(sw.output.find(", acceptance pass; 2/2 values done, elapsed ") != std::string::npos);
    CHECK(sw.output.find(" fail ") != std::string::npos);
    CHECK(sw.output.find(" pass ") != std::string::npos);
    const auto rows = hinf::test::read_csv_rows(d / "sweep/sweep.csv");
    REQUIRE(rows.size() == 2);
    CHECK(rows[0].at("acceptance") == "fail");
    CHECK(rows[1].at("acceptance") == "pass");
    // the value's run is `hinf train` with that value: the same best.h5 step, score and acceptance figures
    auto plain = run_hinf("train " + cfg + " --out " + (d / "plain") + " --quiet" + sets + " --set filter.rho=5");
    INFO(plain.output);
    REQUIRE(plain.status == 0);
    for (const std::string& dir : {d / "plain", d / "sweep/filter.rho=5"}) {
        hinf::h5::Handle f = hinf::h5::open_file(dir + "/best.h5", false);
        CHECK(hinf::h5::get_attr_string(f.get(), "acceptance_verdict") == "pass");
        CHECK(std::to_string(hinf::h5::get_attr_int(f.get(), "select_step")) == rows[1].at("best_step"));
        CHECK(same_bits(hinf::h5::get_attr_double(f.get(), "select_score"), std::stod(rows[1].at("select_score"))));
        CHECK(same_bits(hinf::h5::get_attr_double(f.get(), "acceptance_rmse_position"),
                        std::stod(rows[1].at("acceptance_rmse_position"))));
        CHECK(same_bits(hinf::h5::get_attr_double(f.get(), "acceptance_worst_ratio"),
                        std::stod(rows[1].at("acceptance_worst_ratio"))));
        for (const char* key : {"acceptance_rmse_position_settled", "acceptance_rmse_position_settled_ekf",
                                "acceptance_rms_q_settled", "acceptance_rms_q_settled_ekf"}) {
            INFO(key);
            CHECK(std::isfinite(hinf::h5::get_attr_double(f.get(), key)));
            CHECK(same_bits(hinf::h5::get_attr_double(f.get(), key), std::stod(rows[1].at(key))));
        }
    }
    CHECK(rows[0].at("knot_runaway_step") == "-1");  // no storage knots in this config
    CHECK(sw.output.find("x EKF") != std::string::npos);
    // no value passes: the table, then one error line and exit 5
    auto none = run_hinf("sweep " + cfg + " --vary filter.rho=1e-9,2e-9 --out " + (d / "none") + sets);
    INFO(none.output);
    CHECK(none.status == 5);
    CHECK(none.output.find("hinf: error: no value of filter.rho passed its acceptance check") != std::string::npos);
    // a value finished by a sweep before these columns existed (11 fields in its summary.csv): read back, no verdict
    const std::string old = d / "none/filter.rho=2e-9/summary.csv";
    std::ofstream(old) << "value,how,status,first_step,last_step,wall_seconds,final_loss,median_rel_residual,"
                          "fraction_steps_rel_ok,fraction_steps_violation_ok,mean_cosine\n"
                          "2e-9,trained,0,0,50,1.5,0.25,0.5,0,0,0.75\n";
    auto again = run_hinf("sweep " + cfg + " --vary filter.rho=2e-9 --out " + (d / "none") + sets);
    INFO(again.output);
    CHECK(again.status == 0);  // no check ran in this job
    const auto back = hinf::test::read_csv_rows(d / "none/sweep.csv");
    REQUIRE(back.size() == 1);
    CHECK(back[0].at("how") == "done before");
    CHECK(back[0].at("acceptance") == "-");
    CHECK(back[0].at("best_step") == "-1");
    // and one from before the comparison with the EKF (16 fields): its verdict read back, no EKF figure
    std::ofstream(old) << "value,how,status,first_step,last_step,wall_seconds,final_loss,median_rel_residual,"
                          "fraction_steps_rel_ok,fraction_steps_violation_ok,mean_cosine,best_step,select_score,"
                          "acceptance,acceptance_rmse_position,acceptance_worst_ratio\n"
                          "2e-9,trained,0,0,50,1.5,0.25,0.5,0,0,0.75,40,0.125,fail,0.5,3.5\n";
    auto verdict = run_hinf("sweep " + cfg + " --vary filter.rho=2e-9 --out " + (d / "none") + sets);
    INFO(verdict.output);
    CHECK(verdict.status == 5);  // a failed check read back counts, as a check of this job would
    const auto v16 = hinf::test::read_csv_rows(d / "none/sweep.csv");
    REQUIRE(v16.size() == 1);
    CHECK(v16[0].at("acceptance") == "fail");
    CHECK(v16[0].at("best_step") == "40");
    CHECK(v16[0].at("acceptance_worst_ratio") == "3.5");
    CHECK(v16[0].at("acceptance_rmse_position_settled") == "nan");
    CHECK(v16[0].at("acceptance_rms_q_settled") == "nan");
    CHECK(v16[0].at("knot_runaway_step") == "-1");
}

TEST_CASE("hinf sweep --worst searches each value's checkpoint as hinf worst does and names the smallest level kept",
          "[cli][gain][sweep]") {
    hinf::test::TempDir d("gainsweepworst");
    const std::string cfg = d / "vdp.toml";
    std::ofstream(cfg) << hinf::test::tiny_vdp_gain_config("0.2");  // 20 steps: the full search runs three filters
    const std::string sets = " --set filter.xhat0=[2.0,0.0]";
    auto sw = run_hinf("sweep " + cfg + " --vary filter.rho=1e-9,5 --worst --out " + (d / "sweep") + sets);
    INFO(sw.output);
    REQUIRE(sw.status == 0);
    const auto rows = hinf::test::read_csv_rows(d / "sweep/sweep.csv");
    REQUIRE(rows.size() == 2);
    CHECK(std::stod(rows[0].at("rho")) == 1e-9);
    CHECK(std::stod(rows[1].at("rho")) == 5);
    bool any_kept = false;
    for (const auto& r : rows) {
        INFO(r.at("value"));
        const double ratio = std::stod(r.at("search_ratio"));
        REQUIRE(std::isfinite(ratio));
        CHECK(ratio > 0);
        CHECK(std::isfinite(std::stod(r.at("search_ratio_ekf"))));
        CHECK(std::isfinite(std::stod(r.at("search_ratio_ukf"))));
        REQUIRE((r.at("search_diverged") == "0" || r.at("search_diverged") == "1"));
        // the value's worst.h5 holds the search the table reports
        const std::string dir = d / ("sweep/filter.rho=" + r.at("value"));
        hinf::h5::Handle w = hinf::h5::open_file(dir + "/worst/worst.h5", false);
        hinf::h5::Handle g = hinf::h5::open_group(w.get(), "filters/dnn_gain_measured");
        CHECK(same_bits(searched(g.get()), ratio));
        CHECK(hinf::h5::exists(w.get(), "filters/ukf"));
        any_kept = any_kept || (r.at("search_diverged") == "0" && ratio <= std::stod(r.at("rho")));
    }
    CHECK(std::stod(rows[0].at("search_ratio")) > 1e-9);  // no filter keeps a level of 1e-9
    const bool kept5 = rows[1].at("search_diverged") == "0" && std::stod(rows[1].at("search_ratio")) <= 5;
    CHECK(sw.output.find("keeps rho") != std::string::npos);
    CHECK((sw.output.find("the smallest level kept: rho = 5 ") != std::string::npos) == kept5);
    CHECK((sw.output.find("no value's filter keeps its level") != std::string::npos) == !any_kept);
    // the search is hinf worst's with its defaults on the checkpoint the value's acceptance judged (best.h5)
    const std::string best = d / "sweep/filter.rho=5/best.h5";
    auto w = run_hinf("worst " + cfg + sets + " --set filter.rho=5 --network " + best +
                      " --filters dnn,ekf,ukf --mode measured --quiet --out " + (d / "worst"));
    INFO(w.output);
    REQUIRE(w.status == 0);
    hinf::h5::Handle f = hinf::h5::open_file(d / "worst/worst.h5", false);
    for (const auto& [name, column] : {std::pair<std::string, std::string>{"dnn_gain_measured", "search_ratio"},
                                       {"ekf", "search_ratio_ekf"}, {"ukf", "search_ratio_ukf"}}) {
        INFO(name);
        hinf::h5::Handle g = hinf::h5::open_group(f.get(), "filters/" + name);
        CHECK(same_bits(searched(g.get()), std::stod(rows[1].at(column))));
    }
    // one value, rho = 5, swept into d/plain: its output and its row of sweep.csv
    std::string output;
    const auto sweep_five = [&](const std::string& flags) {
        auto r = run_hinf("sweep " + cfg + " --vary filter.rho=5" + flags + " --out " + (d / "plain") + sets);
        INFO(r.output);
        REQUIRE(r.status == 0);
        output = r.output;
        const auto csv = hinf::test::read_csv_rows(d / "plain/sweep.csv");
        REQUIRE(csv.size() == 1);
        return csv[0];
    };
    // without --worst: no search, its columns empty, no level table
    const auto p = sweep_five(" --quiet");  // (--quiet: no progress lines)
    CHECK(output.find("sweep: filter.rho=5 trained") == std::string::npos);
    CHECK(output.find("ETA") == std::string::npos);
    CHECK(p.at("search_ratio") == "nan");
    CHECK(p.at("search_diverged") == "-1");
    CHECK(std::stod(p.at("rho")) == 5);
    CHECK(output.find("keeps rho") == std::string::npos);
    CHECK_FALSE(std::filesystem::exists(d / "plain/filter.rho=5/worst"));
    // a value finished before these columns existed (21 fields): read back, no level, no search
    std::ofstream(d / "plain/filter.rho=5/summary.csv")
        << "value,how,status,first_step,last_step,wall_seconds,final_loss,median_rel_residual,fraction_steps_rel_ok,"
           "fraction_steps_violation_ok,mean_cosine,best_step,select_score,acceptance,acceptance_rmse_position,"
           "acceptance_worst_ratio,acceptance_rmse_position_settled,acceptance_rmse_position_settled_ekf,"
           "knot_runaway_step,acceptance_rms_q_settled,acceptance_rms_q_settled_ekf\n"
           "5,trained,0,0,50,1.5,0.25,0.5,0,0,0.75,40,0.125,pass,0.5,3.5,0.25,0.125,-1,0.375,0.25\n";
    const auto o = sweep_five(" --worst");
    CHECK(o.at("how") == "done before");
    CHECK(output.find("sweep: filter.rho=5 done before: status 0, training 1.5s, acceptance pass; 1/1 values done, "
                      "elapsed ") != std::string::npos);
    CHECK(output.find("ETA -") != std::string::npos);  // (no value trained: no rate)
    CHECK(o.at("acceptance_rms_q_settled") == "0.375");
    CHECK(o.at("rho") == "nan");
    CHECK(o.at("search_diverged") == "-1");
    CHECK(output.find("(-: no search") != std::string::npos);
}
