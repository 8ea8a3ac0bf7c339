// Helpers shared by subcommands: loading a config with --set overrides, thread count.
#pragma once
#include <omp.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "hinf/config.hpp"
#include "hinf/error.hpp"
#include "config/run_config.hpp"
#include "filters/factory.hpp"
#include "filters/filter.hpp"

namespace hinf::cli {

/// need_level = false: the command designs nothing at a level, so a config naming no rho skips rho* (load_run_config);
/// need_run_span = false: a table of known inputs need not cover [0, t_final] (hinf filter checks its record's times).
inline RunConfig load_config_with_overrides(const std::string& path, const std::vector<std::string>& sets,
                                            bool need_level = true, bool need_run_span = true) {
    ConfigDoc doc = ConfigDoc::from_file(path);
    for (const auto& s : sets) doc.set(s);
    return load_run_config(std::move(doc), need_level, need_run_span);
}

inline void apply_threads(int threads) {
    HINF_CHECK(threads >= 0 && threads <= 1024, "--threads " + std::to_string(threads) + " must be between 1 and 1024");
    if (threads > 0) omp_set_num_threads(threads);
}

/// The filter set's options of compare, worst and filter, one help text each, into `set` (checked by
/// check_filter_set_options): --network, --filters (its default as `filters_default` says), --mode where the command
/// runs both DNN modes (compare, worst: `with_modes`; `hinf filter` has measurements alone), --ensemble, and the
/// classical filters' --particles, --pf-roughening and --glf-vertices
inline void add_filter_set_options(CLI::App* c, FilterSetArgs& set, const std::string& filters_default, bool with_modes) {
    c->add_option("--network", set.networks,
                  std::string("Trained network DIR/best.h5 or DIR/checkpoint.h5 for the dnn filter (repeatable: one "
                              "dnn filter per network") + (with_modes ? " and mode)" : ")"));
    c->add_option("--filters", set.filters, "Comma list of: " + filter_names() + " (default " + filters_default + ")");
    if (with_modes) c->add_option("--mode", set.modes, "DNN modes, comma list of oracle, measured (default both)");
    c->add_flag("--ensemble", set.ensemble,
                "One DNN filter, dnn_gain_ensemble, with the mean gain of every --network (variant gain, trained on one "
                "model, e.g. with different training.seed)");
    c->add_option("--particles", set.particles, "Particle filter: particle count (default 2000)");
    c->add_option("--pf-roughening", set.roughening,
                  "Particle filter: roughening constant K after resampling (0 = plain bootstrap PF; Gordon et al. use 0.2)");
    c->add_option("--glf-vertices", set.glf_vertices, "Global-linearization filter: vertex count N (default 8)");
}

inline void check_filter_set_options(const FilterSetArgs& args) {
    HINF_CHECK(args.particles >= 1, "--particles must be >= 1");
    HINF_CHECK(std::isfinite(args.roughening) && args.roughening >= 0,
               "--pf-roughening must be a finite number >= 0 (0: the plain bootstrap PF)");
}

/// runs/out/<config file stem>/<suffix>
inline std::string default_out_dir(const std::string& config_path, const std::string& suffix) {
    return "runs/out/" + std::filesystem::path(config_path).stem().string() + (suffix.empty() ? "" : "/" + suffix);
}

/// A filter's note after its run(s) (OnlineFilter::run_note: a gain filter's estimate far beyond the region its
/// network was trained on), with what to do about it, on one line. `runs`: "" for one record, else e.g.
/// "in 3 of 50 run(s) (the first: run 7), ".
inline void print_filter_note(const std::string& filter, const std::string& runs, const std::string& note) {
    std::printf("note: %s: %s%s. If the system does go there, train over it (the config's x0, xhat0, t_final or "
                "[online] disturbance_std: docs/byos.md section 4); compare with --filters ekf,ukf\n",
                filter.c_str(), runs.c_str(), note.c_str());
}

/// "in K of R run(s) (the first: run r), " for print_filter_note ("" for none).
inline std::string runs_with_note(const RunNotes& notes, std::int64_t runs) {
    if (notes.runs == 0) return "";
    return "in " + std::to_string(notes.runs) + " of " + std::to_string(runs) + " run(s) (the first: run " +
           std::to_string(notes.first_run) + "), ";
}

}  // namespace hinf::cli
