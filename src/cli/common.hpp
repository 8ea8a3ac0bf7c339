// Helpers shared by subcommands: loading a config with --set overrides, thread count.
#pragma once
#include <omp.h>

#include <filesystem>
#include <string>
#include <vector>

#include "hinf/config.hpp"
#include "hinf/error.hpp"
#include "config/run_config.hpp"

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

/// runs/out/<config file stem>/<suffix>
inline std::string default_out_dir(const std::string& config_path, const std::string& suffix) {
    return "runs/out/" + std::filesystem::path(config_path).stem().string() + (suffix.empty() ? "" : "/" + suffix);
}

}  // namespace hinf::cli
