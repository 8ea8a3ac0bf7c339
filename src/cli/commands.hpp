// Subcommands of the `hinf` binary. Each add_* registers one subcommand (options + callback).
// Argument parsing only: the numerics live in src/train, src/eval, src/filters, src/lmi.
#pragma once
#include <CLI/CLI.hpp>

namespace hinf::cli {


}  // namespace hinf::cli
