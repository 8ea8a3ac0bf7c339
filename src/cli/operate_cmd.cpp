// `hinf operate`: the on-line phase of a trained network; prints the headline figures.
#include <cmath>
#include <cstdio>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "eval/operate.hpp"
#include "filters/factory.hpp"
#include "io/checkpoint.hpp"
#include "lmi/delay_run.hpp"
#include "sim/truth.hpp"

namespace hinf::cli {

namespace {
struct OperateArgs {
    std::string config, out, mode;
    std::vector<std::string> networks;
    bool ensemble = false;
    std::int64_t runs = 0;
    double until = -1;
    int threads = 0;
    std::vector<std::string> sets;
    bool quiet = false;
};
}  // namespace

void add_operate_command(CLI::App& app) {
    auto a = std::make_shared<OperateArgs>();
    CLI::App* op = app.add_subcommand("operate", "Run a trained filter on-line against the simulated true system");
    op->add_option("config", a->config, "Scenario config (TOML): system, noise levels, rho, Q")->required();
    op->add_option("--network", a->networks,
                   "Trained network: DIR/best.h5 or DIR/checkpoint.h5 from `hinf train` (not for [system] kind = "
                   "\"ito_delay\", whose filter is designed by LMIs on the fly); with --ensemble, two or more gain "
                   "networks (repeat --network)");
    op->add_flag("--ensemble", a->ensemble,
                 "One DNN filter with the mean gain of every --network (variant gain, trained on one model; "
                 "docs/method.md 16.15); the on-line check tests it against each member's storage");
    op->add_option("--mode", a->mode, "oracle (true x~ and C(x), the paper's protocol) or measured (y and x^ only)");
    op->add_option("--runs", a->runs, "Monte Carlo runs (default: [online] runs)");
    op->add_option("--until", a->until, "Simulate up to this time [s] (default t_final)");
    op->add_option("--out", a->out, "Output directory (default runs/out/<config name>/operate-<mode>)");
    op->add_option("--threads", a->threads, "OpenMP threads (runs are split over them)");
    op->add_option("--set", a->sets, "Override a config key, e.g. --set online.noise_std=10 (repeatable)");
    op->add_flag("--quiet", a->quiet, "No progress lines");
    op->callback([a]() {
        apply_threads(a->threads);
        HINF_CHECK(a->runs >= 0, "--runs must be >= 1");
        {
            // seed 002's delay systems: the global-linearization filter, designed by LMIs (src/lmi)
            ConfigDoc doc = ConfigDoc::from_file(a->config);
            for (const auto& s : a->sets) doc.set(s);
            ConfigSection sys(doc, "system");
            if (sys.has("kind") && sys.get_string("kind", "") == "ito_delay") {
                int rc = lmi::delay_operate(doc, a->out.empty() ? default_out_dir(a->config, "") : a->out,
                                            static_cast<int>(a->runs), a->threads);
                if (rc != 0) throw CLI::RuntimeError(rc);
                return;
            }
        }
        HINF_CHECK(!a->networks.empty(),
                   "operate needs --network DIR/best.h5 (train one first: hinf train " + a->config + ")");
        HINF_CHECK(a->ensemble || a->networks.size() == 1,
                   "operate runs one network and " + std::to_string(a->networks.size()) +
                       " --network were given (add --ensemble to run the mean of their gains)");
        RunConfig trained;
        std::vector<std::unique_ptr<FrozenNetwork>> nets;
        if (a->ensemble) {
            // checked against the config's system as compare --ensemble does (one model, variant gain)
            nets = load_gain_ensemble(load_config_with_overrides(a->config, a->sets, false), a->networks, &trained);
        } else {
            nets.push_back(ckpt_frozen_network(a->networks[0], &trained));
        }
        // a config that names no variant runs the network's (one trained before `gain` became the default is a
        // `dissipative` network, with its oracle mode by default)
        std::vector<std::string> sets = a->sets;
        {
            ConfigDoc doc = ConfigDoc::from_file(a->config);
            for (const auto& s : a->sets) doc.set(s);
            if (!ConfigSection(doc, "filter").has("variant")) sets.push_back("filter.variant=\"" + trained.variant + "\"");
        }
        RunConfig cfg = load_config_with_overrides(a->config, sets);
        // operate runs the network's game on this config (its check, its retraining): both must weigh the channels
        // alike (compare and filter convert the measurements instead; docs/method.md section 16.13)
        HINF_CHECK(trained.output_weight == cfg.output_weight && trained.disturbance_scale == cfg.disturbance_scale,
                   "network '" + a->networks[0] + "' was trained with [online] noise_std / disturbance_std " +
                       (game_in_config_units(trained)
                            ? std::string("as plain numbers")
                            : std::string("as lists or covariances (each channel in units of its own noise)")) +
                       " and " + a->config + " weighs the channels otherwise: give operate the training's [online] "
                       "noise_std and disturbance_std, in the same form (its checkpoint's config has them), or run it "
                       "with hinf compare, which converts the measurements");
        OperateOptions opt;
        opt.mode = a->mode;
        opt.runs = a->runs;
        opt.until = a->until;
        opt.quiet = a->quiet;
        std::string mode = a->mode.empty() ? cfg.mode : a->mode;
        opt.out_dir = a->out.empty() ? default_out_dir(a->config, "operate-" + mode) : a->out;
        std::vector<FrozenNetwork*> members;
        for (auto& net : nets) members.push_back(net.get());
        OperateSummary s = operate_run(cfg, members, a->networks, opt);
        std::printf("on-line phase: %s mode, %lld run(s), filter %s, variant %s", s.mode.c_str(),
                    static_cast<long long>(s.runs), cfg.type.c_str(), cfg.variant.c_str());
        if (members.size() > 1) std::printf(", an ensemble of %zu networks (the mean of their gains)", members.size());
        std::printf("\n");
        if (s.truth_escaped_runs > 0)
            std::printf("the truth ran away in %lld of %lld run(s) (the first at t = %g s: not finite, or 1e12 times "
                        "beyond every scale its config gives it; %s); those "
                        "runs count for no figure below\n",
                        static_cast<long long>(s.truth_escaped_runs), static_cast<long long>(s.runs),
                        s.first_truth_escape, truth_escape_cause(cfg).c_str());
        if (s.notes.runs > 0) print_filter_note("dnn", runs_with_note(s.notes, s.runs), s.notes.first);
        if (s.diverged_runs > 0)
            std::printf("DIVERGED: %lld of %lld run(s); the first at t = %.2f s (ratios below are infinite)\n",
                        static_cast<long long>(s.diverged_runs), static_cast<long long>(s.runs), s.first_divergence);
        std::printf("attenuation ratio %.5g (open-loop predictor %.5g, rho = %g)", s.attenuation_ratio,
                    s.attenuation_ratio_open_loop, cfg.rho);
        if (members.size() > 1)
            std::printf("; V(x~(0)) undefined for an ensemble (its members' storages differ)\n");
        else if (std::isnan(s.attenuation_ratio_minus_v0))
            std::printf("; V(x~(0)) undefined for this network\n");
        else
            std::printf("; with V(x~(0)) = %.4g subtracted: %.5g\n", s.v0, s.attenuation_ratio_minus_v0);
        const auto names = cfg.system->state_names();
        std::printf("error x - x^ (mean, std) over time:");
        for (int i = 0; i < cfg.n; ++i)
            std::printf(" %s (%.3g, %.3g)", names[i].c_str(), s.error_mean[i], s.error_std[i]);
        // no step at or after settle_time (a run no longer than it): the line above is the whole run's
        if (cfg.n > 0 && std::isfinite(s.error_mean_settled[0])) {
            std::printf("\nerror after t = %g s (mean, std):", cfg.settle_time);
            for (int i = 0; i < cfg.n; ++i)
                std::printf(" %s (%.3g, %.3g)", names[i].c_str(), s.error_mean_settled[i], s.error_std_settled[i]);
        } else {
            std::printf("\nno step at or after t = %g s (online.settle_time): no settled errors", cfg.settle_time);
        }
        if (std::isfinite(s.online_hji_violation_fraction))
            std::printf("\nHJI inequality violated (> 1%% of S) at %.2f%% of the on-line steps", 100 * s.online_hji_violation_fraction);
        else
            std::printf("\nHJI inequality at the true x~: not evaluated (the network changes along each run)");
        if (std::isfinite(s.online_check_violation_fraction))
            std::printf("\non-line check from x^ alone (16 sampled errors per step): %.2f%% of them violate the dissipation "
                        "inequality", 100 * s.online_check_violation_fraction);
        if (members.size() > 1) {
            std::printf(" with member %d's storage (%s; each member:", s.online_check_network + 1,
                        a->networks[s.online_check_network].c_str());
            for (double f : s.online_check_violation_fraction_per_network) std::printf(" %.2f%%", 100 * f);
            std::printf(")");
        }
        if (s.retrain)
            std::printf("\non-line retraining (delta %g): %.0f trigger(s), %.0f Adam step(s) over %lld run(s) (%.0f undone); "
                        "violation max H/S at the triggers %.3g -> %.3g; run 0's network: %s", cfg.retrain_delta,
                        s.retrain_triggers, s.retrain_adam_steps, static_cast<long long>(s.runs), s.retrain_rejected,
                        s.retrain_eps_before, s.retrain_eps_after,
                        s.online_checkpoint.empty() ? "not written (run 0 diverged)" : s.online_checkpoint.c_str());
        // "position": the states of the first state's unit (compare.md), in that unit
        const std::string u = cfg.system->state_units().empty() || cfg.system->state_units()[0].empty()
                                  ? std::string()
                                  : " " + cfg.system->state_units()[0];
        std::printf("\nposition RMSE %.4g%s (open loop %.4g%s); file: %s/operate.h5\n", s.rmse_position, u.c_str(),
                    s.rmse_position_open_loop, u.c_str(), opt.out_dir.c_str());
    });
}

}  // namespace hinf::cli
