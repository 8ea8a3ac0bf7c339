// `hinf bench`: times the training step (forward, loss, backward, Adam on M samples) per precision
// and thread count, the per-time-step work outside it, and this machine's register-FMA peak.
#pragma once
#include <string>
#include <vector>

namespace hinf {

struct BenchOptions {
    std::vector<int> threads = {1, 2};
    std::vector<std::string> precisions = {"f32", "f64"};
    int batch = 800;
    int repeats = 40;
    std::string variant = "paper";  // "paper" (the paper's network and loss) or "dissipative"
    std::string out_dir = "runs/out/bench";
    std::string expr_config = "runs/missile_expr.toml";  // expression system to time ("" = skip that section)
    // GEMM paths, comma-separated, timed interleaved: "default", "own", "openblas", "eigen" (kern::GemmPath)
    std::string gemm = "default";
};

struct BenchRow {
    std::string precision, variant, gemm;
    int threads = 1;
    double median_ms = 0, min_ms = 0, max_ms = 0;
    double gflops = 0, peak_gflops = 0;
    double outside_ms = 0;  // per time step, outside the K Adam steps
};

/// Expression-system evaluation cost (bench_expr in bench.cpp): per state, and as a share of a training time step.
struct BenchExpr {
    double f_ns = 0, g_ns = 0, h_ns = 0;            // per state, in bulk over N states
    double df_us = 0, dh_us = 0;                    // one Jacobian at one state
    double ref_f_ns = 0, ref_g_ns = 0, ref_h_ns = 0, ref_df_us = 0, ref_dh_us = 0;  // built-in missile
    double eval_ms = 0, time_step_ms = 0;           // per training time step: f, g, h on N + 2 states; all
};

/// Runs the benchmark, prints a table on stdout, writes out_dir/bench.h5. Returns the rows.
std::vector<BenchRow> bench_run(const BenchOptions& opt);

}  // namespace hinf
