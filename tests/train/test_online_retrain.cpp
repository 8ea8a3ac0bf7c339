// On-line checking and retraining of the gain variant (issue 14 item 2, docs/method.md section 16.6), on a briefly
// trained Van der Pol gain network (position-only sensor) built inside the test: it triggers where the check fails
// and lowers the violation there, it does not trigger with a huge delta (and then equals the plain gain filter bit
// for bit), it is deterministic (repeated, 1 vs 2 threads, run order), and a run split through an on-line
// checkpoint continues bit for bit.
#include <omp.h>

#include <catch2/catch.hpp>
#include <cstring>

#include "eval/engine.hpp"
#include "eval/operate.hpp"
#include "filters/dnn.hpp"
#include "helpers.hpp"
#include "io/checkpoint.hpp"
#include "train/online_retrain.hpp"
#include "train/trainer.hpp"

using namespace hinf;
using hinf::test::TempDir;

namespace {

const std::string kOnlineVdp = hinf::test::tiny_vdp_gain_config("1.0");

RunConfig retrain_vdp_config(const std::vector<std::string>& sets = {}) {
    ConfigDoc doc = ConfigDoc::from_text(kOnlineVdp, "vdp.toml");
    for (const std::string& s : sets) doc.set(s);
    return load_run_config(std::move(doc));
}

// a briefly trained gain network (0.3 s of the 1 s horizon): DIR/checkpoint.h5
std::string train_brief(const TempDir& d) {
    TrainOptions opt;
    opt.out_dir = d / "run";
    opt.until = 0.3;
    opt.quiet = true;
    train_start(retrain_vdp_config(), opt);
    return d / "run/checkpoint.h5";
}

struct Stepped {
    std::vector<double> xhat;  // [steps x n] the estimate before each step
    OnlineRetrainCounts counts;
};

// steps f over the truth of `run` from step `from` to `to` (absolute indices: they key the draws)
Stepped step_over(OnlineFilter& f, const RunConfig& cfg, const TruthRun& tr, std::int64_t from, std::int64_t to) {
    Stepped s;
    for (std::int64_t k = from; k < to; ++k) {
        s.xhat.insert(s.xhat.end(), f.estimate(), f.estimate() + cfg.n);
        REQUIRE(f.step(FilterInput{tr.y.data() + k * cfg.m, cfg.time_of(k), k, nullptr}) == FILTER_OK);
    }
    s.xhat.insert(s.xhat.end(), f.estimate(), f.estimate() + cfg.n);
    s.counts = OnlineRetrainCounts::from_vector(f.run_report());
    return s;
}

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

OnlineRetrainSettings settings(const RunConfig& cfg, const std::string& ckpt, double delta) {
    OnlineRetrainSettings s = online_retrain_settings(cfg, ckpt);
    s.delta = delta;
    return s;
}

}  // namespace

TEST_CASE("on-line retraining triggers where the check fails and lowers the violation there", "[train][online][retrain]") {
    TempDir d("retrain");
    const std::string ckpt = train_brief(d);
    const RunConfig cfg = retrain_vdp_config({"online.retrain=true"});
    const FilterModel model = filter_model(cfg);
    const std::int64_t K = cfg.steps_until();
    const TruthRun tr = truth_simulate(cfg, Scenario{}, 0, K);
    std::unique_ptr<OnlineFilter> f = make_retrain_gain_filter(model, cfg, ckpt, settings(cfg, ckpt, 0.01), "dnn");
    f->reset(engine_filter_start(cfg, 0));
    const Stepped s = step_over(*f, cfg, tr, 0, K);
    INFO("triggers " << s.counts.triggers << " of " << K << " steps, violation at the triggers " << s.counts.eps_before
                     << " -> " << s.counts.eps_after << " (sums)");
    CHECK(s.counts.check_samples == double(K * kOnlineCheckErrors));
    CHECK(s.counts.check_violations > 0);
    REQUIRE(s.counts.triggers > 0);
    CHECK(s.counts.adam_steps == s.counts.triggers * double(cfg.retrain_steps));
    CHECK(s.counts.rejected == 0);
    // the measured effect: at the points where it triggered, the same check errors violate less afterwards
    CHECK(s.counts.eps_after < s.counts.eps_before);
    // and the network changed: the estimates differ from the plain (frozen) gain filter's
    RunConfig plain_cfg = retrain_vdp_config();
    std::unique_ptr<FrozenNetwork> net = ckpt_frozen_network(ckpt);
    std::unique_ptr<OnlineFilter> plain = make_gain_filter(model, *net, "dnn");
    plain->reset(engine_filter_start(cfg, 0));
    CHECK_FALSE(same_bits(step_over(*plain, plain_cfg, tr, 0, K).xhat, s.xhat));
}

TEST_CASE("on-line retraining with a huge delta never triggers and equals the frozen gain filter", "[train][online][retrain]") {
    TempDir d("retrain");
    const std::string ckpt = train_brief(d);
    const RunConfig cfg = retrain_vdp_config({"online.retrain=true", "online.retrain_delta=1e9"});
    const FilterModel model = filter_model(cfg);
    const std::int64_t K = cfg.steps_until();
    const TruthRun tr = truth_simulate(cfg, Scenario{}, 1, K);
    std::unique_ptr<OnlineFilter> f =
        make_retrain_gain_filter(model, cfg, ckpt, online_retrain_settings(cfg, ckpt), "dnn");
    f->reset(engine_filter_start(cfg, 1));
    const Stepped s = step_over(*f, cfg, tr, 0, K);
    CHECK(s.counts.triggers == 0);
    CHECK(s.counts.adam_steps == 0);
    CHECK(s.counts.check_violations > 0);  // the check fails, only the threshold is out of reach
    std::unique_ptr<FrozenNetwork> net = ckpt_frozen_network(ckpt);
    std::unique_ptr<OnlineFilter> plain = make_gain_filter(model, *net, "dnn");
    plain->reset(engine_filter_start(cfg, 1));
    CHECK(same_bits(step_over(*plain, cfg, tr, 0, K).xhat, s.xhat));
    // operate: the filter's own check (retraining on, never triggering) reports what the observer's check reports
    // with retraining off, and the estimates are the same bits
    OperateOptions oo;
    oo.runs = 2;
    oo.quiet = true;
    oo.out_dir = d / "op_off";
    const OperateSummary off = operate_run(retrain_vdp_config(), *net, ckpt, oo);
    oo.out_dir = d / "op_on";
    const OperateSummary on = operate_run(cfg, *net, ckpt, oo);
    CHECK(off.online_check_violation_fraction > 0);
    CHECK(on.online_check_violation_fraction == off.online_check_violation_fraction);
    CHECK(on.retrain_triggers == 0);
    CHECK(same_bits(on.error_std, off.error_std));
    CHECK(on.online_checkpoint == d / "op_on/online_checkpoint.h5");
}

TEST_CASE("on-line retraining is deterministic: repeated, 1 vs 2 threads, each run on its own network", "[train][online][retrain][determinism]") {
    TempDir d("retrain");
    const std::string ckpt = train_brief(d);
    const RunConfig cfg = retrain_vdp_config({"online.retrain=true", "online.retrain_delta=0.01"});
    const FilterModel model = filter_model(cfg);
    std::unique_ptr<OnlineFilter> proto =
        make_retrain_gain_filter(model, cfg, ckpt, online_retrain_settings(cfg, ckpt), "dnn");
    EngineOptions eo;
    eo.runs = 4;
    eo.steps = cfg.steps_until();
    eo.quiet = true;
    auto engine = [&](int threads) {
        omp_set_num_threads(threads);
        EngineResult r = engine_run(cfg, {proto.get()}, eo);
        omp_set_num_threads(2);
        return r;
    };
    const EngineResult one = engine(1), two = engine(2), again = engine(2);
    for (std::int64_t r = 0; r < eo.runs; ++r) {
        INFO("run " << r);
        CHECK(OnlineRetrainCounts::from_vector(one.runs[0][r].reported).triggers > 0);
        for (const EngineResult* o : {&two, &again}) {
            CHECK(same_bits(one.runs[0][r].err_sq, o->runs[0][r].err_sq));
            CHECK(same_bits(one.runs[0][r].err_sum, o->runs[0][r].err_sum));
            CHECK(same_bits(one.runs[0][r].reported, o->runs[0][r].reported));
        }
        // with 1 thread one clone ran every run in order; a fresh filter for this run alone gives the same bits:
        // nothing one run learned leaks into the next
        std::unique_ptr<OnlineFilter> fresh = proto->clone();
        fresh->reset(engine_filter_start(cfg, std::uint64_t(r)));
        const TruthRun tr = truth_simulate(cfg, Scenario{}, std::uint64_t(r), eo.steps);
        const Stepped s = step_over(*fresh, cfg, tr, 0, eo.steps);
        CHECK(same_bits(s.counts.to_vector(), one.runs[0][r].reported));
        if (r == 0) {
            std::vector<double> before(s.xhat.begin(), s.xhat.end() - cfg.n);  // the engine keeps x^ before each step
            CHECK(same_bits(before, one.runs[0][0].xhat));
        }
    }
}

TEST_CASE("on-line retraining resumes bit-identically from its on-line checkpoint", "[train][online][retrain][resume]") {
    TempDir d("retrain");
    const std::string ckpt = train_brief(d);
    for (const char* precision : {"float", "double"}) {
        INFO("precision " << precision);
        std::string source = ckpt;
        if (std::string(precision) == "double") {  // a double-precision network too
            TrainOptions opt;
            opt.out_dir = d / "run_double";
            opt.until = 0.3;
            opt.quiet = true;
            train_start(retrain_vdp_config({"network.precision=\"double\""}), opt);
            source = d / "run_double/checkpoint.h5";
        }
        const RunConfig cfg = retrain_vdp_config({"online.retrain=true", "online.retrain_delta=0.01"});
        const FilterModel model = filter_model(cfg);
        const OnlineRetrainSettings st = online_retrain_settings(cfg, source);
        const std::int64_t K = cfg.steps_until(), split = 37;
        const std::uint64_t run = 2;
        const TruthRun tr = truth_simulate(cfg, Scenario{}, run, K);
        // unsplit
        std::unique_ptr<OnlineFilter> whole = make_retrain_gain_filter(model, cfg, source, st, "dnn");
        whole->reset(engine_filter_start(cfg, run));
        const Stepped w = step_over(*whole, cfg, tr, 0, K);
        REQUIRE(w.counts.triggers > 0);
        // split: `split` steps, the on-line checkpoint, a new filter from it for the rest
        std::unique_ptr<OnlineFilter> first = make_retrain_gain_filter(model, cfg, source, st, "dnn");
        first->reset(engine_filter_start(cfg, run));
        step_over(*first, cfg, tr, 0, split);
        const std::string online = d / (std::string("online_") + precision + ".h5");
        online_retrain_write(*first, online);
        FilterStart start = engine_filter_start(cfg, run);
        start.xhat0 = ckpt_precision(online) == "double" ? ckpt_read<double>(online).state.xhat
                                                         : ckpt_read<float>(online).state.xhat;
        CHECK((ckpt_precision(online) == "double" ? ckpt_read<double>(online).state.step
                                                  : ckpt_read<float>(online).state.step) == split);
        std::unique_ptr<OnlineFilter> rest = make_retrain_gain_filter(model, cfg, online, st, "dnn");
        rest->reset(start);
        const Stepped r = step_over(*rest, cfg, tr, split, K);
        CHECK(same_bits(std::vector<double>(w.xhat.begin() + split * cfg.n, w.xhat.end()), r.xhat));
        // the final networks and Adam states are the same bits too
        const std::string a = d / "final_whole.h5", b = d / "final_split.h5";
        online_retrain_write(*whole, a);
        online_retrain_write(*rest, b);
        if (std::string(precision) == "double") {
            const Checkpoint<double> ca = ckpt_read<double>(a), cb = ckpt_read<double>(b);
            CHECK(ca.net.theta == cb.net.theta);
            CHECK(ca.adam_m == cb.adam_m);
            CHECK(ca.adam_v == cb.adam_v);
            CHECK(ca.state.adam_step == cb.state.adam_step);
        } else {
            const Checkpoint<float> ca = ckpt_read<float>(a), cb = ckpt_read<float>(b);
            CHECK(ca.net.theta == cb.net.theta);
            CHECK(ca.adam_m == cb.adam_m);
            CHECK(ca.adam_v == cb.adam_v);
            // and they differ from the training's: the on-line network is not lost
            CHECK(ca.net.theta != ckpt_read<float>(source).net.theta);
        }
    }
}

TEST_CASE("on-line retraining of a discrete-time one-step predictor: triggers, lowers its violation, repeats its bits",
          "[train][online][retrain][discrete]") {
    // the linear discrete system the gain variant is tested on (tests/train/test_gain_discrete.cpp), trained for two
    // of its 40 steps: the check uses the one-step inequality (16.8.1), the filter the predictor f(x^) + K e
    const std::string text = hinf::test::linear_discrete_system_toml() +
                             "[filter]\nvariant = \"gain\"\nrho = 6\nQ = [1.0, 1.0]\nx0 = [1, -1]\nxhat0 = [0, 0]\n"
                             "dt = 1\nt_final = 40\n[online]\ndisturbance_std = 0.3\nnoise_std = 0.3\n[network]\n"
                             "hidden = [8]\n[training]\nsamples = 64\nbatch = 32\nadam_steps = 2\n"
                             "acceptance_runs = 0\n";
    auto config = [&](const std::vector<std::string>& sets) {
        ConfigDoc doc = ConfigDoc::from_text(text, "linear.toml");
        for (const std::string& s : sets) doc.set(s);
        return load_run_config(std::move(doc));
    };
    TempDir d("retrain-discrete");
    TrainOptions opt;
    opt.out_dir = d / "run";
    opt.until = 2;
    opt.quiet = true;
    train_start(config({}), opt);
    const std::string ckpt = d / "run/checkpoint.h5";
    const RunConfig cfg = config({"online.retrain=true"});
    const FilterModel model = filter_model(cfg);
    const std::int64_t K = cfg.steps_until();
    const TruthRun tr = truth_simulate(cfg, Scenario{}, 0, K);
    auto run = [&](double delta) {
        std::unique_ptr<OnlineFilter> f = make_retrain_gain_filter(model, cfg, ckpt, settings(cfg, ckpt, delta), "dnn");
        f->reset(engine_filter_start(cfg, 0));
        return step_over(*f, cfg, tr, 0, K);
    };
    const Stepped s = run(0.01);
    INFO("triggers " << s.counts.triggers << " of " << K << " steps, violation at the triggers " << s.counts.eps_before
                     << " -> " << s.counts.eps_after << " (sums)");
    REQUIRE(s.counts.triggers > 0);
    CHECK(s.counts.rejected == 0);
    CHECK(s.counts.eps_after < s.counts.eps_before);
    CHECK(same_bits(run(0.01).xhat, s.xhat));  // repeated: the same bits
    // never triggered, it is the frozen one-step predictor of filters/dnn.cpp, bit for bit
    const Stepped never = run(1e9);
    CHECK(never.counts.triggers == 0);
    std::unique_ptr<FrozenNetwork> net = ckpt_frozen_network(ckpt);
    std::unique_ptr<OnlineFilter> plain = make_gain_filter(model, *net, "dnn");
    plain->reset(engine_filter_start(cfg, 0));
    CHECK(same_bits(step_over(*plain, cfg, tr, 0, K).xhat, never.xhat));
    CHECK_FALSE(same_bits(never.xhat, s.xhat));
}
