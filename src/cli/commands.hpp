// Subcommands of the `hinf` binary. Each add_* registers one subcommand (options + callback).
// Argument parsing only: the numerics live in src/train, src/eval, src/filters, src/lmi.
#pragma once
#include <CLI/CLI.hpp>

namespace hinf::cli {

void add_train_commands(CLI::App& app);   // train, sweep, resume
void add_operate_command(CLI::App& app);  // operate
void add_bench_command(CLI::App& app);    // bench
/// `hinf lmi`: seed 002's LMI filter design (src/cli/lmi_cmd.cpp).
void add_lmi_command(CLI::App& app);
/// `hinf compare`: baseline and DNN filters side by side (src/cli/compare_cmd.cpp).
void add_compare_command(CLI::App& app);
/// `hinf filter`: filters run on recorded measurements, no truth (src/cli/filter_cmd.cpp).
void add_filter_command(CLI::App& app);
/// `hinf worst`: worst-case disturbance and noise per filter, and their replay (src/cli/worst_cmd.cpp).
void add_worst_command(CLI::App& app);
// export: a trained DNN filter as dependency-free C99 (docs/export.md)
void add_export_command(CLI::App& app);
/// `hinf rho`: the smallest attenuation level of the linearised game (src/cli/rho_cmd.cpp).
void add_rho_command(CLI::App& app);

}  // namespace hinf::cli
