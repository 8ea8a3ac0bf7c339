// The time-varying storage's per-state scale (network.storage_scaling, docs/method.md section 16.7 "Scales"): with
// "output" the initial Riccati gain K = rho S^-1 H' gives K H ~ rate on every measured state, whatever the states'
// error scales; "mean" (one scalar, the first S(t)) starts a state with a small error scale at a gain
// rate dx_j^2 / mean(dy^2). Single-output systems keep the error scale bit for bit. An S(t) checkpoint written before
// the key existed is read with "mean" and resumes as trained.
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <vector>

#include "config/run_config.hpp"
#include "gain.hpp"
#include "helpers.hpp"
#include "hinf/config.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"
#include "net/network.hpp"

namespace {

// two states thirty times apart in their initial errors, both measured
std::string two_scale_config(const std::string& extra = "") {
    return R"([system]
kind = "expr"
states = ["a", "b"]
disturbances = 1
measurements = 2
f = ["-0.1*a", "-0.2*b"]
g = [["0"], ["1"]]
h = ["a", "b"]
[filter]
variant = "gain"
rho = 0.5
Q = [1.0, 1.0]
x0 = [30.0, 1.0]
xhat0 = [0.0, 0.0]
dt = 0.01
t_final = 0.3
[network]
hidden = [8]
)" + extra + R"(
[training]
samples = 60
batch = 30
adam_steps = 2
checkpoint_every = 10
acceptance_runs = 0
[sampling]
trajectories = 2
[online]
mode = "measured"
disturbance_std = 0.5
noise_std = 0.1
)";
}

// K H at the start (all knots zero: M = I) for the config's H = I: diag(rho S(0)^-1)
std::vector<double> initial_gain(const hinf::RunConfig& cfg) {
    const hinf::kern::StepConfig sc = hinf::network_step_config(cfg);
    const int n = cfg.n;
    std::vector<double> theta(sc.shape.param_count() + sc.gain.storage_params(n), 0.0), S(n * n);
    hinf::kern::gain_storage_eval(S.data(), static_cast<double*>(nullptr), theta.data(), 0.0, sc);
    REQUIRE(std::fabs(S[1]) < 1e-300);  // diagonal at the start
    return {cfg.rho / S[0], cfg.rho / S[3]};
}

hinf::RunConfig load(const std::string& text) { return hinf::load_run_config(hinf::ConfigDoc::from_text(text, "t.toml")); }

}  // namespace

TEST_CASE("storage_scaling: the initial Riccati gain is the same rate on every measured state", "[gain][scaling]") {
    const hinf::RunConfig out = load(two_scale_config());
    REQUIRE(out.storage_scaling == "output");
    REQUIRE(out.storage_knots > 0);
    const double rate = hinf::network_step_config(out).gain.rate, eps = hinf::network_step_config(out).gain.eps;
    const std::vector<double> k = initial_gain(out);
    CHECK(k[0] == Approx(rate / (1 + eps)).epsilon(1e-9));
    CHECK(k[1] == Approx(rate / (1 + eps)).epsilon(1e-9));
    // the correction's scale: o = 1 everywhere adds rate dx_a / dy_j to K_aj (the constant head's gain scale), so
    // the large output's innovation does not flood the small state
    {
        const hinf::kern::StepConfig sc = hinf::network_step_config(out);
        const hinf::kern::GainSpec& g = sc.gain;
        std::vector<double> theta(sc.shape.param_count() + g.storage_params(2), 0.0), S(4), K(4);
        hinf::kern::gain_storage_eval(S.data(), static_cast<double*>(nullptr), theta.data(), 0.0, sc);
        const double H[4] = {1, 0, 0, 1}, o[4] = {1, 1, 1, 1};
        hinf::kern::gain_riccati_forward(K.data(), o, S.data(), H, g, 2, 2, out.rho);
        for (int a = 0; a < 2; ++a)
            for (int j = 0; j < 2; ++j)
                CHECK(K[a * 2 + j] == Approx(rate / (1 + eps) * ((a == j ? 1.0 : 0.0) + g.dx[a] / g.dy[j])).epsilon(1e-9));
    }
    // one scalar: the small state starts about 10^3 times slower (rate dx_b^2 / mean(dy^2), dx = |x~0| + floor)
    const hinf::RunConfig mean = load(two_scale_config("storage_scaling = \"mean\"\n"));
    const std::vector<double> km = initial_gain(mean);
    CHECK(km[1] < 2e-3 * km[0]);
    CHECK(km[0] > rate);
}

TEST_CASE("storage_scaling: a Jacobian that vanishes at x^0 does not ask for a gain of 1/H", "[gain][scaling]") {
    // h = [a, b^2] at b^ = 1e-7: dh/db = 2e-7, a share of (2e-7 dx_b)^2 against a's dx_a^2; b counts as unseen and
    // starts from the seen state's mean in its own scale, as an unmeasured state does
    std::string text = two_scale_config();
    const std::string h = "h = [\"a\", \"b\"]", x = "xhat0 = [0.0, 0.0]";
    text.replace(text.find(h), h.size(), "h = [\"a\", \"b^2\"]");
    text.replace(text.find(x), x.size(), "xhat0 = [0.0, 1e-7]");
    const hinf::RunConfig c = load(text);
    const hinf::kern::StepConfig sc = hinf::network_step_config(c);
    const hinf::kern::GainSpec& g = sc.gain;
    std::vector<double> theta(sc.shape.param_count() + g.storage_params(2), 0.0), S(4);
    hinf::kern::gain_storage_eval(S.data(), static_cast<double*>(nullptr), theta.data(), 0.0, sc);
    // seen = (1 * dx_a^2 + 4e-14 dx_b^2) / 2 (both counted in the mean); S_bb = (rho / rate)(1 + eps) seen / dx_b^2
    const double seen = (g.dx[0] * g.dx[0] + 4e-14 * g.dx[1] * g.dx[1]) / 2;
    CHECK(S[3] == Approx(c.rho / g.rate * (1 + g.eps) * seen / (g.dx[1] * g.dx[1])).epsilon(1e-9));
    CHECK(S[0] == Approx(c.rho / g.rate * (1 + g.eps)).epsilon(1e-9));
}

TEST_CASE("storage_scaling: one output keeps the error scale bit for bit", "[gain][scaling]") {
    const hinf::RunConfig c = load(hinf::test::tiny_vdp_gain_config("0.5"));
    REQUIRE(c.storage_knots > 0);
    const hinf::kern::GainSpec g = hinf::network_step_config(c).gain;
    for (int a = 0; a < c.n; ++a) CHECK(g.storage_dx()[a] == g.dx[a]);
}

TEST_CASE("an S(t) checkpoint from before storage_scaling loads with the one-scalar scale and resumes as trained",
          "[cli][gain][scaling]") {
    // fixtures written by the hinf of commit 821b096 (before the key) from tests/corpus/legacy/gain_tv_mean.toml
    // (= two_scale_config() above): the 0.1 s checkpoint with its trajectory, and the 0.3 s checkpoint of the full run
    using hinf::test::source_path;
    hinf::test::TempDir d("scalelegacy");
    const std::string dir = d / "run";
    hinf::test::copy_legacy_run("gain_tv_mean", dir);
    CHECK(hinf::ckpt_config(dir + "/checkpoint.h5").storage_scaling == "mean");
    auto r = hinf::test::run_hinf("resume " + dir + "/checkpoint.h5 --quiet");
    INFO(r.output);
    REQUIRE(r.status == 0);
    hinf::h5::Handle got = hinf::h5::open_file(dir + "/checkpoint.h5", false);
    hinf::h5::Handle want = hinf::h5::open_file(source_path("tests/corpus/legacy/gain_tv_mean_full.h5"), false);
    for (const char* name : {"network/layer_1/W", "network/layer_2/W", "network/storage"})
        CHECK(hinf::h5::read_doubles(got.get(), name) == hinf::h5::read_doubles(want.get(), name));
    const std::string text = hinf::h5::read_string(got.get(), "config");
    CHECK(text.find("network.storage_scaling=\"mean\"") != std::string::npos);
    CHECK(hinf::ckpt_config(dir + "/checkpoint.h5").storage_scaling == "mean");
    // the same config trained now starts from the per-state scale: another network
    std::ofstream(d / "now.toml") << two_scale_config();
    auto now = hinf::test::run_hinf("train " + (d / "now.toml") + " --out " + (d / "now") + " --quiet");
    INFO(now.output);
    REQUIRE(now.status == 0);
    hinf::h5::Handle fresh = hinf::h5::open_file(d / "now/checkpoint.h5", false);
    CHECK(hinf::h5::read_doubles(fresh.get(), "network/storage") != hinf::h5::read_doubles(want.get(), "network/storage"));
}
