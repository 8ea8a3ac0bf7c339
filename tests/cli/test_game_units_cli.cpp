// No validated checkpoint (docs/method.md section 16.7): where a `gain` run at the default level, its [online] stds
// plain numbers, keeps no checkpoint (every validation diverged), hinf train trains the game in units of each
// channel's noise in DIR/alternative and keeps it in DIR when it validates. A gain network weighted otherwise than
// the config then filters the same through compare (the measurements are converted), and operate refuses it.
#include <catch2/catch.hpp>
#include <fstream>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "helpers.hpp"
#include "io/checkpoint.hpp"

using hinf::test::run_hinf;

namespace {

// Seborg's exothermic reactor, the temperature measured: from this unstable operating point the truth ignites near
// t = 2 s. In the config's units the game trusts the 0.5 K sensor as much as the 0.02 mol/L/s disturbance, and every
// validation of the trained filter diverged (measured when this test was written); in units of each channel's noise
// it validates.
const char* kReactor = R"toml([system]
kind = "expr"
states = ["c", "T"]
disturbances = 1
measurements = 1
f = ["q/V*(cf - c) - k0*exp(-ER/T)*c", "q/V*(tf - T) + dh/(rho*cp)*k0*exp(-ER/T)*c + ua/(V*rho*cp)*(tc - T)"]
g = [["1"], ["0"]]
h = ["T"]
[system.parameters]
q = 100
V = 100
cf = 1
tf = 350
k0 = 7.2e10
ER = 8750
dh = 5e4
rho = 1000
cp = 0.239
ua = 5e4
tc = 300
[filter]
x0 = [0.5, 350]
xhat0 = [0.8, 345]
dt = 0.01
t_final = 3
[training]
samples = 400
batch = 100
adam_steps = 5
acceptance_runs = 0
[online]
disturbance_std = 0.02
noise_std = 0.5
)toml";

bool names_noise_list(const std::string& checkpoint) {
    return hinf::ckpt_read<float>(checkpoint).config_text.find("noise_std = [") != std::string::npos;
}

// compare's row of `filter`, without its last four columns (the ratio, in the config's game units, MSEp, MSEf and
// the time per step)
std::string row_without_ratio(const std::string& output, const std::string& filter) {
    std::istringstream lines(output);
    std::string line;
    while (std::getline(lines, line)) {
        if (line.rfind(filter + " ", 0) != 0) continue;
        std::istringstream words(line);
        std::vector<std::string> w;
        std::string word;
        while (words >> word) w.push_back(word);
        REQUIRE(w.size() > 4);
        std::string kept;
        for (std::size_t i = 0; i + 4 < w.size(); ++i) kept += w[i] + " ";
        return kept;
    }
    FAIL("no row '" + filter + "' in: " + output);
    return "";
}

}  // namespace

TEST_CASE("a run with no validated checkpoint trains the game in units of each channel's noise and keeps it",
          "[cli][train]") {
    hinf::test::TempDir d("game-units");
    const std::string out = d / "run";
    std::ofstream(d / "reactor.toml") << kReactor;
    auto r = run_hinf("train " + (d / "reactor.toml") + " --quiet --out " + out);
    INFO(r.output);
    REQUIRE(r.status == 0);
    // the diagnostic filter of the first run lost its estimate at the ignition, and training went on
    CHECK(r.output.find("the diagnostic filter (the network being trained") != std::string::npos);
    REQUIRE(r.output.find("no checkpoint of this run validated without divergence") != std::string::npos);
    REQUIRE(r.output.find("the game in units of each channel's noise validated") != std::string::npos);
    REQUIRE(std::filesystem::exists(out + "/best.h5"));
    CHECK(names_noise_list(out + "/checkpoint.h5"));
    CHECK(names_noise_list(out + "/best.h5"));
    CHECK_FALSE(names_noise_list(out + "/alternative/checkpoint.h5"));
    CHECK_FALSE(std::filesystem::exists(out + "/alternative/best.h5"));
    // the level and Q are hinf's defaults, recorded as such (the first run's start check also switched it to flat
    // knots); the kept game's level is its own default
    const std::vector<std::string> first_chose = hinf::ckpt_config(out + "/alternative/checkpoint.h5").chosen;
    REQUIRE(first_chose.size() >= 2u);
    CHECK(first_chose[0] == "filter.rho");
    CHECK(first_chose[1] == "filter.Q");
    const std::vector<std::string> kept_chose = hinf::ckpt_config(out + "/best.h5").chosen;
    REQUIRE(kept_chose.size() >= 2u);
    CHECK(kept_chose[0] == "filter.rho");
    CHECK(kept_chose[1] == "filter.Q");

    // the same run stopped half way and resumed to t_final ends as the run uninterrupted: its default level is read
    // as a default, so it trains the game in noise units too, and keeps the same network
    const auto first = run_hinf("train " + (d / "reactor.toml") + " --quiet --until 1.5 --out " + (d / "split"));
    INFO(first.output);
    REQUIRE(first.status == 0);
    CHECK(first.output.find("no checkpoint of this run validated") == std::string::npos);  // (stopped early)
    const auto rest = run_hinf("resume " + (d / "split/checkpoint.h5") + " --quiet");
    INFO(rest.output);
    REQUIRE(rest.status == 0);
    CHECK(rest.output.find("the game in units of each channel's noise validated") != std::string::npos);
    REQUIRE(std::filesystem::exists(d / "split/best.h5"));
    CHECK(names_noise_list(d / "split/best.h5"));
    CHECK(hinf::ckpt_read<float>(d / "split/best.h5").net.theta == hinf::ckpt_read<float>(out + "/best.h5").net.theta);

    // compare converts the plain config's measurements for the weighted network: the same estimates as with the
    // training's list (without the conversion, the plain config's run had a temperature error of 27 K)
    {
        std::string text = kReactor;
        text.replace(text.find("noise_std = 0.5"), 15, "noise_std = [0.5]");
        std::ofstream(d / "reactor_list.toml") << text;
    }
    const std::string common = " --network " + out + "/best.h5 --filters dnn,ekf --runs 4 --quiet";
    const auto plain = run_hinf("compare " + (d / "reactor.toml") + common + " --out " + (d / "cmp_plain"));
    const auto listed = run_hinf("compare " + (d / "reactor_list.toml") + common + " --out " + (d / "cmp_list"));
    INFO(plain.output);
    INFO(listed.output);
    REQUIRE(plain.status == 0);
    REQUIRE(listed.status == 0);
    CHECK(row_without_ratio(plain.output, "dnn_gain_measured") == row_without_ratio(listed.output, "dnn_gain_measured"));
    CHECK(row_without_ratio(plain.output, "ekf") == row_without_ratio(listed.output, "ekf"));

    // operate runs the network's game on the config: it refuses the other weighting, and runs with the training's
    const auto refused = run_hinf("operate " + (d / "reactor.toml") + " --network " + out + "/best.h5 --runs 1 --quiet" +
                                  " --out " + (d / "op"));
    CHECK(refused.status != 0);
    CHECK(refused.output.find("weighs the channels otherwise") != std::string::npos);
    const auto ran = run_hinf("operate " + (d / "reactor_list.toml") + " --network " + out +
                              "/best.h5 --runs 1 --quiet --out " + (d / "op"));
    CHECK(ran.status == 0);
}

TEST_CASE("a config that names its level keeps its game when no checkpoint validates", "[cli][train]") {
    hinf::test::TempDir d("game-units-rho");
    std::ofstream(d / "reactor.toml") << kReactor;
    auto r = run_hinf("train " + (d / "reactor.toml") + " --quiet --set filter.rho=1.5 --out " + (d / "run"));
    INFO(r.output);
    REQUIRE(r.status == 0);
    REQUIRE(r.output.find("no checkpoint validated without divergence") != std::string::npos);
    CHECK(r.output.find("validated without divergence. Its game") == std::string::npos);
    CHECK_FALSE(std::filesystem::exists(d / "run/alternative"));
    CHECK_FALSE(names_noise_list(d / "run/checkpoint.h5"));
}

TEST_CASE("a diagnostic filter lost from flat knots restarts and a resumed run keeps the bits", "[cli][train]") {
    // flat knots at rho = 1.5: the diagnostic filter is lost at the ignition (t = 2.1 when this test was written); one
    // run to the end against a run stopped at t = 1.5 and resumed
    hinf::test::TempDir d("game-units-resume");
    std::ofstream(d / "reactor.toml") << kReactor;
    const std::string set =
        " --quiet --set filter.rho=1.5 --set network.storage_init=flat --set training.select_every=0";
    const auto whole = run_hinf("train " + (d / "reactor.toml") + set + " --out " + (d / "whole"));
    INFO(whole.output);
    REQUIRE(whole.status == 0);
    REQUIRE(whole.output.find("the diagnostic filter (the network being trained") != std::string::npos);
    const auto first = run_hinf("train " + (d / "reactor.toml") + set + " --until 1.5 --out " + (d / "split"));
    INFO(first.output);
    REQUIRE(first.status == 0);
    CHECK(first.output.find("the diagnostic filter (the network being trained") == std::string::npos);
    const auto rest = run_hinf("resume " + (d / "split/checkpoint.h5") + " --quiet");
    INFO(rest.output);
    REQUIRE(rest.status == 0);
    CHECK(rest.output.find("the diagnostic filter (the network being trained") != std::string::npos);
    const auto a = hinf::ckpt_read<float>(d / "whole/checkpoint.h5"), b = hinf::ckpt_read<float>(d / "split/checkpoint.h5");
    CHECK(a.state.step == b.state.step);
    CHECK(hinf::test::bitwise_equal(a.net.theta, b.net.theta));
    CHECK(hinf::test::bitwise_equal(a.state.xhat, b.state.xhat));  // the restarted diagnostic estimate too
}
