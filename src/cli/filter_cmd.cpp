// `hinf filter`: a trained DNN filter (measured mode) or EKF/UKF/PF/GLF/open loop run on recorded
// measurements; prints truth-free diagnostics and writes estimates.h5 and one CSV per filter.
#include <cmath>
#include <cstdio>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "filters/factory.hpp"
#include "eval/engine.hpp"
#include "eval/filter_recorded.hpp"
#include "io/measurements.hpp"
#include "models/expr_system.hpp"
#include "sim/truth.hpp"

namespace hinf::cli {

namespace {
struct FilterArgs {
    std::string config, measurements, out, dataset = "y", time_dataset = "t", resample;
    double time_tolerance = kUniformTolerance;
    std::vector<std::string> sets;
    std::vector<double> xhat0, initial_std;
    FilterSetArgs set{"", {}, "measured"};  // --filters (default: dnn with --network, else ekf), --network, ...
    int threads = 0;
    bool quiet = false;
};
}  // namespace

void add_filter_command(CLI::App& app) {
    auto a = std::make_shared<FilterArgs>();
    CLI::App* c = app.add_subcommand("filter", "Run a trained filter (or EKF/UKF/PF/GLF) on recorded measurements; no true state needed");
    c->add_option("config", a->config, "Config (TOML) of the system the measurements come from")->required();
    c->add_option("--measurements", a->measurements,
                  "Recorded measurements: CSV (time column + one column per output, optional header) or HDF5 "
                  "(datasets t [K] and y [K x m]); a CSV column or HDF5 dataset inputs/NAME named as a known input "
                  "([system] inputs) is that input, in place of the config's table; docs/formats.md")
        ->required();
    add_filter_set_options(c, a->set, "dnn with --network, else ekf", false);
    c->add_option("--dataset", a->dataset, "HDF5: dataset of the measurements [K x m] (default y)");
    c->add_option("--time-dataset", a->time_dataset, "HDF5: dataset of the times [K] in s (default t)");
    c->add_option("--time-tolerance", a->time_tolerance,
                  "Largest difference of any time step from the record's mean step, as a fraction of that step "
                  "(default 0.05: clock jitter of +-1e-4 s at 0.01 s passes)");
    c->add_option("--resample", a->resample,
                  "Put a non-uniform record on the uniform grid t_0 + k dt (dt its mean step): linear or zoh "
                  "(zero-order hold)");
    c->add_option("--initial-estimate", a->xhat0, "x^(t_0), one value per state (default: the config's [filter] xhat0)")
        ->delimiter(',');
    c->add_option("--initial-std", a->initial_std,
                  "EKF/UKF/PF: standard deviation of x^(t_0)'s error per state, 0 for a known state (default: the "
                  "config's [baseline] initial_std, else |x0 - xhat0| of the config)")
        ->delimiter(',');
    c->add_option("--out", a->out, "Output directory (default runs/out/<config name>/filter)");
    c->add_option("--set", a->sets, "Override a config key, e.g. --set online.noise_std=10 (repeatable)");
    c->add_option("--threads", a->threads, "OpenMP threads");
    c->add_flag("--quiet", a->quiet, "No progress lines");
    c->callback([a]() {
        apply_threads(a->threads);
        check_filter_set_options(a->set);
        // the record's times, not [0, t_final], are what a table of known inputs must cover (recorded_check_sampling)
        ConfigDoc doc = ConfigDoc::from_file(a->config);
        for (const auto& s : a->sets) doc.set(s);
        const bool need_level = filters_need_level(a->set.filters);
        RunConfig cfg = load_run_config(doc, need_level, false);
        const ExprSystem* expr = expr_system_of(*cfg.system);
        Measurements ms = read_measurements(MeasurementSource{a->measurements, cfg.m, a->time_dataset, a->dataset,
                                                              a->time_tolerance, a->resample,
                                                              expr ? expr->inputs() : std::vector<std::string>{}});
        // a record with its inputs beside the outputs: those are the inputs of this run, unless the command line names
        // a table (the what-if of other inputs on the same record)
        std::string named_table;
        for (const auto& s : a->sets)
            if (s.rfind("system.inputs=", 0) == 0) named_table = s;
        if (!ms.input_names.empty()) {
            std::string names;
            for (const std::string& name : ms.input_names) names += (names.empty() ? "" : ", ") + name;
            if (named_table.empty()) {
                set_known_inputs(doc, ms.input_names, ms.input_t, ms.input_values,
                                 "measurements '" + a->measurements + "'");
                cfg = load_run_config(std::move(doc), need_level, false);
            }
            if (!a->quiet)
                std::printf("known inputs %s: %s\n", names.c_str(),
                            named_table.empty() ? "the record's own, on its times (in place of the config's table)"
                                                : ("--set " + named_table + ", not the record's own").c_str());
        }
        const int n = cfg.n;
        if (ms.dt > 10 * cfg.dt || ms.dt < 0.1 * cfg.dt)  // e.g. a time column in milliseconds
            std::fprintf(stderr,
                         "warning: the record's time step %g s is far from the config's dt %g s (is the time column in "
                         "seconds?); the filters step on the record's\n",
                         ms.dt, cfg.dt);
        recorded_check_sampling(cfg, ms, a->measurements);

        RecordedOptions opt;
        opt.out_dir = a->out.empty() ? default_out_dir(a->config, "filter") : a->out;
        opt.source = a->measurements;
        opt.quiet = a->quiet;
        opt.xhat0 = a->xhat0.empty() ? cfg.xhat0 : a->xhat0;
        HINF_CHECK(int(opt.xhat0.size()) == n, "--initial-estimate has " + std::to_string(opt.xhat0.size()) +
                                                   " values, the system has " + std::to_string(n) + " states");
        for (int i = 0; i < n; ++i)
            HINF_CHECK(std::isfinite(opt.xhat0[i]), "--initial-estimate: value " + std::to_string(i + 1) + " is not a "
                                                        "finite number (pass one number per state)");
        for (double v : a->initial_std)
            HINF_CHECK(std::isfinite(v) && v >= 0, "--initial-std: every value must be a finite number >= 0 (0: the "
                                                   "state is known at the start)");
        HINF_CHECK(a->initial_std.empty() || int(a->initial_std.size()) == n,
                   "--initial-std has " + std::to_string(a->initial_std.size()) + " values, the system has " +
                       std::to_string(n) + " states");
        opt.P0 = baseline_initial_covariance(cfg, a->initial_std);  // what `compare` tells the filters by default

        // the filters step on the record's own grid; EKF/UKF/PF are told the config's [baseline] model and statistics
        // (default: [system] and [online])
        FilterModel told = scenario_told_model(cfg, scenario_named("nominal")), model = filter_model(cfg);
        told.dt = model.dt = ms.dt;
        FilterSetArgs chosen = a->set;
        if (chosen.filters.empty()) chosen.filters = chosen.networks.empty() ? "ekf" : "dnn";
        bool bayes = false;  // a filter that starts from P0
        for (const std::string& f : split_list(chosen.filters)) bayes = bayes || f == "ekf" || f == "ukf" || f == "pf";
        if (bayes && a->initial_std.empty() && cfg.initial_std.empty() && !opt.quiet) {  // the default P0: say if certain
            const std::string note = baseline_certain_note(cfg, opt.P0);
            if (!note.empty()) std::printf("%s\n", note.c_str());
        }
        FilterSet set = build_filter_set(cfg, chosen, told, model);
        for (const std::string& note : set.notes) std::printf("%s\n", note.c_str());
        std::vector<OnlineFilter*> filters;
        for (auto& f : set.filters) filters.push_back(f.get());
        std::printf("filter: %lld measurements of %d output(s) from %s, t = %g .. %g s, dt = %g s%s\n",
                    static_cast<long long>(ms.rows), ms.m, a->measurements.c_str(), ms.t.front(), ms.t.back(), ms.dt,
                    (std::string(a->resample.empty() ? "" : " (resampled, " + a->resample + ")") +
                     (ms.missing_rows > 0 ? "; " + std::to_string(ms.missing_rows) +
                                                " row(s) without a measurement (empty or NaN): predicted only"
                                          : "")).c_str());
        std::vector<RecordedResult> res = filter_recorded(cfg, filters, ms, opt);

        std::printf("%-26s %-9s", "filter (mode measured)", "diverged");
        for (int j = 0; j < std::min(cfg.m, 4); ++j) std::printf("  %-26s", ("innovation " + std::to_string(j + 1) + " (mean, rms)").c_str());
        std::printf("  %8s  %9s\n", "NIS/m", "us/step");
        for (const auto& r : res) {
            char div[32];
            if (r.diverged_at < 0) std::snprintf(div, sizeof div, "no");
            else std::snprintf(div, sizeof div, "t=%g", r.diverged_at);  // non-finite, or left the plausible range
            std::printf("%-26s %-9s", r.name.c_str(), div);
            for (int j = 0; j < std::min(cfg.m, 4); ++j) {
                char cell[48];
                std::snprintf(cell, sizeof cell, "%.3g, %.3g", r.innovation_mean[j], r.innovation_rms[j]);
                std::printf("  %-26s", cell);
            }
            if (std::isfinite(r.nis_per_output)) std::printf("  %8.3g", r.nis_per_output);
            else std::printf("  %8s", "-");
            std::printf("  %9.2f\n", r.us_per_step);
        }
        for (const auto& r : res)
            if (!r.note.empty()) print_filter_note(r.name, "", r.note);
        for (const auto& r : res) {
            const std::string off = innovation_consistency_note(r);
            if (!off.empty()) std::printf("%s\n", off.c_str());
        }
        bool any_nis = false;
        for (const auto& r : res) any_nis = any_nis || std::isfinite(r.nis_per_output);
        if (any_nis)
            std::printf("NIS/m: mean normalised innovation squared per output after t = %g s, against the innovations' "
                        "covariance each Bayesian filter expects (about 1 where its statistics hold; -: states none)\n",
                        res.front().nis_from);
        std::printf("files: %s/estimates.h5, estimates_<filter>.csv (xhat[k] estimates x(t_k) from y before t_k)\n",
                    opt.out_dir.c_str());
    });
}

}  // namespace hinf::cli
