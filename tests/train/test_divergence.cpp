// Divergence: a loss past training.loss_limit (here: Adam with learning rate 3 blows up at time step 2)
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
t_final = 0.06
[network]
hidden = [8]
[training]
samples = 50
batch = 20
adam_steps = 2
checkpoint_every = 1
learning_rate = 3.0
)";

}  // namespace

TEST_CASE("a diverging run stops with a diagnostic and keeps its last good checkpoint", "[train][divergence]") {
    test::TempDir d("diverge");
    const std::string cfg = d / "div.toml";
    std::ofstream(cfg) << kDiverging;
    auto r = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + cfg + " --out " + (d / "run") +
                               " --quiet");
    INFO(r.output);
    CHECK(r.status == 4);
    CHECK(r.output.find("hinf: error: training diverged at time step 2 (t = 0.02 s): training loss = ") !=
          std::string::npos);
    CHECK(r.output.find("last finite values: loss ") != std::string::npos);
    CHECK(r.output.find("The last good checkpoint " + (d / "run/checkpoint.h5") + " is kept") != std::string::npos);
    ckpt_verify(d / "run/checkpoint.h5");
    CHECK(ckpt_read<float>(d / "run/checkpoint.h5").state.step == 2);
}

TEST_CASE("on_divergence = rollback goes back to the checkpoint with a smaller learning rate", "[train][divergence]") {
    test::TempDir d("rollback");
    const std::string cfg = d / "div.toml";
    std::ofstream(cfg) << kDiverging << "on_divergence = \"rollback\"\nrollback_factor = 0.01\n";
    auto r = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + cfg + " --out " + (d / "run") +
                               " --quiet");
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK(r.output.find("hinf: rolled back to time step 2 with learning rate 0.03 (roll-back 1 of 3)") !=
          std::string::npos);
    Checkpoint<float> ck = ckpt_read<float>(d / "run/checkpoint.h5");
    CHECK(ck.state.step == 6);
    CHECK(ck.state.learning_rate_scale == 0.01);  // stored, so that a resume continues at the lower rate
    SECTION("without a checkpoint to go back to, it stops") {
        std::string text = kDiverging;
        text.replace(text.find("checkpoint_every = 1"), 20, "checkpoint_every = 100");
        std::ofstream(cfg) << text << "on_divergence = \"rollback\"\n";
        auto s = test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + cfg + " --out " +
                                   (d / "none") + " --quiet");
        INFO(s.output);
        CHECK(s.status == 4);
        CHECK(s.output.find("no checkpoint to roll back to yet") != std::string::npos);
        CHECK(s.output.find("No checkpoint was written yet") != std::string::npos);
    }
}
