// The constant storage as a second run (docs/method.md section 16.7). A Riccati start held at once ("Held at once:
// both storages trained"): where the game's Riccati equation falls to the storage's floor before its first knot, the
// knots start flat, and hinf train trains a constant storage as well and keeps, in its --out directory, the run whose
// best checkpoint validated lower; the other run is in DIR/alternative. Far behind the EKF ("Far behind the EKF: a
// constant storage tried"): where the acceptance check finds a run with knots settled above kFarBehindEkf (2) times
// the EKF's error (between 1.5 and 2 times on the check's few runs: on 25 runs, "Near the line: more runs decide"), the
// same choice follows, and a kept constant storage gets its own check; where those knots started
// on a Riccati solution held at the floor after the first knot ("Far behind the EKF, held later: flat knots tried"),
// flat knots are trained first and the lowest of the three kept. A config that names
// network.storage_knots (or network.knot_ratio) gets no second run, and a fresh run removes an earlier run's
// DIR/alternative.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "helpers.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"

using hinf::test::run_hinf;

namespace {

// three coupled masses, the outer two positions measured: the Riccati equation is held from the first step (measured
// when this test was written: t = 0.01 s, before the first knot at t_final / 32)
const char* kChain = R"toml([system]
kind = "expr"
states = ["p1", "v1", "p2", "v2", "p3", "v3"]
disturbances = 3
measurements = 2
f = ["v1", "-2*p1 + p2 - 0.1*v1", "v2", "p1 - 2*p2 + p3 - 0.1*v2", "v3", "p2 - 2*p3 - 0.1*v3 - 0.2*p3^3"]
g = [["0","0","0"], ["1","0","0"], ["0","0","0"], ["0","1","0"], ["0","0","0"], ["0","0","1"]]
h = ["p1", "p3"]
[filter]
x0 = [1.0, 0.0, 0.0, 0.0, -1.0, 0.0]
xhat0 = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
dt = 0.01
t_final = 1
[training]
acceptance_runs = 0
samples = 400
batch = 200
adam_steps = 10
[online]
disturbance_std = 0.2
noise_std = 0.05
)toml";

// the number after `key` in `text`
double number_after(const std::string& text, const std::string& key) {
    const std::size_t at = text.find(key);
    REQUIRE(at != std::string::npos);
    return std::strtod(text.c_str() + at + key.size(), nullptr);
}

// `hinf train` of the chain into d/run, with `extra` options; fails the test case unless it succeeds
hinf::test::CommandResult train_chain(const hinf::test::TempDir& d, const std::string& extra = "") {
    std::ofstream(d / "chain.toml") << kChain;
    auto r = run_hinf("train " + (d / "chain.toml") + " --quiet " + extra + " --out " + (d / "run"));
    INFO(r.output);
    REQUIRE(r.status == 0);
    return r;
}

bool names_constant_storage(const std::string& checkpoint) {
    return hinf::ckpt_read<float>(checkpoint).config_text.find("storage_knots = 0") != std::string::npos;
}

// Van der Pol cut to 3 s, 500 samples, one or two Adam steps a time step and a short acceptance search: at its
// default level its Riccati start is held from 1.77 s, after its first knot (not at once); at rho = 3 it is not held.
// When this test was written the acceptance check found every such run 3-4x behind the EKF, and (best validated
// scores) at the default level seed 1 with one step kept the Riccati start (0.0053; flat knots 0.0170, a constant
// storage 0.0127) and seed 2 with two steps kept flat knots (0.004390 against 0.004394), then a constant storage
// (0.0021); at rho = 3 seed 2 with two steps kept a constant storage (0.0029 against the knots' 0.0042)
hinf::test::CommandResult train_short_vdp(const std::string& out, const std::string& extra) {
    auto r = run_hinf("train " + hinf::test::source_path("runs/vanderpol.toml") +
                      " --quiet --threads 1 --set filter.t_final=3 --set online.settle_time=1"
                      " --set training.samples=500 --set training.batch=100 --set training.acceptance_worst_evals=24 " +
                      extra + " --out " + out);
    INFO(r.output);
    REQUIRE(r.status == 0);
    return r;
}

// the storage a checkpoint's config names, as the notes name it when kept
std::string storage_of(const std::string& checkpoint) {
    const std::string text = hinf::ckpt_read<float>(checkpoint).config_text;
    if (text.find("storage_knots = 0") != std::string::npos) return "constant storage";
    if (text.find("storage_init") != std::string::npos) return "flat knots";
    return "";  // the first run's knots (the notes: "knots" or "Riccati start")
}

// each directory holds one whole run: its checkpoint and best checkpoint agree on the storage, DIR's on the kept one
void check_runs_whole(const std::string& out, bool kept_constant) {
    CHECK(names_constant_storage(out + "/checkpoint.h5") == kept_constant);
    CHECK(names_constant_storage(out + "/best.h5") == kept_constant);
    CHECK(names_constant_storage(out + "/alternative/checkpoint.h5") == !kept_constant);
    CHECK(names_constant_storage(out + "/alternative/best.h5") == !kept_constant);
    CHECK(!std::filesystem::exists(out + "/alternative.swap"));
}

// One choice note: "best validated settled Q-weighted MSE A with X, B with Y: DIR keeps the Z, ..."
struct Choice {
    double first = 0, second = 0;
    std::string kept;
};
std::vector<Choice> choices_in(const std::string& output) {
    std::vector<Choice> out;
    const std::string key = "best validated settled Q-weighted MSE ";
    for (std::size_t at = output.find(key); at != std::string::npos; at = output.find(key, at + 1)) {
        Choice c;
        c.first = std::strtod(output.c_str() + at + key.size(), nullptr);
        const std::size_t comma = output.find(", ", at);
        REQUIRE(comma != std::string::npos);
        c.second = std::strtod(output.c_str() + comma + 2, nullptr);
        const std::size_t keeps = output.find(" keeps the ", comma);
        REQUIRE(keeps != std::string::npos);
        const std::size_t end = output.find(", ", keeps);
        c.kept = output.substr(keeps + 11, end - keeps - 11);
        out.push_back(c);
    }
    return out;
}

// The run in `out` is whole and holds the storage whose best checkpoint validated lowest of those trained (one choice:
// knots or a constant storage; a Riccati start held later: two, flat knots then a constant storage); `expected` is
// the storage this test means to cover (see train_short_vdp)
void check_choice(const hinf::test::CommandResult& r, const std::string& out, bool held_later,
                  const std::string& expected) {
    INFO(r.output);
    REQUIRE(r.output.find("times the EKF's error. Its " + std::string(held_later ? "knots started on the game's Riccati"
                                                                                 : "storage S(t) changes with time")) !=
            std::string::npos);
    const std::vector<Choice> c = choices_in(r.output);
    REQUIRE(c.size() == (held_later ? 2u : 1u));
    // the storages each choice compared, as the notes name them, and the lowest score seen
    std::vector<std::pair<std::string, std::string>> names;
    if (held_later) names = {{"Riccati start", "flat knots"}, {c[0].kept, "constant storage"}};
    else names = {{"knots", "constant storage"}};
    double lowest = c[0].first;
    for (std::size_t i = 0; i < c.size(); ++i) {
        CHECK(c[i].kept == (c[i].second < c[i].first ? names[i].second : names[i].first));
        lowest = std::min(lowest, c[i].second);
    }
    if (held_later) CHECK(c[1].first == std::min(c[0].first, c[0].second));  // the second choice starts from the kept
    CHECK(std::min(c.back().first, c.back().second) == lowest);
    CHECK(c.back().kept == expected);
    const auto in_file = [](const std::string& name) {  // storage_of's name for it
        return name == "knots" || name == "Riccati start" ? std::string() : name;
    };
    CHECK(storage_of(out + "/checkpoint.h5") == in_file(expected));
    CHECK(storage_of(out + "/best.h5") == in_file(expected));
    // DIR/alternative: the other run of the last choice, whole
    const std::string other = in_file(c.back().kept == names.back().second ? names.back().first : names.back().second);
    CHECK(storage_of(out + "/alternative/checkpoint.h5") == other);
    CHECK(storage_of(out + "/alternative/best.h5") == other);
    CHECK(!std::filesystem::exists(out + "/alternative.swap"));
    // the kept run was checked: one acceptance line for the first run, a second for another storage kept, whose
    // verdict is in its own best checkpoint
    CHECK(hinf::test::count_occurrences(r.output, "acceptance (5 measured runs") == (in_file(expected).empty() ? 1 : 2));
    hinf::h5::Handle f = hinf::h5::open_file(out + "/best.h5", false);
    CHECK(hinf::h5::has_attr(f.get(), "acceptance_verdict"));
}

}  // namespace

TEST_CASE("a Riccati start held at once trains both storages and keeps the one that validates lower", "[cli][train]") {
    hinf::test::TempDir d("held-start");
    const std::string out = d / "run";
    const auto r = train_chain(d);
    INFO(r.output);
    REQUIRE(r.output.find("hinf trains it too (network.storage_knots = 0") != std::string::npos);
    const double flat = number_after(r.output, "Q-weighted MSE "), constant = number_after(r.output, "with flat knots, ");
    REQUIRE(std::filesystem::exists(out + "/checkpoint.h5"));
    REQUIRE(std::filesystem::exists(out + "/alternative/checkpoint.h5"));
    REQUIRE(std::filesystem::exists(out + "/best.h5"));
    REQUIRE(std::filesystem::exists(out + "/alternative/best.h5"));
    const bool kept_constant = constant < flat;
    CHECK(r.output.find(kept_constant ? "keeps the constant storage" : "keeps the flat knots") != std::string::npos);
    check_runs_whole(out, kept_constant);
    // the kept run resumes as a run of its own config (it is at t_final: nothing to add, no error)
    auto again = run_hinf("resume " + out + "/checkpoint.h5 --quiet");
    INFO(again.output);
    CHECK(again.status == 0);
    // a sweep's value ends as hinf train does (eval's training_run): both storages, the same one kept, the same bits
    // (training.seed = 1 is the default; before, a sweep trained the knots alone)
    const std::string value = (d / "sweep") + "/training.seed=1";
    auto sweep = run_hinf("sweep " + (d / "chain.toml") + " --vary training.seed=1 --out " + (d / "sweep"));
    INFO(sweep.output);
    REQUIRE(sweep.status == 0);
    REQUIRE(std::filesystem::exists(value + "/alternative/best.h5"));
    CHECK(names_constant_storage(value + "/best.h5") == kept_constant);
    CHECK(hinf::ckpt_read<float>(value + "/best.h5").net.theta == hinf::ckpt_read<float>(out + "/best.h5").net.theta);
    CHECK(hinf::ckpt_read<float>(value + "/alternative/best.h5").net.theta ==
          hinf::ckpt_read<float>(out + "/alternative/best.h5").net.theta);
    // a config that names the storage's knots trains one storage, and a fresh run removes the old second one
    const auto named = train_chain(d, "--force --set network.storage_knots=32");
    CHECK(named.output.find("hinf trains it too") == std::string::npos);
    CHECK(!std::filesystem::exists(out + "/alternative"));
    // so does one that names their spacing (network.knot_ratio; a constant storage has no knots to space)
    const auto spaced = train_chain(d, "--force --set network.knot_ratio=1.5");
    CHECK(spaced.output.find("hinf trains it too") == std::string::npos);
    CHECK(!std::filesystem::exists(out + "/alternative"));
}

TEST_CASE("a knots run far behind the EKF trains other storages and keeps the lowest validation", "[cli][train]") {
    hinf::test::TempDir d("far-behind");
    const std::string out = d / "run";
    SECTION("held later: flat knots then a constant storage validate lower, the last kept and checked") {
        const std::string opts = "--set training.adam_steps=2 --set training.seed=2";
        check_choice(train_short_vdp(out, opts), out, true, "constant storage");
        auto again = run_hinf("resume " + out + "/checkpoint.h5 --quiet");  // the kept run resumes as itself
        INFO(again.output);
        CHECK(again.status == 0);
        // stopped early and resumed to t_final, the run ends as the run uninterrupted: the other runs and the choices
        // come at the end of the resume
        const std::string split = d / "split";
        const auto first = train_short_vdp(split, opts + " --until 1.5");
        CHECK(first.output.find("times the EKF's error. Its") == std::string::npos);
        auto rest = run_hinf("resume " + split + "/checkpoint.h5 --quiet --threads 1");
        check_choice(rest, split, true, "constant storage");
        const auto a = hinf::ckpt_read<float>(out + "/best.h5"), b = hinf::ckpt_read<float>(split + "/best.h5");
        CHECK(a.net.theta == b.net.theta);
        const auto c = hinf::ckpt_read<float>(out + "/alternative/best.h5");
        const auto e = hinf::ckpt_read<float>(split + "/alternative/best.h5");
        CHECK(c.net.theta == e.net.theta);
    }
    SECTION("held later: the Riccati start validates lowest, kept") {
        check_choice(train_short_vdp(out, "--set training.adam_steps=1 --set training.seed=1"), out, true,
                     "Riccati start");
    }
    SECTION("not held: the constant storage validates lower, kept and checked") {
        std::filesystem::create_directories(out);  // a file of the user's in DIR stays there when the runs swap
        std::ofstream(out + "/notes.txt") << "the user's notes";
        check_choice(train_short_vdp(out, "--set training.adam_steps=2 --set training.seed=2 --set filter.rho=3"), out,
                     false, "constant storage");
        CHECK(std::filesystem::exists(out + "/notes.txt"));
        CHECK_FALSE(std::filesystem::exists(out + "/alternative/notes.txt"));
    }
    SECTION("near the line: more runs decide, and below it the run is kept alone") {
        // the check's 5 runs read 1.73 times the EKF's error, in (kFarBehindRecheck, kFarBehindEkf]: 25 runs decide
        const auto r = train_short_vdp(out, "--set training.adam_steps=20 --set training.seed=1");
        INFO(r.output);
        const auto at = r.output.find("near the 2 from which hinf tries other storages; on 25 runs");
        REQUIRE(at != std::string::npos);
        const double more = std::atof(r.output.c_str() + r.output.find("): ", at) + 3);
        CHECK(more > 1.0);
        CHECK(more <= 2.0);
        // its worst case found (1.21) is below the EKF's (1.81): the line stays at 2 ("Behind on both counts")
        CHECK(r.output.find("where, as here, its worst case found is above") == std::string::npos);
        CHECK(r.output.find("times the EKF's error. Its") == std::string::npos);
        CHECK(r.output.find("hinf trains it too") == std::string::npos);
        CHECK(!std::filesystem::exists(out + "/alternative"));
        CHECK(!std::filesystem::exists(out + "/acceptance/recheck"));  // the scratch runs are removed
    }
    SECTION("a config that names the storage trains it alone") {
        const auto r = train_short_vdp(out, "--set training.adam_steps=1 --set training.seed=1 "
                                            "--set network.storage_knots=32");
        INFO(r.output);
        CHECK(r.output.find("times the EKF's error. Its") == std::string::npos);
        CHECK(r.output.find("hinf trains it too") == std::string::npos);
        CHECK(!std::filesystem::exists(out + "/alternative"));
    }
}
