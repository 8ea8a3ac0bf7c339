// The time-varying storage's per-state scale (network.storage_scaling, docs/method.md section 16.7 "Scales"): with
// "output" the initial Riccati gain K = rho S^-1 H' gives K H ~ rate on every measured state, whatever the states'
// error scales; "mean" (one scalar, the first S(t)) starts a state with a small error scale at a gain
// rate dx_j^2 / mean(dy^2). Single-output systems keep the error scale bit for bit. An S(t) checkpoint written before
// the key existed is read with "mean" and resumes as trained.
#include <catch2/catch.hpp>
#include <algorithm>
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
#include "train/trainer.hpp"

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

using hinf::test::config_from_text;

}  // namespace

TEST_CASE("storage_scaling: the initial Riccati gain is the same rate on every measured state", "[gain][scaling]") {
    const hinf::RunConfig out = config_from_text(two_scale_config());
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
    const hinf::RunConfig mean = config_from_text(two_scale_config("storage_scaling = \"mean\"\n"));
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
    const hinf::RunConfig c = config_from_text(text);
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
    const hinf::RunConfig c = config_from_text(hinf::test::tiny_vdp_gain_config("0.5"));
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
    // and, from before network.storage_init: flat knots and the margin of then (0.02; now 0 with S(t))
    CHECK(hinf::ckpt_config(dir + "/checkpoint.h5").storage_init == "flat");
    CHECK(hinf::ckpt_config(dir + "/checkpoint.h5").margin == 0.02);
    CHECK(config_from_text(two_scale_config()).margin == 0.0);
    auto r = hinf::test::run_hinf("resume " + dir + "/checkpoint.h5 --quiet");
    INFO(r.output);
    REQUIRE(r.status == 0);
    hinf::h5::Handle got = hinf::h5::open_file(dir + "/checkpoint.h5", false);
    hinf::h5::Handle want = hinf::h5::open_file(source_path("tests/corpus/legacy/gain_tv_mean_full.h5"), false);
    for (const char* name : {"network/layer_1/W", "network/layer_2/W", "network/storage"})
        hinf::test::check_legacy_array(hinf::h5::read_doubles(got.get(), name),
                                       hinf::h5::read_doubles(want.get(), name));
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

namespace {
// two decoupled linear states, both measured (H = I), the disturbance on b: the information-form Riccati equations
// are scalar, Sa' = 0.2 Sa - Qa + rho and Sb' = 0.4 Sb - Qb - Sb^2 / rho + rho
std::string riccati_config(double rho, double q) {
    std::string text = two_scale_config("storage_knots = 4\nstorage_init = \"riccati\"\n");
    auto put = [&text](const std::string& from, const std::string& to) {
        const std::size_t at = text.find(from);
        REQUIRE(at != std::string::npos);
        text.replace(at, from.size(), to);
    };
    put("rho = 0.5", "rho = " + std::to_string(rho));
    put("Q = [1.0, 1.0]", "Q = [" + std::to_string(q) + ", " + std::to_string(q) + "]");
    put("t_final = 0.3", "t_final = 2.0");
    return text;
}
}  // namespace

TEST_CASE("storage_init = riccati: the knots start on the game's Riccati solution", "[gain][scaling][riccati]") {
    const double rho = 4.0, q = 1.0;
    const hinf::RunConfig c = config_from_text(riccati_config(rho, q));
    REQUIRE(c.storage_init == "riccati");
    const hinf::Network<double> net = hinf::network_create<double>(c);
    const hinf::kern::StepConfig& sc = net.step;
    std::vector<double> S(4);
    hinf::kern::gain_storage_eval(S.data(), static_cast<double*>(nullptr), net.theta.data(), 0.0, sc);
    // RK4 of the two scalar equations from the network's S(0), compared at the knots t = 0.5, 1, 1.5, 2
    double sa = S[0], sb = S[3];
    const double s0a = S[0];
    auto fa = [&](double s) { return 0.2 * s - q + rho; };
    auto fb = [&](double s) { return 0.4 * s - q - s * s / rho + rho; };
    const double h = 1e-4;
    int checked = 0;
    for (int step = 1; step <= 20000; ++step) {
        const double a1 = fa(sa), a2 = fa(sa + 0.5 * h * a1), a3 = fa(sa + 0.5 * h * a2), a4 = fa(sa + h * a3);
        const double b1 = fb(sb), b2 = fb(sb + 0.5 * h * b1), b3 = fb(sb + 0.5 * h * b2), b4 = fb(sb + h * b3);
        sa += h / 6 * (a1 + 2 * a2 + 2 * a3 + a4);
        sb += h / 6 * (b1 + 2 * b2 + 2 * b3 + b4);
        if (step % 5000 == 0) {
            const double t = step * h;
            hinf::kern::gain_storage_eval(S.data(), static_cast<double*>(nullptr), net.theta.data(), t, sc);
            INFO("t = " << t << ": S = " << S[0] << ", " << S[3] << " against " << sa << ", " << sb);
            // the sampled recursion (dt = 0.01) against the ODE: first order in dt
            CHECK(S[0] == Approx(sa).epsilon(0.01));
            CHECK(S[3] == Approx(sb).epsilon(0.01));
            CHECK(std::fabs(S[1]) < 1e-9 * std::sqrt(S[0] * S[3]));
            ++checked;
        }
    }
    CHECK(checked == 4);
    CHECK(sa > 1.5 * s0a);  // the information grew: the gain fell
}

TEST_CASE("storage_init = riccati: where the game's Riccati equation loses definiteness S(t) is held at its floor",
          "[gain][scaling][riccati]") {
    // Q / rho = 1.2 against H'H = 1: the information falls slowly (s' = 0.2 s - 0.1 on the first state, in the
    // scaled form) and reaches the floor after the first knot (t = 0.5 s): no H-infinity filter of level rho from this
    // start beyond there. S(t) is held at its floor max(2 eps, rate dt / kappa) in its scale, S(0) = (1 + eps) in it
    const hinf::RunConfig c = config_from_text(riccati_config(0.5, 0.6));
    REQUIRE(c.margin == 0.0);
    const hinf::Network<double> net = hinf::network_create<double>(c);
    const hinf::kern::GainSpec& g = net.step.gain;
    const double lo = std::max(2 * g.eps, g.rate * g.loss.dt / g.loss.kappa), eps = g.eps;
    std::vector<double> S0(4), S(4);
    hinf::kern::gain_storage_eval(S0.data(), static_cast<double*>(nullptr), net.theta.data(), 0.0, net.step);
    hinf::kern::gain_storage_eval(S.data(), static_cast<double*>(nullptr), net.theta.data(), 0.5, net.step);
    for (int e : {0, 3}) CHECK(S[e] > 2 * S0[e] * lo);  // knot 1: the Riccati solution, above the floor
    for (double t : {1.5, 2.0}) {
        INFO("t = " << t);
        hinf::kern::gain_storage_eval(S.data(), static_cast<double*>(nullptr), net.theta.data(), t, net.step);
        // at the floor, but for the last prediction step's contraction on top of it (within 1 %)
        for (int e : {0, 3}) {
            CHECK(S[e] >= S0[e] * lo / (1 + eps) * (1 - 1e-9));
            CHECK(S[e] <= S0[e] * lo / (1 + eps) * 1.01);
        }
        CHECK(std::fabs(S[1]) < 1e-9 * S[0]);
    }
    // held from 1.01 s; the same equation without the floor loses definiteness a little later (t = 1.11 s)
    const double held = hinf::riccati_start_held_later(c), lost = hinf::riccati_start_lost(c);
    CHECK(held > 0.5);
    CHECK(lost > held);
    CHECK(lost < 1.5);
    // a short run's large rate puts the floor max(2 eps, rate dt / kappa) above S(0) itself: held from the start,
    // while without the floor the equation (Q / rho = 0.25) stays positive definite -- the floor is the gain's cap
    std::string capped = riccati_config(4.0, 1.0);
    capped.replace(capped.find("t_final = 2.0"), 13, "t_final = 0.1");
    const hinf::RunConfig cc = config_from_text(capped);
    CHECK(hinf::riccati_start_held_later(cc) == 0.0);
    CHECK(hinf::riccati_start_lost(cc) == -1.0);
    CHECK(hinf::riccati_start_lost(config_from_text(riccati_config(4.0, 1.0))) == -1.0);  // never held, never lost
    // "flat" starts every knot at S(0) and keeps the margin of before
    std::string text = riccati_config(0.5, 0.6);
    text.replace(text.find("\"riccati\""), 9, "\"flat\"");
    const hinf::RunConfig flat = config_from_text(text);
    REQUIRE(flat.storage_init == "flat");
    CHECK(flat.margin == 0.02);
    const hinf::Network<double> fnet = hinf::network_create<double>(flat);
    for (std::size_t e = fnet.step.shape.param_count(); e < fnet.theta.size(); ++e) CHECK(fnet.theta[e] == 0.0);
}

TEST_CASE("storage_init = riccati: held at its floor before the first knot, the knots start flat",
          "[gain][scaling][riccati]") {
    // Q / rho = 200 against H'H = 1: the information falls through zero at once, so every knot after S(0) would sit
    // at the floor (the gain at its sampled-data cap) -- a start far worse than the flat one on a stiff spring chain
    // (docs/method.md section 16.7). The knots start flat, as with storage_init = "flat" (but the margin stays 0).
    const hinf::RunConfig c = config_from_text(riccati_config(0.5, 100.0));
    REQUIRE(c.storage_init == "riccati");
    const hinf::Network<double> net = hinf::network_create<double>(c);
    for (std::size_t e = net.step.shape.param_count(); e < net.theta.size(); ++e) CHECK(net.theta[e] == 0.0);
    CHECK(hinf::riccati_start_held_at_once(c));
    CHECK(hinf::riccati_start_lost(c) == 0.0);  // without the floor: indefinite at the first step
    std::string text = riccati_config(0.5, 100.0);
    text.replace(text.find("\"riccati\""), 9, "\"flat\"");
    CHECK(std::isnan(hinf::riccati_start_lost(config_from_text(text))));  // no Riccati start: nothing to say
}

TEST_CASE("storage_init = riccati: a noise-free trajectory that escapes stops the recursion, the knots stay finite",
          "[gain][scaling][riccati]") {
    // a' = a^2 from a = 1 escapes at t = 1 s; the knots after the stop keep the last one's values
    std::string text = two_scale_config("storage_knots = 8\n");
    auto put = [&text](const std::string& from, const std::string& to) {
        const std::size_t at = text.find(from);
        REQUIRE(at != std::string::npos);
        text.replace(at, from.size(), to);
    };
    put("f = [\"-0.1*a\", \"-0.2*b\"]", "f = [\"a^2\", \"-0.2*b\"]");
    put("x0 = [30.0, 1.0]", "x0 = [1.0, 1.0]");
    put("rho = 0.5", "rho = 4.0");
    put("t_final = 0.3", "t_final = 2.0");
    const hinf::RunConfig c = config_from_text(text);
    REQUIRE(c.storage_init == "riccati");
    const hinf::Network<double> net = hinf::network_create<double>(c);
    const std::int64_t P = net.step.shape.param_count();
    for (std::size_t e = P; e < net.theta.size(); ++e) CHECK(std::isfinite(net.theta[e]));
    // knots 5..8 (t >= 1.25 s, past the escape) equal knot 4's or an earlier one's: the last set before the stop
    const int np = 3;
    for (int e = 0; e < np; ++e) CHECK(net.theta[P + 8 * np + e] == net.theta[P + 5 * np + e]);
}

namespace {
// knot j's log-diagonal for state a set to v in a checkpoint (packed tril per knot, row by row), rewritten whole
template <typename T>
void put_log_diagonal(const std::string& path, int j, int a, double v) {
    hinf::Checkpoint<T> ck = hinf::ckpt_read<T>(path);
    const hinf::RunConfig cfg = hinf::ckpt_config(path);
    const hinf::kern::StepConfig sc = hinf::network_step_config(cfg);
    const int np = cfg.n * (cfg.n + 1) / 2;
    ck.net.theta[sc.shape.param_count() + j * np + a * (a + 1) / 2 + a] = T(v);
    hinf::ckpt_write(path, ck, cfg);
}
}  // namespace

TEST_CASE("a knot whose log-diagonal runs below the runaway level is said once and recorded in the summary",
          "[cli][gain][scaling]") {
    // method.md 16.7 "Why 280 knots fail": every failed missile training had a knot there, no good one had
    hinf::test::TempDir d("runaway");
    std::ofstream(d / "k.toml") << two_scale_config("storage_knots = 4\n");
    const hinf::RunConfig cfg = config_from_text(two_scale_config("storage_knots = 4\n"));
    const double level = hinf::storage_runaway_level(hinf::network_step_config(cfg).gain);
    CHECK(level == Approx(0.5 * std::log(1e-3) - 3.0));
    const hinf::StorageLow start = hinf::storage_lowest_log_diagonal(hinf::network_create<double>(cfg));
    CHECK(start.knot >= 0);
    CHECK(start.value > level);
    // knot 2 (t = 0.15 s) of state b put where a run-away knot sits, in a run stopped at 0.1 s
    auto stopped = [&](const std::string& dir) {
        auto r = hinf::test::run_hinf("train " + (d / "k.toml") + " --out " + (d / dir) + " --until 0.1");
        INFO(r.output);
        REQUIRE(r.status == 0);
        CHECK(r.output.find("no longer moves S(t)") == std::string::npos);
        const std::string ck = d / (dir + "/checkpoint.h5");
        if (hinf::ckpt_precision(ck) == "float")
            put_log_diagonal<float>(ck, 2, 1, level - 5.0);
        else
            put_log_diagonal<double>(ck, 2, 1, level - 5.0);
        return ck;
    };
    // the CLI says so once, naming the knot, the state, and this knot count with fewer to compare
    auto s = hinf::test::run_hinf("resume " + stopped("cli"));
    INFO(s.output);
    REQUIRE(s.status == 0);
    const std::string note = "the storage's knot 2 (of 0-4; t = 0.15 s) has the log-diagonal of state b at";
    const std::size_t at = s.output.find(note);
    CHECK(at != std::string::npos);
    CHECK(s.output.find(note, at + 1) == std::string::npos);
    CHECK(s.output.find("storage_knots=4,2,1") != std::string::npos);  // this count beside fewer
    // the library's summary records it
    hinf::TrainOptions opt;
    opt.out_dir = d / "lib";
    opt.quiet = true;
    const hinf::TrainSummary sum = hinf::train_resume(stopped("lib"), opt);
    CHECK(sum.status == 0);
    CHECK(sum.runaway_step == sum.first_step + 1);
    CHECK(sum.runaway_knot == 2);
    CHECK(sum.runaway_state == 1);
    CHECK(sum.runaway_value < level);
}
