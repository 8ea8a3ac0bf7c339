// A system written in other units trains the same filter. Every state, initial error and noise of a Van der Pol
// system of one's own multiplied by 10^6 or 10^-6 (its model rewritten so that the scaled states follow the same
// flow) must give the same level rho, the same losses to rounding and the same selected checkpoint: every scale
// hinf chooses by default (error floor, error and innovation scales, storage, level, Q = I through rho*) follows the
// units, and no absolute constant stands in for one (docs/method.md section 16.4, "Units"; measured on full
// trainings; docs/byos.md "Units" says it to users).
#include <catch2/catch.hpp>
#include <cstdio>
#include <string>
#include <vector>

#include "helpers.hpp"
#include "hinf/h5.hpp"

namespace {

std::string num(double v) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", v);
    return buf;
}

// the defaults of a system of one's own: no variant, rho, Q, error floor or objective named
std::string vdp_in_units(double s) {
    return R"([system]
kind = "expr"
states = ["p", "w"]
disturbances = 1
measurements = 1
parameters = { mu = 1.0, c = 0.3, s = )" +
           num(s) + R"( }
f = ["w", "mu*(1 - (p/s)^2)*w - p"]
g = [["0"], ["1"]]
h = ["p + c*p^3/s^2"]
[filter]
x0 = [)" + num(2 * s) +
           R"(, 0.0]
xhat0 = [)" + num(0.5 * s) +
           ", " + num(s) + R"(]
dt = 0.01
t_final = 0.4
)" + hinf::test::tiny_network_and_training() +
           R"(acceptance_runs = 0
[online]
disturbance_std = )" +
           num(0.5 * s) + R"(
noise_std = )" + num(0.1 * s) +
           R"(
)";
}

struct Trained {
    std::vector<double> loss, xhat;
    double rho = 0, select_score = 0, select_step = -1;
};

Trained train_in_units(const hinf::test::TempDir& d, const std::string& name, double s) {
    const std::string cfg = hinf::test::write_file(d, name + ".toml", vdp_in_units(s));
    const auto r = hinf::test::run_hinf("train " + cfg + " --out " + (d / name) + " --quiet");
    INFO(r.output);
    REQUIRE(r.status == 0);
    Trained t;
    {
        hinf::h5::Handle f = hinf::h5::open_file(d / (name + "/trajectory.h5"), false);
        t.loss = hinf::h5::read_doubles(f.get(), "loss");
        t.xhat = hinf::h5::read_doubles(f.get(), "xhat");
    }
    hinf::h5::Handle b = hinf::h5::open_file(d / (name + "/best.h5"), false);
    t.select_score = hinf::h5::get_attr_double(b.get(), "select_score");
    t.select_step = hinf::h5::get_attr_double(b.get(), "select_step");
    t.rho = hinf::test::config_from_text(hinf::h5::read_string(b.get(), "config")).rho;
    return t;
}

}  // namespace

TEST_CASE("a system written in other units trains the same filter (states scaled by 1e6 and 1e-6)", "[gain][units]") {
    hinf::test::TempDir d("units");
    const Trained one = train_in_units(d, "one", 1.0);
    REQUIRE(one.loss.size() > 40);
    for (double s : {1e6, 1e-6}) {
        INFO("scale " << s);
        const Trained other = train_in_units(d, s > 1 ? "mega" : "micro", s);
        CHECK(other.rho == Approx(one.rho).epsilon(1e-9));
        // the losses are ratios to the game's own scales: the same numbers, up to rounding carried through training
        CHECK(hinf::test::max_rel_diff(other.loss, one.loss) < 1e-6);
        std::vector<double> back(other.xhat);
        for (double& v : back) v /= s;
        CHECK(hinf::test::max_rel_diff(back, one.xhat, 1e-9) < 1e-6);
        CHECK(other.select_step == one.select_step);
        CHECK(other.select_score == Approx(one.select_score * s * s).epsilon(1e-6));  // Q = I: a square of the units
    }
}
