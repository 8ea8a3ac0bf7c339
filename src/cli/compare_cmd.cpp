// `hinf compare`: EKF, UKF, PF, the open-loop predictor and trained DNN filters side by side on the same
// truth and measurements; prints the table, writes compare.h5 and compare.csv, optionally the plots.
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "eval/compare.hpp"
#include "eval/engine.hpp"
#include "filters/factory.hpp"
#include "sim/truth.hpp"

namespace hinf::cli {

namespace {
std::string join_names(const std::vector<std::string>& names) {
    std::string all;
    for (const auto& n : names) all += (all.empty() ? "" : ", ") + n;
    return all;
}

struct CompareArgs {
    std::string config, out, scenario = "nominal";
    std::vector<std::string> sets;
    std::int64_t runs = 50;
    FilterSetArgs set{"dnn,ekf,ukf,pf,open_loop", {}, "oracle,measured"};  // --filters, --network, --mode, ...
    double until = -1;
    int threads = 0;
    bool quiet = false, plot = false;
};

}  // namespace

void add_compare_command(CLI::App& app) {
    auto a = std::make_shared<CompareArgs>();
    CLI::App* c = app.add_subcommand("compare", "Compare filters (DNN, EKF, UKF, PF, open loop) on the same truth and noise");
    c->add_option("config", a->config, "Scenario config (TOML): system, noise levels, x0, x^0, Q")->required();
    add_filter_set_options(c, a->set, "dnn,ekf,ukf,pf,open_loop", true);
    c->add_option("--runs", a->runs, "Monte Carlo runs (default 50)");
    c->add_option("--until", a->until, "Simulate up to this time [s] (default t_final)");
    c->add_option("--scenario", a->scenario,
                  "One of: " + join_names(scenario_names()) +
                      " (cov_small / cov_large: EKF/UKF/PF told 10x too small / large covariances; v_cov_*, n_cov_*: "
                      "only the disturbance's / the noise's; docs/compare.md)");
    c->add_option("--out", a->out, "Output directory (default runs/out/<config name>/compare-<scenario>)");
    c->add_option("--threads", a->threads, "OpenMP threads (runs are split over them)");
    c->add_option("--set", a->sets, "Override a config key, e.g. --set online.noise_std=10 (repeatable)");
    c->add_flag("--plot", a->plot, "Draw PNGs with scripts/plot (needs /usr/bin/python3 with h5py and matplotlib)");
    c->add_flag("--quiet", a->quiet, "No progress lines");
    c->callback([a]() {
        apply_threads(a->threads);
        HINF_CHECK(a->runs >= 1, "--runs must be >= 1");
        check_filter_set_options(a->set);
        RunConfig cfg = load_config_with_overrides(a->config, a->sets, filters_need_level(a->set.filters));
        CompareOptions opt;
        opt.scenario = scenario_named(a->scenario);
        opt.runs = a->runs;
        opt.until = a->until;
        opt.quiet = a->quiet;
        opt.out_dir = a->out.empty() ? default_out_dir(a->config, "compare-" + a->scenario) : a->out;
        // the Bayesian filters are told the true statistics (seed 000 Section IV), or wrong ones by scenario
        const FilterModel told = scenario_told_model(cfg, opt.scenario), exact = filter_model(cfg);
        FilterSet set = build_filter_set(
            cfg, a->set, told, exact);
        for (const std::string& note : set.notes) std::printf("%s\n", note.c_str());
        std::vector<const OnlineFilter*> filters;
        for (const auto& o : set.filters) filters.push_back(o.get());
        CompareSummary s = compare_run(cfg, filters, opt);

        // energy_pulse's window is fixed in time (seed 000's manoeuvre): a shorter run meets part of it or none
        const double span = s.scenario == "energy_pulse" ? energy_pulse_span(cfg, s.steps) : kPulseEnd - kPulseStart;
        if (span < kPulseEnd - kPulseStart)
            std::printf("compare: note: energy_pulse's pulse is fixed at %g <= t < %g (seed 000's manoeuvre); this run "
                        "ends at t = %g, so %s (docs/compare.md)\n", kPulseStart, kPulseEnd, cfg.time_of(s.steps),
                        span > 0 ? "it is cut short there"
                                 : "the scenario has no disturbance at all here: its figures are a run without one");
        const auto names = cfg.system->state_names();
        // no step at or after settle_time (a run no longer than it): the state columns give the whole run's errors
        const bool settled = !s.filters.empty() && std::isfinite(s.filters[0].rmse_position_settled);
        char window[96];
        if (settled)
            std::snprintf(window, sizeof window, "after t = %g s", cfg.settle_time);
        else
            std::snprintf(window, sizeof window, "over the whole run (no step at or after t = %g s)", cfg.settle_time);
        std::printf("compare: scenario %s, %lld run(s), %lld steps of %g s; errors x - x^ %s: per-run "
                    "(mean, std) averaged over runs, +- 95%% CI\n",
                    s.scenario.c_str(), static_cast<long long>(s.runs), static_cast<long long>(s.steps), cfg.dt,
                    window);
        std::printf("%-26s %-8s %5s", "filter", "mode", "div");
        for (int i = 0; i < std::min(cfg.n, 3); ++i) std::printf("  %-27s", (names[i] + " (mean, std)").c_str());
        char settled_head[32];  // the settled-window RMSE, named by its window
        std::snprintf(settled_head, sizeof settled_head, "RMSEpos%g", cfg.settle_time);
        std::printf("  %10s %10s %10s %9s %9s %9s\n", "RMSEpos", settled_head, "ratio", "MSEp[dB]", "MSEf[dB]", "us/step");
        for (const auto& fr : s.filters) {
            std::printf("%-26s %-8s %5lld", fr.name.c_str(), fr.mode.c_str(), static_cast<long long>(fr.diverged_runs));
            for (int i = 0; i < std::min(cfg.n, 3); ++i) {
                char cell[64];
                if (settled)
                    std::snprintf(cell, sizeof cell, "%.3g+-%.2g, %.3g+-%.2g", fr.mean_settled[i],
                                  fr.mean_settled_ci[i], fr.std_settled[i], fr.std_settled_ci[i]);
                else
                    std::snprintf(cell, sizeof cell, "%.3g+-%.2g, %.3g+-%.2g", fr.mean[i], fr.mean_ci[i], fr.std[i],
                                  fr.std_ci[i]);
                std::printf("  %-27s", cell);
            }
            std::printf("  %10.4g %10.4g %10.4g %9.2f %9.2f %9.2f\n", fr.rmse_position, fr.rmse_position_settled,
                        fr.attenuation_ratio, fr.mse_db, fr.mse_filtered_db, fr.us_per_step);
        }
        for (const auto& fr : s.filters)
            if (fr.name == "ehf" && fr.report_runs > 0)
                std::printf("ehf: no filter of level rho = %g along the estimate at %.0f step(s) of %lld run(s): it took "
                            "Kalman steps with the game's weights there (a larger --set filter.rho=R avoids them; "
                            "docs/compare.md \"The extended H-infinity filter\")\n",
                            cfg.rho, fr.report_sum[0], static_cast<long long>(fr.report_runs));
        for (const auto& fr : s.filters)
            if (fr.notes.runs > 0) print_filter_note(fr.name, runs_with_note(fr.notes, s.runs), fr.notes.first);
        for (const auto& fr : s.filters) {
            const std::string overconfident = consistency_note(cfg, fr);
            if (!overconfident.empty()) std::printf("%s\n", overconfident.c_str());
        }
        if (s.truth_escaped_runs > 0)
            std::printf("the truth ran away in %lld of %lld run(s) (the first at t = %g s: not finite, or 1e12 times "
                        "beyond every scale its config gives it; %s); those "
                        "runs count for no filter, in the table and in the files\n",
                        static_cast<long long>(s.truth_escaped_runs), static_cast<long long>(s.runs),
                        s.first_truth_escape, truth_escape_cause(cfg).c_str());
        const std::string settle = settle_note(cfg, s, "compare");
        if (!settle.empty()) std::printf("%s\n", settle.c_str());
        std::printf("MSEp / MSEf: 10 log10 of the mean over runs of each run's MSE over all states and steps, of the "
                    "one-step prediction x^(k|k-1) / of the filtered estimate x^(k|k) (nan: none)\n");
        bool same = true;
        for (const auto& fr : s.filters) same = same && fr.stream_hash == s.truth_stream_hash;
        std::printf("measurement streams identical for all filters: %s; wall %.1f s; files: %s/compare.h5, compare.csv\n",
                    same ? "yes" : "NO", s.wall_seconds, opt.out_dir.c_str());
        if (s.rank_seconds.size() > 1) {
            double mx = 0, sum = 0;
            for (double v : s.rank_seconds) {
                mx = std::max(mx, v);
                sum += v;
            }
            const double mean = sum / double(s.rank_seconds.size());
            std::printf("load balance over %zu processes: busy %.2f s max, %.2f s mean (max/mean %.3f)\n",
                        s.rank_seconds.size(), mx, mean, mean > 0 ? mx / mean : 1.0);
        }
        HINF_CHECK(same, "compare: a filter was fed a different measurement stream (bug)");
        if (a->plot) {
            const std::string script = std::string(HINF_SOURCE_DIR) + "/scripts/plot";
            if (std::system("test -x /usr/bin/python3") != 0) {
                std::printf("--plot: /usr/bin/python3 not found, no plots drawn\n");
                return;
            }
            const std::string cmd = "/usr/bin/python3 " + script + " " + opt.out_dir + "/compare.h5 --out " + opt.out_dir;
            int rc = std::system(cmd.c_str());
            std::printf("--plot: %s\n", rc == 0 ? ("PNGs in " + opt.out_dir).c_str() : "scripts/plot failed (see above)");
        }
    });
}

}  // namespace hinf::cli
