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

/// need_level = false: the command designs nothing at a level, so a config naming no rho skips rho* (load_run_config).
inline RunConfig load_config_with_overrides(const std::string& path, const std::vector<std::string>& sets,
                                            bool need_level = true) {
    ConfigDoc doc = ConfigDoc::from_file(path);
    for (const auto& s : sets) doc.set(s);
    return load_run_config(std::move(doc), need_level);
}

inline void apply_threads(int threads) {
    HINF_CHECK(threads >= 0 && threads <= 1024, "--threads " + std::to_string(threads) + " must be between 1 and 1024");
    if (threads > 0) omp_set_num_threads(threads);
}

/// The classical filters' options of compare, filter and worst, one help text each, into args' particles, roughening
/// and glf_vertices (checked by check_baseline_options)
inline void add_baseline_options(CLI::App* c, FilterSetArgs& args) {
    c->add_option("--particles", args.particles, "Particle filter: particle count (default 2000)");
    c->add_option("--pf-roughening", args.roughening,
                  "Particle filter: roughening constant K after resampling (0 = plain bootstrap PF; Gordon et al. use 0.2)");
    c->add_option("--glf-vertices", args.glf_vertices, "Global-linearization filter: vertex count N (default 8)");
}

inline void check_baseline_options(const FilterSetArgs& args) {
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
