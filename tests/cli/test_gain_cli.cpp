// The gain variant end to end (docs/method.md section 14): train a tiny Van der Pol filter with a position-only
// sensor (m < n), run it through operate, compare, filter and worst in measured mode; --mode oracle is refused in
// one line; a checkpoint whose config was changed is refused.
#include <catch2/catch.hpp>
#include <fstream>

#include "helpers.hpp"
#include "hinf/h5.hpp"

using hinf::test::run_hinf;

namespace {
const std::string kVdp = hinf::test::tiny_vdp_gain_config("0.5");
}  // namespace

TEST_CASE("gain variant: train, operate, compare, filter and worst run it in measured mode only", "[cli][gain]") {
    hinf::test::TempDir d("gaincli");
    const std::string cfg = d / "vdp.toml", net = d / "run/checkpoint.h5";
    std::ofstream(cfg) << kVdp;
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet");
    INFO(t.output);
    REQUIRE(t.status == 0);
    CHECK(t.output.find("acceptance (5 measured runs") != std::string::npos);
    {
        hinf::h5::Handle f = hinf::h5::open_file(net, false);
        CHECK(hinf::h5::has_attr(f.get(), "acceptance_verdict"));
    }
    auto op = run_hinf("operate " + cfg + " --network " + net + " --mode measured --runs 2 --out " + (d / "op"));
    INFO(op.output);
    CHECK(op.status == 0);
    auto orc = run_hinf("operate " + cfg + " --network " + net + " --mode oracle --runs 2 --out " + (d / "op2"));
    CHECK(orc.status == 2);
    CHECK(orc.output.find("--mode oracle is meaningless") != std::string::npos);
    auto cmp = run_hinf("compare " + cfg + " --network " + net + " --filters dnn,ukf --runs 2 --out " + (d / "cmp"));
    INFO(cmp.output);
    CHECK(cmp.status == 0);
    CHECK(cmp.output.find("dnn_gain_measured") != std::string::npos);
    auto cmpo = run_hinf("compare " + cfg + " --network " + net + " --filters dnn --mode oracle --runs 2 --out " +
                         (d / "cmp2"));
    CHECK(cmpo.status == 2);
    auto w = run_hinf("worst " + cfg + " --network " + net + " --filters dnn,ukf --evals 10 --random-starts 1 --scenario-starts none --out " +
                      (d / "worst"));
    INFO(w.output);
    CHECK(w.status == 0);
    CHECK(w.output.find("dnn_gain_measured") != std::string::npos);
    {  // recorded measurements (hinf filter): the gain filter runs on y alone
        std::ofstream rec(d / "rec.csv");
        rec << "t,y0\n";
        for (int k = 0; k < 50; ++k) rec << 0.01 * k << "," << 2.0 - 0.001 * k << "\n";
    }
    auto fl = run_hinf("filter " + cfg + " --measurements " + (d / "rec.csv") + " --network " + net +
                       " --filters dnn --out " + (d / "filt"));
    INFO(fl.output);
    CHECK(fl.status == 0);
    CHECK(fl.output.find("dnn_gain_measured") != std::string::npos);
    // resume continues the same run
    auto r = run_hinf("resume " + net + " --quiet");
    CHECK(r.status == 0);
}

TEST_CASE("training.require_acceptance: a filter that fails its validation Monte Carlo exits 5", "[cli][gain]") {
    hinf::test::TempDir d("gainacc");
    const std::string cfg = d / "vdp.toml";
    std::ofstream(cfg) << kVdp;
    // no initial error (V(x~(0)) = 0) and rho far below any filter's ratio: the check must fail
    const std::string sets = " --set filter.xhat0=[2.0,0.0] --set filter.rho=1e-9 --set training.require_acceptance=true";
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet" + sets);
    INFO(t.output);
    CHECK(t.status == 5);
    CHECK(t.output.find("FAIL") != std::string::npos);
    CHECK(t.output.find("failed its acceptance check") != std::string::npos);
    auto ok = run_hinf("train " + cfg + " --out " + (d / "run2") + " --quiet --set training.require_acceptance=true");
    INFO(ok.output);
    CHECK(ok.status == 0);
}
