// `hinf operate` with on-line retraining (docs/method.md section 16.6): counts per run in operate.h5, one printed
// line, run 0's retrained network as a checkpoint that operate runs again; compare refuses retrain in one line.
#include <catch2/catch.hpp>
#include <fstream>

#include "helpers.hpp"
#include "hinf/h5.hpp"

using hinf::test::run_hinf;

namespace {
const std::string kRetrainVdp = hinf::test::tiny_vdp_gain_config("0.5", "acceptance_runs = 1\n");
}  // namespace

TEST_CASE("operate with online.retrain: counts in operate.h5, the on-line network written and usable", "[cli][retrain]") {
    hinf::test::TempDir d("retraincli");
    const std::string cfg = d / "vdp.toml", net = d / "run/checkpoint.h5";
    std::ofstream(cfg) << kRetrainVdp;
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet");
    INFO(t.output);
    REQUIRE(t.status == 0);
    const std::string on = " --set online.retrain=true --set online.retrain_delta=0.01";
    auto op = run_hinf("operate " + cfg + " --network " + net + " --runs 3 --quiet --out " + (d / "op") + on);
    INFO(op.output);
    REQUIRE(op.status == 0);
    CHECK(op.output.find("on-line retraining (delta 0.01):") != std::string::npos);
    const std::string online = d / "op/online_checkpoint.h5";
    {
        hinf::h5::Handle f = hinf::h5::open_file(d / "op/operate.h5", false);
        CHECK(hinf::h5::get_attr_int(f.get(), "online_retrain") == 1);
        const std::vector<double> trig = hinf::h5::read_doubles(f.get(), "retrain_triggers_per_run");
        const std::vector<double> steps = hinf::h5::read_doubles(f.get(), "retrain_adam_steps_per_run");
        REQUIRE(trig.size() == 3);
        double total = 0;
        for (std::size_t r = 0; r < 3; ++r) {
            CHECK(steps[r] == 5 * trig[r]);  // retrain_steps = 5 per trigger
            total += trig[r];
        }
        CHECK(total > 0);
        CHECK(hinf::h5::get_attr_double(f.get(), "retrain_triggers") == total);
        CHECK(hinf::h5::get_attr_string(f.get(), "online_checkpoint") == online);
    }
    // the same command again: the same bits (the on-line network too)
    auto op2 = run_hinf("operate " + cfg + " --network " + net + " --runs 3 --quiet --out " + (d / "op2") + on);
    REQUIRE(op2.status == 0);
    {
        hinf::h5::Handle a = hinf::h5::open_file(d / "op/operate.h5", false), b = hinf::h5::open_file(d / "op2/operate.h5", false);
        CHECK(hinf::h5::read_doubles(a.get(), "xhat") == hinf::h5::read_doubles(b.get(), "xhat"));
        hinf::h5::Handle na = hinf::h5::open_file(online, false), nb = hinf::h5::open_file(d / "op2/online_checkpoint.h5", false);
        CHECK(hinf::h5::read_doubles(na.get(), "network/layer_1/W") == hinf::h5::read_doubles(nb.get(), "network/layer_1/W"));
        hinf::h5::Handle nt = hinf::h5::open_file(net, false);  // retrained: not the training's weights
        CHECK(hinf::h5::read_doubles(na.get(), "network/layer_1/W") != hinf::h5::read_doubles(nt.get(), "network/layer_1/W"));
    }
    // operate --network on the written on-line checkpoint starts from the retrained weights
    auto again = run_hinf("operate " + cfg + " --network " + online + " --runs 1 --quiet --out " + (d / "op3"));
    INFO(again.output);
    CHECK(again.status == 0);
    // compare does not retrain: a one-line refusal rather than silently running the checkpoint as trained
    auto cmp = run_hinf("compare " + cfg + " --network " + net + " --filters dnn,ukf --runs 1 --out " + (d / "cmp") + on);
    CHECK(cmp.status == 2);
    CHECK(cmp.output.find("on-line retraining runs in hinf operate only") != std::string::npos);
}
