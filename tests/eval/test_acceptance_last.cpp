// The acceptance check of an early best.h5 (docs/method.md section 16.9): where the validation kept an earlier
// checkpoint than the last and it FAILs, the last checkpoint gets the same check; where that PASSes it becomes best.h5
// and the validation's pick stays as best_average.h5; where both FAIL, best.h5 stays and a note gives both figures.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "config/run_config.hpp"
#include "eval/acceptance.hpp"
#include "helpers.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"

using namespace hinf;
namespace fs = std::filesystem;

namespace {

// a tiny Van der Pol gain training (50 steps) whose validation keeps an earlier checkpoint than the last, copied
// into `dir`; returns the selection best.h5 records
Selection trained_with_early_best(const std::string& src, const std::string& dir) {
    fs::copy(src, dir, fs::copy_options::recursive);
    fs::remove_all(dir + "/acceptance");
    Selection best;
    h5::Handle f = h5::open_file(dir + "/best.h5", false);
    best.score = h5::get_attr_double(f.get(), "select_score");
    best.step = h5::get_attr_int(f.get(), "select_step");
    best.run_scores = h5::get_attr_doubles(f.get(), "select_run_scores");
    best.lowest_score = h5::get_attr_double(f.get(), "select_lowest_score");
    best.lowest_step = h5::get_attr_int(f.get(), "select_lowest_step");
    best.lowest_run_scores = h5::get_attr_doubles(f.get(), "select_lowest_run_scores");
    return best;
}

TrainSummary ended_at(std::int64_t last) {
    TrainSummary s;
    s.last_step = last;
    return s;
}

std::string attr_string(const std::string& path, const char* name) {
    h5::Handle f = h5::open_file(path, false);
    return h5::get_attr_string(f.get(), name);
}

// the score select.csv recorded for `step`
double csv_score(const std::string& csv, std::int64_t step) {
    std::ifstream in(csv);
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
        std::istringstream row(line);
        std::string a, t, score;
        std::getline(row, a, ',');
        std::getline(row, t, ',');
        std::getline(row, score, ',');
        if (std::stoll(a) == step) return std::stod(score);
    }
    return NAN;
}

}  // namespace

TEST_CASE("an early best.h5 that fails its acceptance check: the last checkpoint is judged too, and kept where it "
          "passes", "[acceptance][select]") {
    test::TempDir d("acc-last");
    const std::string cfg_path = d / "vdp.toml";
    std::ofstream(cfg_path) << test::tiny_vdp_gain_config("0.5", "select_every = 10\nselect_runs = 2\n");
    // xhat0 = x0: no initial error, so the Monte Carlo's ratio is the plain one; rho = 5 (this training PASSes it)
    const std::string sets = " --set filter.xhat0=[2.0,0.0] --set filter.rho=5 --set training.acceptance_runs=0";
    auto t = test::run_hinf("train " + cfg_path + " --out " + (d / "run") + " --quiet" + sets);
    INFO(t.output);
    REQUIRE(t.status == 0);
    const RunConfig cfg0 = ckpt_config(d / "run/checkpoint.h5");
    const std::int64_t last = cfg0.steps_until();
    {
        h5::Handle f = h5::open_file(d / "run/best.h5", false);
        // the premise: this training's validation keeps step 20 of 50 (if a change of the trainer moves it to the
        // last, the test no longer tests anything: give it another training)
        REQUIRE(h5::get_attr_int(f.get(), "select_step") < last);
    }
    RunConfig cfg = cfg0;
    cfg.acceptance_runs = 3;
    cfg.acceptance_worst_evals = 200;

    SECTION("best.h5 fails (its network spoiled), the last passes: the last becomes best.h5") {
        const std::string dir = d / "swap";
        Selection best = trained_with_early_best(d / "run", dir);
        const std::int64_t early = best.step;
        {  // best.h5's gain network made useless (weights x 50) while its selection record stays
            const std::string path = dir + "/best.h5";
            Checkpoint<float> ck = ckpt_read<float>(path);
            for (float& w : ck.net.theta) w *= 50.0f;
            h5::Handle keep = h5::open_file(path, false);
            const double score = h5::get_attr_double(keep.get(), "select_score");
            keep = h5::Handle();
            ckpt_write<float>(path, ck, cfg0);
            h5::Handle f = h5::open_file(path, true);
            h5::set_attr(f.get(), "select_score", score);
            h5::set_attr(f.get(), "select_step", early);
        }
        const AcceptanceOutcome a = acceptance_after(cfg, dir, ended_at(last), &best, false, true);
        INFO(a.line << "\n" << a.selection_note);
        REQUIRE(a.ran);
        CHECK(a.pass);
        CHECK(a.file == dir + "/best.h5");
        CHECK(a.selection_note.find("acceptance: note: best.h5 (step " + std::to_string(early) +
                                    ", the validation's pick) FAILed and the last checkpoint (step " +
                                    std::to_string(last) + ") PASSed the same check") == 0);
        CHECK(a.selection_note.find(dir + "/best_average.h5") != std::string::npos);
        CHECK(a.line.find(dir + "/acceptance/last/operate.h5") != std::string::npos);
        // the notes' commands name best.h5, the file the user now has, not the checkpoint the check judged
        CHECK(a.search_note.find("--network " + dir + "/best.h5") != std::string::npos);
        for (const std::string& text : {a.note, a.settle_note, a.search_note, a.advice}) {
            INFO(text);
            CHECK(text.find(dir + "/checkpoint.h5") == std::string::npos);
        }
        // the selection now says the last step, with the score its validation gave (select.csv's row, bit for bit)
        CHECK(best.step == last);
        CHECK(best.score == csv_score(dir + "/select.csv", last));
        CHECK(best.run_scores.size() == 2);
        // best.h5 is the last checkpoint's network with its PASS, marked as kept by the check; the pick is kept aside
        CHECK(ckpt_read<float>(dir + "/best.h5").net.theta == ckpt_read<float>(dir + "/checkpoint.h5").net.theta);
        CHECK(attr_string(dir + "/best.h5", "acceptance_verdict") == "pass");
        CHECK(attr_string(dir + "/best.h5", "select_kept_by") == "acceptance");
        {
            h5::Handle f = h5::open_file(dir + "/best.h5", false);
            CHECK(h5::get_attr_int(f.get(), "select_step") == last);
            CHECK(h5::get_attr_int(f.get(), "select_lowest_step") == best.lowest_step);
        }
        REQUIRE(fs::exists(dir + "/best_average.h5"));
        CHECK(attr_string(dir + "/best_average.h5", "acceptance_verdict") == "fail");
        {
            h5::Handle f = h5::open_file(dir + "/best_average.h5", false);
            CHECK(h5::get_attr_int(f.get(), "select_step") == early);
        }
        // the check again (a resumed run's end): the earlier second check's files do not outlive it
        Selection again = best;
        const AcceptanceOutcome b = acceptance_after(cfg, dir, ended_at(last), &again, false, true);
        CHECK(b.pass);
        CHECK(b.selection_note.empty());  // best.h5 is the last checkpoint now: one check
        CHECK_FALSE(fs::exists(dir + "/acceptance/last"));
        CHECK_FALSE(fs::exists(dir + "/best_average.h5"));
    }
    SECTION("both fail: best.h5 stays, and the note gives the last's figures beside it") {
        const std::string dir = d / "both";
        Selection best = trained_with_early_best(d / "run", dir);
        const std::int64_t early = best.step;
        RunConfig tight = cfg;
        tight.rho = 1e-9;  // no filter keeps it
        const AcceptanceOutcome a = acceptance_after(tight, dir, ended_at(last), &best, false, true);
        INFO(a.line << "\n" << a.selection_note);
        REQUIRE(a.ran);
        CHECK_FALSE(a.pass);
        CHECK(a.file == dir + "/best.h5");
        CHECK(a.selection_note.find("acceptance: note: the last checkpoint (step " + std::to_string(last) +
                                    ") FAILed the same check too (worst figure found ") == 0);
        CHECK(a.selection_note.find("stays the validation's pick") != std::string::npos);
        CHECK(best.step == early);
        CHECK(attr_string(dir + "/best.h5", "acceptance_verdict") == "fail");
        CHECK(attr_string(dir + "/checkpoint.h5", "acceptance_verdict") == "fail");
        CHECK(fs::exists(dir + "/acceptance/last/operate.h5"));
        CHECK_FALSE(fs::exists(dir + "/best_average.h5"));
    }
    SECTION("best.h5 passes: one check, and the note names the last checkpoint's full search too") {
        const std::string dir = d / "pass";
        Selection best = trained_with_early_best(d / "run", dir);
        const AcceptanceOutcome a = acceptance_after(cfg, dir, ended_at(last), &best, false, true);
        INFO(a.line);
        REQUIRE(a.ran);
        CHECK(a.pass);
        CHECK(a.selection_note.empty());
        CHECK(a.search_note.find("search " + dir + "/checkpoint.h5 the same way") != std::string::npos);
        CHECK_FALSE(fs::exists(dir + "/acceptance/last"));
    }
}

TEST_CASE("after the last checkpoint is kept as best.h5, every note's command names best.h5", "[acceptance][select]") {
    AcceptanceOutcome a;
    a.note = "acceptance: note: ... compare both best.h5 (hinf compare c.toml --network D/checkpoint.h5 --filters dnn)";
    a.search_note = "acceptance: note: ... run the full search: hinf worst c.toml --network D/checkpoint.h5 ...";
    a.settle_note = "no file named";
    a.selection_note = "D/checkpoint.h5 was judged";  // the selection note says which file was judged: kept
    rename_in_notes(a, "D/checkpoint.h5", "D/best.h5");
    CHECK(a.note == "acceptance: note: ... compare both best.h5 (hinf compare c.toml --network D/best.h5 --filters dnn)");
    CHECK(a.search_note == "acceptance: note: ... run the full search: hinf worst c.toml --network D/best.h5 ...");
    CHECK(a.settle_note == "no file named");
    CHECK(a.selection_note == "D/checkpoint.h5 was judged");
    // twice in one text, and a name that contains the new one
    a.advice = "D/checkpoint.h5 and D/checkpoint.h5";
    rename_in_notes(a, "D/checkpoint.h5", "D/checkpoint.h5.best");
    CHECK(a.advice == "D/checkpoint.h5.best and D/checkpoint.h5.best");
}
