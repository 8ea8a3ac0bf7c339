// What the outputs tell about each state (eval/observability.hpp): an unmeasured state that drives nothing keeps the
// open loop's error variance exactly, growing as the open loop's does where it is unstable; one that drives the
// measured state is seen; the note names the first and not the second; discrete time and a noiseless sensor run.
#include <catch2/catch.hpp>
#include <cmath>

#include "eval/observability.hpp"
#include "helpers.hpp"

using namespace hinf;

namespace {

// x1' = -x1 + 0.5 sin(x1) + c x2 + v1, x2' = a x2 + v2, y = x1 + n: x2 is seen only through c
RunConfig unseen_pair(double a, double c, const std::string& time = "", const std::string& noise = "0.1") {
    return load_run_config(ConfigDoc::from_text(
        "[system]\nkind = \"expr\"\n" + time + "states = [\"x1\", \"x2\"]\ndisturbances = 2\nmeasurements = 1\n"
        "parameters = { a = " + std::to_string(a) + ", c = " + std::to_string(c) + " }\n"
        "f = [\"-x1 + 0.5*sin(x1) + c*x2\", \"a*x2\"]\ng = [[\"1\", \"0\"], [\"0\", \"1\"]]\nh = [\"x1\"]\n"
        "[filter]\nrho = 5\nx0 = [1.0, 1.0]\nxhat0 = [0.0, 0.0]\ndt = 0.01\nt_final = 10\n"
        "[online]\ndisturbance_std = 0.3\nnoise_std = " + noise + "\n",
        "pair.toml"));
}

bool contains_text(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

}  // namespace

TEST_CASE("state information: a state that drives no output keeps the open loop's variance", "[eval][observability]") {
    const StateInformation s = state_information(unseen_pair(-0.5, 0.0));
    REQUIRE(s.ran);
    CHECK(s.steps == 1000);
    CHECK(s.ratio[0] < 0.1);                     // x1 is measured
    CHECK(std::fabs(s.ratio[1] - 1.0) < 1e-12);  // x2: the same recursion with and without measurements
    CHECK(s.growth[1] < 1.0);                    // and it settles on its own
    const std::string note = unseen_states_note(unseen_pair(-0.5, 0.0), s);
    INFO(note);
    CHECK(contains_text(note, "hinf: note: the outputs tell next to nothing about x2: "));
    CHECK(contains_text(note, "keeps 100 % of the open-loop predictor's error variance"));
    CHECK_FALSE(contains_text(note, "no filter can estimate"));
}

TEST_CASE("state information: an unstable state no output sees grows as the open loop's", "[eval][observability]") {
    const RunConfig c = unseen_pair(0.3, 0.0);
    const StateInformation s = state_information(c);
    REQUIRE(s.ran);
    CHECK(std::fabs(s.ratio[1] - 1.0) < 1e-12);
    // continuous time: P(t) = e^(2at) (P0 + q / 2a) - q / 2a with P0 = 1, q = 0.09: from t = 5 to 10, 20.2 times
    const double k = 0.09 / 0.6, want = (std::exp(6.0) * (1 + k) - k) / (std::exp(3.0) * (1 + k) - k);
    CHECK(std::fabs(s.growth[1] / want - 1) < 0.05);
    const std::string note = unseen_states_note(c, s);
    INFO(note);
    CHECK(contains_text(note, "and that still grows (x2 "));
    CHECK(contains_text(note, "no filter can estimate it from these outputs"));
}

TEST_CASE("state information: a state that drives the measured one is seen", "[eval][observability]") {
    for (double a : {-0.5, 0.3}) {
        const RunConfig c = unseen_pair(a, 1.0);
        const StateInformation s = state_information(c);
        REQUIRE(s.ran);
        INFO("a = " << a);
        CHECK(s.ratio[0] < 0.1);
        CHECK(s.ratio[1] < 0.5);  // 0.25 at a = -0.5 when written: the disturbance on x1 masks part of it
        CHECK(unseen_states_note(c, s).empty());
    }
}

TEST_CASE("state information: discrete time and a noiseless sensor", "[eval][observability]") {
    // x1(k+1) = x1 - 0.01 x1 + ... : the same pair stepped as a map; x2 unseen
    const RunConfig d = load_run_config(ConfigDoc::from_text(
        "[system]\nkind = \"expr\"\ntime = \"discrete\"\nstates = [\"x1\", \"x2\"]\ndisturbances = 2\n"
        "measurements = 1\nf = [\"0.9*x1 + 0.1*sin(x1)\", \"0.95*x2\"]\ng = [[\"1\", \"0\"], [\"0\", \"1\"]]\n"
        "h = [\"x1\"]\n[filter]\nrho = 5\nx0 = [1.0, 1.0]\nxhat0 = [0.0, 0.0]\ndt = 1\nt_final = 100\n"
        "[online]\ndisturbance_std = 0.3\nnoise_std = 0.1\n",
        "map.toml"));
    const StateInformation s = state_information(d);
    REQUIRE(s.ran);
    CHECK(s.ratio[0] < 0.2);
    CHECK(std::fabs(s.ratio[1] - 1.0) < 1e-12);
    CHECK(contains_text(unseen_states_note(d, s), "about x2: "));
    // a noiseless sensor (the Bayesian filters told another noise in [baseline]): runs, and sees x2 as above
    const StateInformation z = state_information(unseen_pair(-0.5, 1.0, "", "0\n[baseline]\nnoise_std = 0.1"));
    REQUIRE(z.ran);
    CHECK(z.ratio[1] < 0.5);
}

TEST_CASE("hinf rho and hinf train say which states the outputs tell next to nothing about", "[cli][observability]") {
    hinf::test::TempDir d("observability");
    const auto config = [&](const std::string& name, const std::string& f2) {
        return hinf::test::write_file(
            d, name,
            "[system]\nkind = \"expr\"\nstates = [\"x1\", \"x2\"]\ndisturbances = 2\nmeasurements = 1\n"
            "f = [\"-x1 + 0.5*sin(x1)\", \"" + f2 + "\"]\ng = [[\"1\", \"0\"], [\"0\", \"1\"]]\nh = [\"x1\"]\n"
            "[filter]\nx0 = [1.0, 1.0]\nxhat0 = [0.0, 0.0]\ndt = 0.01\nt_final = 4\n[network]\nhidden = [8]\n"
            "[training]\nsamples = 100\nbatch = 40\nadam_steps = 2\n[online]\ndisturbance_std = 0.3\n"
            "noise_std = 0.1\n");
    };
    const std::string unstable = config("unstable.toml", "0.5*x2"), seen = config("seen.toml", "x1 - x2");
    auto r = hinf::test::run_hinf("rho " + unstable);
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK(contains_text(r.output, "the outputs tell next to nothing about x2: "));
    CHECK(contains_text(r.output, "no filter can estimate it from these outputs"));
    auto s = hinf::test::run_hinf("rho " + seen);
    INFO(s.output);
    CHECK(s.status == 0);
    CHECK(contains_text(s.output, "the outputs see every state: "));
    // train says it before it trains (the run cut short: the note is what is checked)
    auto t = hinf::test::run_hinf("train " + unstable + " --until 0.05 --quiet --out " + (d / "run"));
    INFO(t.output);
    CHECK(t.status == 0);
    CHECK(contains_text(t.output, "hinf: note: the outputs tell next to nothing about x2: "));
}
