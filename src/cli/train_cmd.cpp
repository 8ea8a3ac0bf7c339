// `hinf train` and `hinf resume`: argument parsing and the end-of-run summary.
#include <cstdio>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "io/progress.hpp"
#include "train/trainer.hpp"

namespace hinf::cli {

namespace {

struct TrainArgs {
    std::string config, checkpoint, out;
    double until = -1;
    int threads = 0;
    std::vector<std::string> sets;
    bool quiet = false;
    bool force = false;
};

void print_summary(const TrainSummary& s, const std::string& dir) {
    std::printf("trained time steps %lld..%lld in %s (%.2f ms per time step)\n", static_cast<long long>(s.first_step),
                static_cast<long long>(s.last_step), format_duration(s.wall_seconds).c_str(),
                s.last_step > s.first_step ? 1e3 * s.wall_seconds / double(s.last_step - s.first_step) : 0.0);
    std::printf("final loss %.4g; median relative HJIE residual %.3g; steps with median <= 0.01: %.1f%%; "
                "steps with <= 1%% of samples violating HJIE <= 0: %.1f%%; mean cos(p, x~) %.3f\n",
                s.final_loss, s.median_rel_residual, 100 * s.fraction_steps_rel_ok,
                100 * s.fraction_steps_violation_ok, s.mean_cosine);
    if (s.mixed)
        std::printf("second HJIE (seed 001 eq. (20)): median relative residual %.3g; steps with <= 1%% of samples "
                    "violating HJIE2 <= 0: %.1f%%; largest gap x^ + x~ vs x: %.3g (with eqs. (11), (23) as printed: "
                    "%.3g)\n",
                    s.median_rel_residual2, 100 * s.fraction_steps_violation2_ok, s.max_consistency_gap,
                    s.max_consistency_gap_printed);
    std::printf("files: %s/trajectory.h5 %s/checkpoint.h5\n", dir.c_str(), dir.c_str());
}

}  // namespace

void add_train_commands(CLI::App& app) {
    auto args = std::make_shared<TrainArgs>();
    CLI::App* train = app.add_subcommand("train", "Train the HJIE-embedded DNN filter offline (seed 000 Fig. 3)");
    train->add_option("config", args->config, "Scenario config (TOML), e.g. runs/missile_hinf.toml")->required();
    train->add_option("--out", args->out, "Output directory (default runs/out/<config name>)");
    train->add_option("--until", args->until, "Stop at this simulated time [s] (default: the config's t_final)");
    train->add_option("--threads", args->threads, "OpenMP threads (default: all cores); results do not depend on it");
    train->add_option("--set", args->sets, "Override a config key, e.g. --set training.adam_steps=10 (repeatable)");
    train->add_flag("--quiet", args->quiet, "No progress lines");
    train->add_flag("--force", args->force, "Start afresh even if the output directory already holds a run");
    train->callback([args]() {
        apply_threads(args->threads);
        RunConfig cfg = load_config_with_overrides(args->config, args->sets);
        TrainOptions opt;
        opt.out_dir = args->out.empty() ? default_out_dir(args->config, "") : args->out;
        HINF_CHECK(args->force || !std::filesystem::exists(opt.out_dir + "/checkpoint.h5"),
                   opt.out_dir + " already holds a run (checkpoint.h5): continue it with `hinf resume " + opt.out_dir +
                       "/checkpoint.h5`, or start afresh with --force or another --out");
        opt.until = args->until;
        opt.quiet = args->quiet;
        TrainSummary s = train_start(cfg, opt);
        if (s.status != 0) throw CLI::RuntimeError(s.status);
        print_summary(s, opt.out_dir);
    });

    CLI::App* resume = app.add_subcommand("resume", "Continue a training run from its checkpoint (bit-identical)");
    resume->add_option("checkpoint", args->checkpoint, "DIR/checkpoint.h5 written by `hinf train`")->required();
    resume->add_option("--until", args->until, "Stop at this simulated time [s] (default: the config's t_final)");
    resume->add_option("--threads", args->threads, "OpenMP threads (default: all cores)");
    resume->add_flag("--quiet", args->quiet, "No progress lines");
    resume->callback([args]() {
        apply_threads(args->threads);
        TrainOptions opt;
        opt.until = args->until;
        opt.quiet = args->quiet;
        TrainSummary s = train_resume(args->checkpoint, opt);
        if (s.status != 0) throw CLI::RuntimeError(s.status);
        print_summary(s, std::filesystem::path(args->checkpoint).parent_path().string());
    });
}

}  // namespace hinf::cli
