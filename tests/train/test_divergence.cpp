// Divergence: a loss past training.loss_limit (here: Adam with learning rate 0.3 and loss_limit 1e3)
// stops `hinf train` with exit 4 and one diagnostic line, the last good checkpoint intact; with
// training.on_divergence = "rollback" the run goes back to it with a smaller learning rate and ends.
#include <catch2/catch.hpp>
#include <fstream>
#include <map>

#include "helpers.hpp"
#include "hinf/h5.hpp"
#include "config/run_config.hpp"
#include "hinf/config.hpp"
#include "io/checkpoint.hpp"

using namespace hinf;

namespace {

const char* kDiverging = R"([system]
kind = "missile"
[filter]
variant = "dissipative"
t_final = 0.3
[network]
hidden = [8]
[training]
samples = 50
batch = 20
adam_steps = 2
checkpoint_every = 1
learning_rate = 0.3
loss_limit = 1e3
)";

// The time step in "... diverged at time step S (t = ...", or -1.
long long diverged_step(const std::string& out) {
    const std::string key = "training diverged at time step ";
    std::size_t at = out.find(key);
    return at == std::string::npos ? -1 : std::atoll(out.c_str() + at + key.size());
}

}  // namespace

TEST_CASE("a diverging run stops with a diagnostic and keeps its last good checkpoint", "[train][divergence]") {
    test::TempDir d("diverge");
    const std::string cfg = d / "div.toml";
    std::ofstream(cfg) << kDiverging;
    auto r = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + cfg + " --out " + (d / "run") +
                               " --quiet");
    INFO(r.output);
    CHECK(r.status == 4);
    const long long step = diverged_step(r.output);
    REQUIRE(step > 0);  // after at least one checkpoint (checkpoint_every = 1)
    CHECK(r.output.find("training loss") != std::string::npos);
    CHECK(r.output.find("last finite values: loss ") != std::string::npos);
    CHECK(r.output.find("learning rate 0.3.") != std::string::npos);
    CHECK(r.output.find("The last good checkpoint " + (d / "run/checkpoint.h5") + " is kept") != std::string::npos);
    ckpt_verify(d / "run/checkpoint.h5");
    CHECK(ckpt_read<float>(d / "run/checkpoint.h5").state.step == step);  // the state before the bad step

    // the advice is a command the user can run as printed: resume with a tenth of the rate
    const std::string key = "continue it with a lower rate: hinf resume ";
    const std::size_t at = r.output.find(key), end = r.output.find(", or --set", at);
    REQUIRE(at != std::string::npos);
    REQUIRE(end != std::string::npos);
    const std::string advised = r.output.substr(at + key.size() - 7, end - at - key.size() + 7);  // "resume ..."
    CHECK(advised == "resume " + (d / "run/checkpoint.h5") + " --set training.learning_rate=0.03");
    auto c = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " " + advised + " --quiet");
    INFO(c.output);
    CHECK((c.status == 0 || diverged_step(c.output) > step));  // it gets past the step it diverged at
    // the change is recorded where the run's config lives: the checkpoint's and the trajectory's
    const std::string text = ckpt_read<float>(d / "run/checkpoint.h5").config_text;
    CHECK(load_run_config(ConfigDoc::from_text(text, "ckpt")).learning_rate == Approx(0.03).epsilon(1e-12));
    CHECK(text.find("# hinf resume at step " + std::to_string(step) + ": --set training.learning_rate=0.03") !=
          std::string::npos);
    {
        h5::Handle f = h5::open_file(d / "run/trajectory.h5", false);
        CHECK(h5::get_text(f.get(), "config") == text);
    }
    // a key that fixes what the checkpoint means is refused in one line
    auto k = test::run_command(std::string(HINF_CLI_PATH) + " resume " + (d / "run/checkpoint.h5") +
                               " --set training.seed=3 2>&1");
    CHECK(k.status == 2);
    CHECK(k.output.find("resume --set training.seed: this key cannot change on resume") != std::string::npos);
    CHECK(ckpt_read<float>(d / "run/checkpoint.h5").config_text == text);  // nothing changed
}

TEST_CASE("on_divergence = rollback: back to the checkpoint, rate x factor each time, then stop", "[train][divergence]") {
    // here the error x~ itself grows, so a lower rate only delays the limit: 3 roll-backs, then exit 4
    test::TempDir d("rollback");
    const std::string cfg = d / "div.toml";
    std::ofstream(cfg) << kDiverging << "on_divergence = \"rollback\"\nrollback_factor = 0.1\n";
    auto r = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + cfg + " --out " + (d / "run") +
                               " --quiet");
    INFO(r.output);
    CHECK(r.status == 4);
    const long long step = diverged_step(r.output);
    REQUIRE(step > 0);
    CHECK(r.output.find("hinf: rolled back to time step " + std::to_string(step) +
                        " with learning rate 0.03 (roll-back 1 of 3)") != std::string::npos);
    CHECK(r.output.find("with learning rate 0.003 (roll-back 2 of 3)") != std::string::npos);
    CHECK(r.output.find("with learning rate 0.0003 (roll-back 3 of 3)") != std::string::npos);
    CHECK(r.output.find("learning rate 0.0003. The last good checkpoint") != std::string::npos);
    ckpt_verify(d / "run/checkpoint.h5");
    Checkpoint<float> ck = ckpt_read<float>(d / "run/checkpoint.h5");
    CHECK(ck.state.step > step);  // progress was made after the first roll-back
    // written after roll-back 1 succeeded a step (rolls 2 and 3 never completed one): a resume keeps it
    CHECK(ck.state.learning_rate_scale == Approx(0.1).epsilon(1e-12));
}

TEST_CASE("rollback without a checkpoint restarts from the initial state and can finish", "[train][divergence]") {
    test::TempDir d("rollback0");
    const std::string cfg = d / "div.toml";
    std::string text = kDiverging;
    text.replace(text.find("learning_rate = 0.3"), 19, "learning_rate = 10.0");  // loss past the limit in step 0
    text.replace(text.find("checkpoint_every = 1"), 20, "checkpoint_every = 100");
    text.replace(text.find("loss_limit = 1e3"), 16, "loss_limit = 1e5");
    std::ofstream(cfg) << text << "on_divergence = \"rollback\"\nrollback_factor = 0.01\n";
    auto r = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + cfg + " --out " + (d / "run") +
                               " --quiet");
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK(diverged_step(r.output) == 0);
    CHECK(r.output.find("last finite values: loss none yet") != std::string::npos);
    CHECK(r.output.find("No checkpoint was written yet") != std::string::npos);
    CHECK(r.output.find("hinf: rolled back to time step 0 with learning rate 0.1 (roll-back 1 of 3)") !=
          std::string::npos);
    CHECK(r.output.find("trained time steps 0..30") != std::string::npos);
    CHECK(ckpt_read<float>(d / "run/checkpoint.h5").state.step == 30);
}

// Van der Pol with the mixed filter: at learning rate 0.5 the loss passes 10 at time step 16, after the
// checkpoint at 16; a roll-back to it at rate 0.005 then trains on to the end (t_final = 0.4 s: 40 steps).
const char* kMixedRollback = R"([system]
kind = "expr"
states = ["p", "w"]
units = ["m", "m/s"]
disturbances = 1
measurements = 1
parameters = { mu = 1.0, c = 0.3 }
f = ["w", "mu*(1 - p^2)*w - p"]
g = [["0"], ["1"]]
h = ["p + c*p^3"]
[filter]
type = "h2hinf"
rho = 0.5
Q = [1.0, 1.0]
x0 = [2.0, 0.0]
xhat0 = [0.5, 1.0]
dt = 0.01
t_final = 0.4
[network]
hidden = [8]
[training]
samples = 50
batch = 20
adam_steps = 3
checkpoint_every = 2
learning_rate = 0.5
loss_limit = 10
on_divergence = "rollback"
rollback_factor = 0.01
[sampling]
error_floor = [0.2, 0.2]
[objective]
disturbance_intensity = 0.0025
noise_intensity = 0.0001
[online]
disturbance_std = 0.5
noise_std = 0.1
)";

TEST_CASE("rollback on an h2hinf run keeps every trajectory column growing, and the run resumes", "[train][divergence]") {
    // the mixed filter (seed 001) has six more columns; a roll-back reopens the file with the same column list
    test::TempDir d("rollback_mixed");
    const std::string cfg = d / "mixed.toml";
    std::ofstream(cfg) << kMixedRollback;
    auto r = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + cfg + " --out " + (d / "run") +
                               " --quiet");
    INFO(r.output);
    REQUIRE(r.output.find("(roll-back 1 of 3)") != std::string::npos);
    CHECK(r.status == 0);
    const std::int64_t step = ckpt_read<float>(d / "run/checkpoint.h5").state.step;
    CHECK(step == 40);
    REQUIRE(step > diverged_step(r.output));  // rows were appended after the roll-back
    {
        h5::Handle f = h5::open_file(d / "run/trajectory.h5", false);
        for (const char* col : {"t", "x", "xhat", "gain", "hjie_residual", "hjie2_residual", "hjie2_rel_residual_median",
                                "hjie2_rel_residual_p95", "hji2_violation_fraction", "consistency_gap",
                                "consistency_gap_printed"}) {
            INFO(col);
            std::vector<hsize_t> dims;
            h5::read_doubles(f.get(), col, &dims);
            CHECK(dims[0] == hsize_t(step));
        }
    }
    // the checkpoint and its trajectory still agree: resuming to the checkpoint's own time is accepted
    auto res = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " resume " + (d / "run/checkpoint.h5") +
                                 " --until 0.4 --quiet");
    INFO(res.output);
    CHECK(res.status == 0);
}

namespace {
// Rows of every dataset of a trajectory file's root (each column is one dataset, rows first).
std::map<std::string, hsize_t> column_rows(const std::string& path) {
    h5::Handle f = h5::open_file(path, false);
    std::map<std::string, hsize_t> rows;
    H5Literate(
        f.get(), H5_INDEX_NAME, H5_ITER_NATIVE, nullptr,
        [](hid_t loc, const char* name, const H5L_info_t*, void* out) -> herr_t {
            H5O_info_t info;
            if (H5Oget_info_by_name(loc, name, &info, H5P_DEFAULT) < 0 || info.type != H5O_TYPE_DATASET) return 0;
            hid_t d = H5Dopen2(loc, name, H5P_DEFAULT), s = H5Dget_space(d);
            hsize_t dims[4] = {0, 0, 0, 0};
            H5Sget_simple_extent_dims(s, dims, nullptr);
            (*static_cast<std::map<std::string, hsize_t>*>(out))[name] = dims[0];
            H5Sclose(s);
            H5Dclose(d);
            return 0;
        },
        &rows);
    return rows;
}
}  // namespace

// The roll-back reopens the trajectory with the same column list as a resume (trajectory_columns): with the
// mixed filter's six extra columns a roll-back once dropped them, and the run could no longer be resumed
TEST_CASE("an h2hinf run rolled back keeps every column growing and resumes", "[train][divergence][mixed]") {
    test::TempDir d("rollback_mixed");
    const std::string cfg = d / "div.toml";
    std::string text = kDiverging;
    text.replace(text.find("[filter]\n"), 9, "[filter]\ntype = \"h2hinf\"\n");
    std::ofstream(cfg) << text << "on_divergence = \"rollback\"\nrollback_factor = 0.1\n";
    auto r = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + cfg + " --out " + (d / "run") +
                               " --quiet");
    INFO(r.output);
    REQUIRE(r.output.find("hinf: rolled back to time step") != std::string::npos);
    const std::int64_t step = ckpt_read<float>(d / "run/checkpoint.h5").state.step;
    REQUIRE(step > 0);
    auto rows = column_rows(d / "run/trajectory.h5");
    REQUIRE(rows.count("hjie2_residual") == 1);
    for (const auto& c : rows) {
        INFO(c.first);
        CHECK(c.second == rows.at("t"));  // no column stopped growing
        CHECK(c.second >= hsize_t(step));
    }
    // the run resumes from its checkpoint: it may diverge again (exit 4), but never refuse the trajectory (exit 2)
    auto res = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " resume " + (d / "run/checkpoint.h5") +
                                 " --quiet");
    INFO(res.output);
    CHECK(res.status != 2);
    CHECK(res.output.find("rows but the checkpoint needs") == std::string::npos);
    for (const auto& c : column_rows(d / "run/trajectory.h5")) CHECK(c.second == column_rows(d / "run/trajectory.h5").at("t"));
}

TEST_CASE("a gain run diverging from the Riccati start hinf chose starts again flat once and one that names it gets the advice",
          "[train][divergence][gain]") {
    test::TempDir d("divgain");
    std::string text = kDiverging;
    text.replace(text.find("variant = \"dissipative\""), 23, "variant = \"gain\"");
    // rate 1: with its errors grouped per estimate (two here) the gain run trains through 0.3 at this size
    text.replace(text.find("learning_rate = 0.3"), 19, "learning_rate = 1.0");
    text += "acceptance_runs = 0\n";
    std::ofstream(d / "gain.toml") << text;
    // every gain entry learned: with the missile's structural zeros (method.md 16.17) this setting no longer diverges
    const std::string full = " --set network.gain_structure='\"full\"'";
    // the config names no start: hinf chose the Riccati one, and a divergence from it starts the run again from flat
    // knots, once (method.md 16.7, "A start that diverges"); here the flat start diverges too, and the run says so
    auto a = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + (d / "gain.toml") + " --out " +
                               (d / "auto") + " --quiet" + full);
    INFO(a.output);
    CHECK(a.status == 4);
    REQUIRE(diverged_step(a.output) > 0);
    const auto count = test::count_occurrences;
    CHECK(count(a.output, "training diverged at time step ") == 2);
    CHECK(count(a.output, "the run starts again from flat knots (below).") == 1);
    CHECK(count(a.output, "it starts again from flat knots, recorded in its config") == 1);
    CHECK(a.output.find("try --set network.storage_init=flat") == std::string::npos);
    CHECK(ckpt_config(d / "auto/checkpoint.h5").storage_init == "flat");  // the second run's checkpoint
    // a config that names the Riccati start keeps it, and its one line names the other starts
    auto r = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + (d / "gain.toml") + " --out " +
                               (d / "run") + " --quiet --set network.storage_init=riccati" + full);
    INFO(r.output);
    CHECK(r.status == 4);
    REQUIRE(diverged_step(r.output) > 0);
    CHECK(count(r.output, "training diverged at time step ") == 1);
    CHECK(r.output.find("try --set network.storage_init=flat or --set network.storage_knots=0.") != std::string::npos);
    // the flat start (and every other variant) does not get that advice
    auto f = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + (d / "gain.toml") + " --out " +
                               (d / "flat") + " --quiet --set network.storage_init=flat" + full);
    INFO(f.output);
    REQUIRE(diverged_step(f.output) > 0);
    CHECK(f.output.find("storage_init=flat") == std::string::npos);
}
