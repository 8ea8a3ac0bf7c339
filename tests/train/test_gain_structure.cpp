// The gain's structural zeros (network.gain_structure = "components", docs/method.md section 16.17): K_aj = 0 where
// state a and output j lie in different components of the system's dependency graph (the drift's Jacobian, the
// disturbance inputs, Q and the outputs' Jacobian). A system in one component keeps every entry (no mask: the same
// bits as before the key); "full" turns it off; a trained filter's gain has the zeros.
#include <catch2/catch.hpp>
#include <algorithm>
#include <string>
#include <vector>

#include "config/run_config.hpp"
#include "gain.hpp"
#include "helpers.hpp"
#include "hinf/config.hpp"
#include "io/checkpoint.hpp"
#include "net/network.hpp"
#include "train/trainer.hpp"

using namespace hinf;

namespace {

// two subsystems: a decays alone and is measured by y1; b, c oscillate, v drives c, y2 measures b
std::string split_config(const std::string& extra_filter = "", const std::string& extra_network = "") {
    return R"([system]
kind = "expr"
states = ["a", "b", "c"]
disturbances = 1
measurements = 2
f = ["-0.5*a", "c", "-b - 0.2*c"]
g = [["0"], ["0"], ["1"]]
h = ["a", "b + 0.1*b^3"]
[filter]
variant = "gain"
rho = 2.0
x0 = [1.0, 0.5, 0.0]
xhat0 = [0.0, 0.0, 0.0]
dt = 0.01
t_final = 1.0
)" + extra_filter + R"(
[network]
hidden = [8]
)" + extra_network + R"(
[training]
samples = 64
batch = 32
adam_steps = 2
checkpoint_every = 50
acceptance_runs = 0
[online]
disturbance_std = 0.3
noise_std = 0.1
)";
}

using hinf::test::config_from_text;

}  // namespace

TEST_CASE("gain structure: the components of the dependency graph give the gain's zeros", "[train][gain][structure]") {
    SECTION("two subsystems: each state takes only its own subsystem's output") {
        const RunConfig cfg = config_from_text(split_config());
        std::vector<int> comp;
        const std::vector<double> mask = gain_component_mask(cfg, &comp);
        CHECK(mask == std::vector<double>{1, 0, 0, 1, 0, 1});
        REQUIRE(comp.size() == 5);  // a, b, c, y1, y2
        CHECK(comp[0] == comp[3]);
        CHECK(comp[1] == comp[2]);
        CHECK(comp[1] == comp[4]);
        CHECK(comp[0] != comp[1]);
        CHECK(network_step_config(cfg).gain.mask == mask);
    }
    SECTION("a Q that couples the subsystems, or gain_structure = full: no mask") {
        const RunConfig coupled = config_from_text(split_config("Q = [[1, 0.1, 0], [0.1, 1, 0], [0, 0, 1]]\n"));
        CHECK(network_step_config(coupled).gain.mask.empty());
        CHECK(network_step_config(config_from_text(split_config("", "gain_structure = \"full\"\n"))).gain.mask.empty());
    }
    SECTION("a disturbance into both subsystems joins them") {
        std::string text = split_config();
        const std::string g = "g = [[\"0\"], [\"0\"], [\"1\"]]";
        text.replace(text.find(g), g.size(), "g = [[\"1\"], [\"0\"], [\"1\"]]");
        CHECK(network_step_config(config_from_text(text)).gain.mask.empty());
    }
    SECTION("the paper's missile: two positions see only their own output, the third and the velocities the rest") {
        ConfigDoc doc = ConfigDoc::from_file(std::string(HINF_SOURCE_DIR) + "/runs/missile_hinf.toml");
        doc.set("filter.variant=\"gain\"");
        const RunConfig cfg = load_run_config(doc);
        const std::vector<double> mask = gain_component_mask(cfg);
        for (int a = 0; a < 6; ++a)
            for (int j = 0; j < 6; ++j) {
                INFO("state " << a << ", output " << j);
                CHECK(mask[a * 6 + j] == ((a == j || (a >= 2 && j >= 2)) ? 1.0 : 0.0));
            }
    }
    SECTION("Van der Pol with a position sensor is one component: no mask") {
        ConfigDoc doc = ConfigDoc::from_file(std::string(HINF_SOURCE_DIR) + "/runs/vanderpol.toml");
        doc.set("filter.variant=\"gain\"");
        CHECK(network_step_config(load_run_config(doc)).gain.mask.empty());
    }
    SECTION("refused in one line for another variant") {
        std::string text = split_config("", "gain_structure = \"components\"\n");
        text.replace(text.find("variant = \"gain\""), 16, "variant = \"dissipative\"");
        CHECK_THROWS_WITH(config_from_text(text), Catch::Contains("gain_structure: shapes the gain K(x^)"));
    }
}

TEST_CASE("gain structure: a trained gain has the zeros, and a checkpoint without the key reads as full",
          "[train][gain][structure]") {
    test::TempDir d("gain-structure");
    const RunConfig cfg = config_from_text(split_config());
    TrainOptions opt;
    opt.out_dir = d / "run";
    opt.quiet = true;
    REQUIRE(train_start(cfg, opt).status == 0);
    RunConfig trained;
    const std::unique_ptr<FrozenNetwork> net = ckpt_frozen_network(d / "run/checkpoint.h5", &trained);
    CHECK(trained.gain_structure == "components");
    for (const std::string& set : ckpt_as_trained(d / "run/checkpoint.h5")) CHECK(set.find("gain_structure") == std::string::npos);
    // gain networks written before the key learned every entry: they read (and resume) as "full"
    for (const char* legacy : {"gain_constant_s_checkpoint.h5", "gain_tv_mean_checkpoint.h5"}) {
        const std::string path = std::string(HINF_SOURCE_DIR) + "/tests/corpus/legacy/" + legacy;
        INFO(path);
        const std::vector<std::string> sets = ckpt_as_trained(path);
        CHECK(std::find(sets.begin(), sets.end(), "network.gain_structure=\"full\"") != sets.end());
        CHECK(ckpt_config(path).gain_structure == "full");
    }
    for (const double xa : {-1.0, 0.3, 2.0}) {
        const double xhat[3] = {xa, 0.5 * xa, -xa};
        double K[6];
        net->gain(K, nullptr, nullptr, xhat, 0.4, *cfg.system, 1);
        INFO("K = " << K[0] << " " << K[1] << " / " << K[2] << " " << K[3] << " / " << K[4] << " " << K[5]);
        CHECK(K[1] == 0.0);  // a from y2
        CHECK(K[2] == 0.0);  // b from y1
        CHECK(K[4] == 0.0);  // c from y1
        CHECK(K[0] != 0.0);
        CHECK(K[3] != 0.0);
        CHECK(K[5] != 0.0);
    }
}
