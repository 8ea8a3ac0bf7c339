// `hinf bench`: argument parsing for the training-step benchmark (src/eval/bench.cpp).
#include <filesystem>
#include <sstream>

#include "cli/commands.hpp"
#include "eval/bench.hpp"
#include "hinf/error.hpp"

namespace hinf::cli {

namespace {
std::vector<std::string> split(const std::string& s) {
    std::vector<std::string> out;
    std::stringstream ss(s);
    for (std::string item; std::getline(ss, item, ',');)
        if (!item.empty()) out.push_back(item);
    return out;
}
}  // namespace

void add_bench_command(CLI::App& app) {
    struct Args {
        std::string threads = "1,2", precision = "f32,f64", variant = "paper", out = "runs/out/bench", gemm = "default";
        std::string expr_config = "runs/missile_expr.toml";
        int batch = 800, repeats = 40;
    };
    auto a = std::make_shared<Args>();
    CLI::App* b = app.add_subcommand("bench", "Time the training step (ms, GFLOP/s, fraction of the FMA peak)");
    b->add_option("--threads", a->threads, "Comma-separated thread counts (default 1,2)");
    b->add_option("--batch", a->batch, "Minibatch M (default 800)");
    b->add_option("--precision", a->precision, "Comma-separated: f32, f64 (default both)");
    b->add_option("--variant", a->variant, "paper (the paper's network and loss) or dissipative (default paper)");
    b->add_option("--repeats", a->repeats, "Timed steps per configuration (default 40)");
    b->add_option("--out", a->out, "Output directory for bench.h5 (default runs/out/bench)");
    b->add_option("--expr-config", a->expr_config,
                  "Expression system whose evaluation cost is timed (default runs/missile_expr.toml; \"\" to skip)");
    b->add_option("--gemm", a->gemm, "GEMM kernels, comma-separated and timed interleaved: default (own where built, else openblas), own, "
                  "openblas, eigen");
    b->callback([a]() {
        BenchOptions opt;
        opt.threads.clear();
        for (const auto& t : split(a->threads)) {
            try {
                opt.threads.push_back(std::stoi(t));
            } catch (const std::exception&) {
                HINF_FAIL("--threads '" + a->threads + "' must be comma-separated integers, e.g. 1,2");
            }
        }
        HINF_CHECK(!opt.threads.empty(), "--threads needs at least one count, e.g. 1,2");
        opt.precisions = split(a->precision);
        HINF_CHECK(a->variant == "paper" || a->variant == "dissipative",
                   "--variant '" + a->variant + "' is not one of: paper, dissipative");
        opt.variant = a->variant;
        opt.batch = a->batch;
        opt.repeats = a->repeats;
        opt.out_dir = a->out;
        opt.expr_config = a->expr_config;
        // the default example also when run outside the source tree
        std::error_code ec;
        if (a->expr_config == "runs/missile_expr.toml" && !std::filesystem::exists(a->expr_config, ec))
            opt.expr_config = std::string(HINF_SOURCE_DIR) + "/runs/missile_expr.toml";
        opt.gemm = a->gemm;
        bench_run(opt);
    });
}

}  // namespace hinf::cli
