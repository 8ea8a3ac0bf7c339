// Seed 002 runs from a TOML config: `hinf lmi` (design, print, DIR/lmi.h5) and the Monte Carlo of Table 3
// (DIR/operate.h5). Not the numerics (delay_lmi, delay_sim) and not argument parsing (src/cli/lmi_cmd.cpp).
#pragma once
#include <iosfwd>
#include <string>

#include "hinf/config.hpp"
#include "lmi/delay_sim.hpp"

namespace hinf::lmi {

/// Everything a config's sections [system] (kind = "ito_delay"), [vertices], [vertex1..m], [bounds],
/// [design], [simulation], [solver] say (docs/formats_lmi.md).
struct DelayConfig {
    DelaySystem system;
    DelayLmiSpec spec;  // with the bounds already chosen (paper values or estimated)
    DelayFilter filter;  // vertices, operating points, weight coordinates (gains come from the design)
    DelaySimSpec sim;
    SdpOptions sdp;
    std::string bounds_source;  // "paper" or "simulation"
    int bound_runs = 20;
    int runs = 100;
    int threads = 0;  // 0: all the OpenMP threads there are
    bool use_paper_gains = false;  // [simulation] gains = "paper_solution": operate with P2^-1 Y_j of [paper_solution]
    bool has_paper_point = false;  // [paper_solution]: a published solution to evaluate in our LMIs
    DelayLmiPoint paper_point;
};

/// Reads and checks the config (throws hinf::Error with file:line on bad input). With bounds from
/// simulation this runs the truth simulations of Table 1 Step 3.
DelayConfig delay_config_read(const ConfigDoc& doc);

/// `hinf lmi`: designs, prints the result on `out`, writes DIR/lmi.h5. Returns 0 on a verified optimal
/// solution and 4 otherwise (no gains are printed or written then).
int delay_lmi_run(const ConfigDoc& doc, const std::string& out_dir, std::ostream& out);

/// `hinf operate` for [system] kind = "ito_delay": designs the filter, runs `runs` Monte Carlo runs
/// (<= 0: the config's) on `threads` threads (<= 0: the config's, then all), writes DIR/operate.h5 with root
/// attributes mean_error_energy, ci95_low, ci95_high. Returns 0, or 4 when the design failed.
int delay_operate(const ConfigDoc& doc, const std::string& out_dir, int runs, int threads);

}  // namespace hinf::lmi
