// On-line phase: true system with v, n ~ std * N(0,1), filter (19) with the frozen network's gain,
// in `oracle` (true x~ and C(x), the paper's protocol) or `measured` (innovation only) mode.
#include "eval/operate.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "hinf/error.hpp"
#include "hinf/h5.hpp"
#include "io/atomic.hpp"
#include "io/measurements.hpp"
#include "io/run_lock.hpp"
#include "par/par.hpp"
#include "eval/engine.hpp"
#include "filters/dnn.hpp"
#include "filters/gain_law.hpp"
#include "filters/open_loop.hpp"
#include "gain.hpp"
#include "train/gain_samples.hpp"
#include "train/online_retrain.hpp"

namespace hinf {

namespace {

// Does the network satisfy the HJI inequality at the errors it meets on-line? At each step of the DNN filter
// (filter 0), with the true x~ and x: HJIE(p(x~)) > 0.01 S counts as a violation (seed 000 eq. (16) terms).
// An ensemble of gain networks (docs/method.md 16.15) filters with the mean gain K̄; it is checked against each
// member's storage S_e (a member whose inequality K̄ keeps certifies the ensemble), member by member.
class HjiCheck final : public StepObserver {
public:
    /// sampled = false: the filter checks itself (on-line retraining: its network changes, the observer's would not)
    HjiCheck(const RunConfig& cfg, const std::vector<FrozenNetwork*>& nets, bool sampled = true)
        : cfg_(cfg), check_here_(sampled) {
        for (const FrozenNetwork* net : nets) nets_.push_back(net->clone());
        counts_.assign(4 * nets_.size(), 0.0);
    }
    void begin(int filter, std::uint64_t run) override {
        active_ = filter == 0;
        std::fill(counts_.begin(), counts_.end(), 0.0);
        run_ = run;
    }
    // The on-line check a user has (variant gain, docs/method.md section 14.5): at the estimate x^ alone, the
    // inequality (14.1) over kCheck errors drawn as in training (Philox stream RNG_STREAM_GAIN, counter
    // 2^40 + run * 2^24 + step: deterministic, disjoint from training's time-step counters), for the gain K the
    // filter runs and member e's storage (its own error scales).
    void check_sampled(std::size_t e, std::int64_t k, double t, const double* xhat, const double* K) {
        constexpr std::int64_t kCheck = kOnlineCheckErrors;
        const kern::GainSpec& g = nets_[e]->step_config().gain;
        gain_samples_at(&smp_, cfg_, g, xhat, t, kCheck, online_check_counter(run_, k));
        const int n = cfg_.n, m = cfg_.m;
        std::vector<double> Ke(static_cast<std::size_t>(n) * m), S(static_cast<std::size_t>(n) * n), Sd(S.size());
        nets_[e]->gain(Ke.data(), S.data(), Sd.data(), xhat, t, *cfg_.system, 1);
        kern::GainLossParams lp;
        lp.rho = cfg_.rho;
        lp.discrete = cfg_.system->discrete_time();
        const kern::HjieSystemView view = smp_.view();
        for (std::int64_t i = 0; i < kCheck; ++i) {
            const kern::GainSampleValue v = kern::gain_sample_forward(K == nullptr ? Ke.data() : K, S.data(), view, i,
                                                                      lp, Sd.data());
            counts_[4 * e + 2] += v.residual > 0.01 * v.abs_sum ? 1 : 0;
            counts_[4 * e + 3] += 1;
        }
    }
    void observe(std::int64_t k, double t, const double* x, const double* xhat) override {
        if (!active_) return;
        const int n = cfg_.n;
        if (nets_[0]->step_config().gain.enabled) {  // variant gain: its own inequality (docs/method.md section 14)
            // the ensemble's gain: the members' gains summed in the order given, then divided (as the filter)
            std::vector<double> Kbar;
            if (nets_.size() > 1) {
                std::vector<double> Ke(static_cast<std::size_t>(n) * cfg_.m);
                Kbar.assign(Ke.size(), 0.0);
                for (auto& net : nets_) {
                    net->gain(Ke.data(), nullptr, nullptr, xhat, t, *cfg_.system, 1);
                    for (std::size_t j = 0; j < Ke.size(); ++j) Kbar[j] += Ke[j];
                }
                for (double& g : Kbar) g /= static_cast<double>(nets_.size());
            }
            const double* K = Kbar.empty() ? nullptr : Kbar.data();
            for (std::size_t e = 0; e < nets_.size(); ++e) {
                double S = 0;
                const double H = gain_point_residual(&S, nullptr, *nets_[e], *cfg_.system, x, xhat, t, cfg_.Q.data(),
                                                     cfg_.rho, K);
                counts_[4 * e] += H > 0.01 * S ? 1 : 0;
                counts_[4 * e + 1] += 1;
                if (check_here_) check_sampled(e, k, t, xhat, K);
            }
            return;
        }
        std::vector<double> xt(n), pt(n);
        cfg_.system->state_difference(xt.data(), x, xhat);  // an angle state's wrapped
        nets_[0]->gradient(pt.data(), xt.data(), 1);
        double terms[4];
        hjie_point_terms(terms, pt.data(), *cfg_.system, x, xhat, t, cfg_.Q.data(), cfg_.rho);
        const double S = std::fabs(terms[0]) + std::fabs(terms[1]) + std::fabs(terms[2]) + std::fabs(terms[3]);
        counts_[0] += (terms[0] + terms[1] + terms[2] + terms[3]) > 0.01 * S ? 1 : 0;
        counts_[1] += 1;
    }
    /// per network: violations at the true x~, steps, sampled errors violating, sampled errors
    std::vector<double> end() override { return counts_; }
    std::unique_ptr<StepObserver> clone() const override {
        std::vector<FrozenNetwork*> nets;
        for (const auto& net : nets_) nets.push_back(net.get());
        return std::make_unique<HjiCheck>(cfg_, nets, check_here_);
    }

private:
    const RunConfig& cfg_;
    std::vector<std::unique_ptr<FrozenNetwork>> nets_;
    bool check_here_ = true, active_ = false;
    std::vector<double> counts_;  // [4 x networks], as end()
    std::uint64_t run_ = 0;
    GainSamples smp_;
};

// Run 0 of the retraining filter once more, alone, on the engine's truth of run 0: its final network is what the
// on-line checkpoint keeps. The estimates must equal the engine's run 0 bit for bit (deterministic retraining).
std::unique_ptr<OnlineFilter> online_retrain_run0(const RunConfig& cfg, const OnlineFilter& proto, const EngineResult& er,
                                                 const FilterRunStats& d0) {
    const int n = cfg.n;
    const std::int64_t K = std::int64_t(er.t.size());
    std::unique_ptr<OnlineFilter> f = proto.clone();
    const FilterStart start = engine_filter_start(cfg, 0);
    f->reset(start);
    const std::vector<double> bound = plausible_bound(cfg, start, er.truth0.x.data(), nullptr, K);
    bool same = true;
    filter_stream(*f, er.truth0.y.data(), cfg.m, er.t.data(), K, er.truth0.x.data(), n, bound.data(), nullptr,
                  [&](std::int64_t k, const double* xh, bool) {
                      for (int i = 0; i < n; ++i) same = same && xh[i] == d0.xhat[std::size_t(k) * n + i];
                  });
    HINF_CHECK(same, "on-line retraining: run 0 repeated alone did not reproduce the Monte Carlo's run 0 bit for bit "
                     "(a determinism bug: please report it with the config)");
    return f;
}

void mean_std(std::vector<double>* mean, std::vector<double>* sd, const std::vector<double>& sum,
              const std::vector<double>& sq, double count) {
    mean->resize(sum.size());
    sd->resize(sum.size());
    for (std::size_t i = 0; i < sum.size(); ++i) {
        (*mean)[i] = sum[i] / count;
        (*sd)[i] = std::sqrt(std::max(0.0, sq[i] / count - (*mean)[i] * (*mean)[i]));
    }
}

}  // namespace

OperateSummary operate_run(const RunConfig& cfg, FrozenNetwork& network, const std::string& network_path,
                           const OperateOptions& opt) {
    return operate_run(cfg, std::vector<FrozenNetwork*>{&network}, std::vector<std::string>{network_path}, opt);
}

OperateSummary operate_run(const RunConfig& cfg, const std::vector<FrozenNetwork*>& networks,
                           const std::vector<std::string>& network_paths, const OperateOptions& opt) {
    HINF_CHECK(!networks.empty() && networks.size() == network_paths.size(),
               "operate: one path per network (" + std::to_string(networks.size()) + " networks, " +
                   std::to_string(network_paths.size()) + " paths)");
    FrozenNetwork& network = *networks[0];
    const std::string& network_path = network_paths[0];
    const bool ensemble = networks.size() > 1;
    for (std::size_t e = 0; e < networks.size(); ++e) {
        const int trained_n = networks[e]->step_config().head.n;
        HINF_CHECK(trained_n == cfg.n, "network '" + network_paths[e] + "' was trained for " + std::to_string(trained_n) +
                                           " states, the config's system has " + std::to_string(cfg.n) +
                                           " (use the matching config)");
        HINF_CHECK(!ensemble || networks[e]->step_config().gain.enabled,
                   "an ensemble averages gains K(x^): network '" + network_paths[e] +
                       "' is not variant \"gain\" (train every member with [filter] variant = \"gain\")");
    }
    HINF_CHECK(!ensemble || !cfg.retrain,
               "online.retrain = true retrains one network and an ensemble of " + std::to_string(networks.size()) +
                   " was given (operate one --network at a time to retrain it, or set online.retrain = false)");
    auto t0 = std::chrono::steady_clock::now();
    OperateSummary sum;
    sum.mode = opt.mode.empty() ? cfg.mode : opt.mode;
    HINF_CHECK(sum.mode == "oracle" || sum.mode == "measured",
               "--mode '" + sum.mode + "' is not one of: oracle, measured");
    sum.runs = opt.runs > 0 ? opt.runs : cfg.runs;
    const bool measured = sum.mode == "measured";
    if (measured && par_root()) {
        const std::string warning = dnn_measured_warning(cfg.variant, cfg.n, cfg.m);
        if (!warning.empty()) std::fprintf(stderr, "%s\n", warning.c_str());
    }
    const double tf = cfg.final_time(opt.until);
    const std::int64_t steps = cfg.steps_until(opt.until);
    const int n = cfg.n;

    // the engine over {the DNN filter, the open-loop predictor}: the same truth, the same measurements
    const FilterModel model = filter_model(cfg);
    const bool gain = network.step_config().gain.enabled;
    HINF_CHECK(!gain || measured, "network '" + network_path + "' is variant \"gain\": its gain K(x^) never sees the "
                                  "true error, so --mode oracle is meaningless for it (use --mode measured)");
    HINF_CHECK(!cfg.retrain || gain, "online.retrain = true needs a network of variant \"gain\" and '" + network_path +
                                         "' is not one (train with [filter] variant = \"gain\", or set online.retrain = false)");
    // on-line retraining (docs/method.md section 16.6): the filter reads the checkpoint itself (weights and Adam state)
    std::unique_ptr<OnlineFilter> dnn =
        cfg.retrain ? make_retrain_gain_filter(model, cfg, network_path, online_retrain_settings(cfg, network_path), "dnn")
        : gain      ? make_gain_ensemble_filter(model, std::vector<const FrozenNetwork*>(networks.begin(), networks.end()),
                                                "dnn")
                    : make_dnn_filter(model, network, *make_hinf_gain_law(cfg.rho), measured, "dnn");
    std::unique_ptr<OnlineFilter> open_loop = make_open_loop_filter(model);
    EngineOptions eo;
    eo.runs = sum.runs;
    eo.steps = steps;
    eo.stride = steps;  // no error subsampling needed
    eo.label = "operate";
    eo.quiet = opt.quiet;
    HjiCheck hji(cfg, networks, !cfg.retrain);
    // before the runs, not only before anything there is opened for writing: a second `hinf operate` into the same
    // directory is told at once, not after the first one's runs
    const RunDirLock lock(opt.out_dir, "hinf operate");
    EngineResult er = engine_run(cfg, {dnn.get(), open_loop.get()}, eo, &hji);
    const std::vector<FilterRunStats>& D = er.runs[0];
    const std::vector<FilterRunStats>& O = er.runs[1];

    // V(x~(0)) along the segment (defined for the quadratic head: p^T x~ > 0 on every ray)
    std::vector<double> xt0(n);
    for (int i = 0; i < n; ++i) xt0[i] = cfg.x0[i] - cfg.xhat0[i];
    // an ensemble has no common storage: its members' V_e(x~(0)) differ and none is its own
    const bool v_defined = !ensemble && (network.step_config().head.kind == kern::HEAD_QUADRATIC || gain);
    if (gain) {
        std::vector<double> S(static_cast<std::size_t>(n) * n), K(static_cast<std::size_t>(n) * cfg.m);
        std::unique_ptr<FrozenNetwork> net = network.clone();
        net->gain(K.data(), S.data(), nullptr, cfg.xhat0.data(), 0.0, *cfg.system, 1);  // V(x~(0), 0)
        sum.v0 = ensemble ? NAN : quadratic_form(S.data(), xt0.data(), n);
    } else {
        sum.v0 = network.value(xt0.data(), n);
    }

    // the energies are dt-weighted sums; a discrete system's inequality sums per step, so V(x~(0)) counts dt times
    const double v0_weight = cfg.system->discrete_time() ? cfg.dt : 1.0;
    std::vector<double> ratio(sum.runs), ratio_open(sum.runs), ratio_v0(sum.runs), diverged_at(sum.runs);
    // a run whose truth ran away (sim/truth.hpp) counts for no figure (docs/compare.md "Divergence")
    std::int64_t counted = 0;
    for (std::int64_t r = 0; r < sum.runs; ++r) {
        const double e = er.truth_escaped_at[r];
        if (e < 0) {
            ++counted;
            continue;
        }
        ++sum.truth_escaped_runs;
        if (sum.first_truth_escape < 0 || e < sum.first_truth_escape) sum.first_truth_escape = e;
    }
    HINF_CHECK(counted > 0, "operate: " + truth_escape_refusal(cfg, sum.runs, "run(s)", sum.first_truth_escape));
    for (std::int64_t r = 0; r < sum.runs; ++r) {
        diverged_at[r] = er.truth_escaped_at[r] >= 0 ? NAN : D[r].diverged_at;
        if (diverged_at[r] >= 0) {
            ++sum.diverged_runs;
            if (sum.first_divergence < 0 || diverged_at[r] < sum.first_divergence) sum.first_divergence = diverged_at[r];
        }
    }
    std::vector<double> es(n, 0), eq(n, 0), eso(n, 0), eqo(n, 0), ss(n, 0), sq(n, 0);
    double set_count = 0, eps_before = 0, eps_after = 0;
    const std::size_t E = networks.size();
    std::vector<double> hji_v(E, 0.0), hji_n(E, 0.0), chk_v(E, 0.0), chk_n(E, 0.0);  // per network (HjiCheck::end)
    std::vector<double> triggers(sum.runs, 0.0), adam_steps(sum.runs, 0.0);
    sum.retrain = cfg.retrain;
    for (std::int64_t r = 0; r < sum.runs; ++r) {
        if (er.truth_escaped_at[r] >= 0) {
            ratio[r] = ratio_open[r] = ratio_v0[r] = NAN;
            sum.run_mse_settled.insert(sum.run_mse_settled.end(), std::size_t(n), NAN);
            continue;
        }
        // a diverged filter's error energy counts as infinite (its estimate is frozen)
        const double num = D[r].diverged_at >= 0 ? INFINITY : D[r].error_energy, den = D[r].signal_energy;
        ratio[r] = num / den;
        ratio_open[r] = O[r].error_energy / den;
        ratio_v0[r] = (num - v0_weight * sum.v0) / den;
        sum.attenuation_ratio += ratio[r] / double(counted);
        sum.attenuation_ratio_open_loop += ratio_open[r] / double(counted);
        sum.attenuation_ratio_minus_v0 += ratio_v0[r] / double(counted);
        for (int i = 0; i < n; ++i) {
            es[i] += D[r].err_sum[i];
            eq[i] += D[r].err_sq[i];
            eso[i] += O[r].err_sum[i];
            eqo[i] += O[r].err_sq[i];
            ss[i] += D[r].err_sum_settled[i];
            sq[i] += D[r].err_sq_settled[i];
        }
        set_count += D[r].settled_steps;
        for (int i = 0; i < n; ++i) {
            const bool settled = D[r].settled_steps > 0;
            const double mse = settled ? D[r].err_sq_settled[i] / D[r].settled_steps : D[r].err_sq[i] / double(steps);
            sum.run_mse_settled.push_back(D[r].diverged_at >= 0 ? INFINITY : mse);
        }
        for (std::size_t e = 0; e < E; ++e) {
            hji_v[e] += D[r].observed[4 * e];
            hji_n[e] += D[r].observed[4 * e + 1];
            chk_v[e] += D[r].observed[4 * e + 2];
            chk_n[e] += D[r].observed[4 * e + 3];
        }
        sum.notes.see(r, D[r].note);
        if (cfg.retrain) {  // the retraining filter's own check, with its network of the moment
            const OnlineRetrainCounts c = OnlineRetrainCounts::from_vector(D[r].reported);
            chk_v[0] += c.check_violations;
            chk_n[0] += c.check_samples;
            triggers[r] = c.triggers;
            adam_steps[r] = c.adam_steps;
            sum.retrain_triggers += c.triggers;
            sum.retrain_adam_steps += c.adam_steps;
            sum.retrain_rejected += c.rejected;
            eps_before += c.eps_before;
            eps_after += c.eps_after;
        }
    }
    if (sum.retrain_triggers > 0) {
        sum.retrain_eps_before = eps_before / sum.retrain_triggers;
        sum.retrain_eps_after = eps_after / sum.retrain_triggers;
    }
    if (!v_defined) sum.attenuation_ratio_minus_v0 = NAN;
    const double count = double(steps) * double(counted);
    mean_std(&sum.error_mean, &sum.error_std, es, eq, count);
    mean_std(&sum.error_mean_open_loop, &sum.error_std_open_loop, eso, eqo, count);
    for (std::size_t e = 0; e < E; ++e) {
        sum.online_hji_violation_fraction_per_network.push_back(hji_n[e] > 0 ? hji_v[e] / hji_n[e] : 0.0);
        sum.online_check_violation_fraction_per_network.push_back(chk_n[e] > 0 ? chk_v[e] / chk_n[e] : NAN);
    }
    // an ensemble's figures are those of the member whose storage the mean gain keeps best on the sampled errors
    for (std::size_t e = 1; e < E; ++e)
        if (sum.online_check_violation_fraction_per_network[e] <
            sum.online_check_violation_fraction_per_network[sum.online_check_network])
            sum.online_check_network = static_cast<int>(e);
    sum.online_hji_violation_fraction = sum.online_hji_violation_fraction_per_network[sum.online_check_network];
    // with retraining the network changes along each run and the observer holds the checkpoint's: no such figure
    if (cfg.retrain) sum.online_hji_violation_fraction = NAN;
    sum.online_check_violation_fraction = sum.online_check_violation_fraction_per_network[sum.online_check_network];
    if (set_count > 0) mean_std(&sum.error_mean_settled, &sum.error_std_settled, ss, sq, set_count);
    else sum.error_mean_settled = sum.error_std_settled = std::vector<double>(n, NAN);
    for (int i : state_unit_group(*cfg.system, 0)) {  // the states of the first state's unit
        sum.rmse_position += eq[i] / count;
        sum.rmse_position_open_loop += eqo[i] / count;
    }
    sum.rmse_position = std::sqrt(sum.rmse_position);
    sum.rmse_position_open_loop = std::sqrt(sum.rmse_position_open_loop);
    // the retrained network of run 0 is kept: run 0 once more by itself (the same bits as in the engine, checked)
    std::unique_ptr<OnlineFilter> run0;
    if (cfg.retrain && par_root()) run0 = online_retrain_run0(cfg, *dnn, er, D[0]);
    sum.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    if (run0 != nullptr && D[0].diverged_at < 0) {
        sum.online_checkpoint = opt.out_dir + "/online_checkpoint.h5";
        online_retrain_write(*run0, sum.online_checkpoint);
    }
    const std::string path = opt.out_dir + "/operate.h5";
    AtomicH5 f(path);
    hid_t root = f.get();
    h5::set_attr(root, "format", "hinf-operate");
    h5::set_attr(root, "mode", sum.mode);
    std::string paths;
    for (const std::string& p : network_paths) paths += (paths.empty() ? "" : ",") + p;
    h5::set_attr(root, "network", paths);  // an ensemble's members, comma-separated
    h5::set_attr(root, "ensemble_size", std::int64_t(E));
    h5::set_attr(root, "filter_type", cfg.type);
    h5::set_attr(root, "variant", cfg.variant);
    h5::set_attr(root, "runs", sum.runs);
    h5::set_attr(root, "t_final", tf);
    h5::set_attr(root, "attenuation_ratio", sum.attenuation_ratio);
    h5::set_attr(root, "attenuation_ratio_open_loop", sum.attenuation_ratio_open_loop);
    h5::set_attr(root, "attenuation_ratio_minus_v0", sum.attenuation_ratio_minus_v0);
    h5::set_attr(root, "v0", sum.v0);
    h5::set_attr(root, "diverged_runs", sum.diverged_runs);
    h5::set_attr(root, "first_divergence_time", sum.first_divergence);
    h5::set_attr(root, "truth_escaped_runs", sum.truth_escaped_runs);
    h5::set_attr(root, "first_truth_escape_time", sum.first_truth_escape);
    h5::set_attr(root, "v0_defined", std::int64_t(v_defined ? 1 : 0));
    h5::set_attr(root, "error_mean", sum.error_mean);
    h5::set_attr(root, "error_std", sum.error_std);
    h5::set_attr(root, "settle_time", cfg.settle_time);
    h5::set_attr(root, "online_hji_violation_fraction", sum.online_hji_violation_fraction);
    h5::set_attr(root, "online_check_violation_fraction", sum.online_check_violation_fraction);
    if (ensemble) {
        h5::set_attr(root, "online_check_network", std::int64_t(sum.online_check_network));
        h5::write_doubles(root, "online_check_violation_fraction_per_network",
                          sum.online_check_violation_fraction_per_network.data(), {hsize_t(E)}, "1",
                          "the ensemble's mean gain against each member's storage: share of the sampled errors at x^ "
                          "violating (14.1); online_check_violation_fraction is the smallest (member online_check_network)");
        h5::write_doubles(root, "online_hji_violation_fraction_per_network",
                          sum.online_hji_violation_fraction_per_network.data(), {hsize_t(E)}, "1",
                          "the same at the true x~: share of the steps violating (14.1) by more than 1 % of its scale");
    }
    if (sum.notes.runs > 0) {  // what the figures do not say (OnlineFilter::run_note)
        h5::set_attr(root, "note", sum.notes.first);
        h5::set_attr(root, "note_runs", sum.notes.runs);
        h5::set_attr(root, "note_first_run", sum.notes.first_run);
    }
    h5::set_attr(root, "online_retrain", std::int64_t(cfg.retrain ? 1 : 0));
    if (cfg.retrain) {
        h5::set_attr(root, "retrain_delta", cfg.retrain_delta);
        h5::set_attr(root, "retrain_steps", cfg.retrain_steps);
        h5::set_attr(root, "retrain_samples", cfg.retrain_samples);
        h5::set_attr(root, "retrain_triggers", sum.retrain_triggers);
        h5::set_attr(root, "retrain_adam_steps", sum.retrain_adam_steps);
        h5::set_attr(root, "retrain_rejected", sum.retrain_rejected);
        h5::set_attr(root, "retrain_violation_before", sum.retrain_eps_before);
        h5::set_attr(root, "retrain_violation_after", sum.retrain_eps_after);
        h5::set_attr(root, "online_checkpoint", sum.online_checkpoint);
        h5::write_doubles(root, "retrain_triggers_per_run", triggers.data(), {hsize_t(sum.runs)}, "1",
                          "steps whose on-line check violation max_j H_j/S_j exceeded retrain_delta (each: retrain_steps "
                          "Adam steps), per Monte Carlo run");
        h5::write_doubles(root, "retrain_adam_steps_per_run", adam_steps.data(), {hsize_t(sum.runs)}, "1",
                          "on-line Adam steps taken, per Monte Carlo run");
    }
    h5::set_attr(root, "error_mean_settled", sum.error_mean_settled);
    h5::set_attr(root, "error_std_settled", sum.error_std_settled);
    h5::set_attr(root, "error_mean_open_loop", sum.error_mean_open_loop);
    h5::set_attr(root, "error_std_open_loop", sum.error_std_open_loop);
    h5::set_attr(root, "rmse_position", sum.rmse_position);
    h5::set_attr(root, "rmse_position_open_loop", sum.rmse_position_open_loop);
    h5::set_attr(root, "meaning",
                 "attenuation_ratio = int_0^T x~^T Q x~ dt / int_0^T (v^T v + n^T n) dt, mean over runs (seed 000 "
                 "Section IV); _open_loop: the same noise with the gain set to zero; _minus_v0: numerator minus "
                 "V(x~(0)); error_mean/std: per state, over time and runs, of x - x^; _settled: over t >= settle_time only (mode says whether the "
                 "filter used the true state: oracle, or only measurements: measured)");
    h5::write_string(root, "config", cfg.doc.text(), "the effective TOML config");
    std::string names, units;  // for axis labels (scripts/plot)
    for (const auto& s : cfg.system->state_names()) names += (names.empty() ? "" : ",") + s;
    for (const auto& u : cfg.system->state_units()) units += (units.empty() ? "" : ",") + u;
    h5::set_attr(root, "state_names", names);
    h5::set_attr(root, "state_units", units);
    h5::write_doubles(root, "attenuation_ratio_per_run", ratio.data(), {hsize_t(sum.runs)}, "1", "per Monte Carlo run");
    h5::write_doubles(root, "diverged_at", diverged_at.data(), {hsize_t(sum.runs)}, "s",
                      "time the estimate became non-finite or left |x^| < 1e12 or the plausible range (-1: never); from then "
                      "on it is frozen. NaN: the truth ran away, and the run counts for no figure");
    h5::write_doubles(root, "attenuation_ratio_open_loop_per_run", ratio_open.data(), {hsize_t(sum.runs)}, "1",
                      "per Monte Carlo run, gain set to zero");
    h5::write_doubles(root, "t", er.t.data(), {hsize_t(steps)}, "s", "time");
    h5::write_doubles(root, "x", er.truth0.x.data(), {hsize_t(steps), hsize_t(n)}, "state units", "true state, run 0");
    h5::write_doubles(root, "xhat", D[0].xhat.data(), {hsize_t(steps), hsize_t(n)}, "state units",
                      "DNN filter estimate, run 0");
    std::vector<double> y_user = er.truth0.y;
    outputs_to_user(cfg, y_user.data(), steps);
    h5::write_doubles(root, "y", y_user.data(), {hsize_t(steps), hsize_t(cfg.m)}, "output units",
                      "measurements y(t_k) = C(x(t_k)) + n_k fed to the filter, run 0 (input for `hinf filter`)");
    write_record_inputs(root, *cfg.system, er.t.data(), steps);
    h5::write_doubles(root, "xhat_open_loop", O[0].xhat.data(), {hsize_t(steps), hsize_t(n)}, "state units",
                      "open-loop predictor, run 0");
    f.commit();
    return sum;
}

}  // namespace hinf
