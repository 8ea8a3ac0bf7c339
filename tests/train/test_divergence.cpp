// Divergence: a loss past training.loss_limit (here: Adam with learning rate 0.3 and loss_limit 1e3)
// stops `hinf train` with exit 4 and one diagnostic line, the last good checkpoint intact; with
// training.on_divergence = "rollback" the run goes back to it with a smaller learning rate and ends.
#include <catch2/catch.hpp>
#include <fstream>

#include "helpers.hpp"
#include "io/checkpoint.hpp"

using namespace hinf;

namespace {

const char* kDiverging = R"([system]
kind = "missile"
[filter]
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
