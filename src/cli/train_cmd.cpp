// `hinf train` and `hinf resume`: argument parsing and the end-of-run summary.
#include <algorithm>
#include <csignal>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cli/commands.hpp"
#include "cli/common.hpp"
#include "eval/acceptance.hpp"
#include "eval/training_run.hpp"
#include "io/progress.hpp"
#include "io/run_lock.hpp"
#include "par/par.hpp"
#include "train/sweep.hpp"
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

// Ctrl-C / SIGTERM: the trainer stops at the next safe point with a checkpoint; a second signal ends at once.
extern "C" void on_stop_signal(int sig) {
    train_request_stop(sig);
    std::signal(sig, SIG_DFL);
}
void install_stop_handlers() {
    if (par_world_size() > 1) return;  // under mpirun every process must stop at the same step: not handled yet
    std::signal(SIGINT, on_stop_signal);
    std::signal(SIGTERM, on_stop_signal);
}

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

void print_acceptance(const AcceptanceOutcome& a) {
    if (a.ran) std::printf("%s\n", a.line.c_str());
    if (!a.advice.empty()) std::printf("%s\n", a.advice.c_str());
    if (!a.selection_note.empty()) std::printf("%s\n", a.selection_note.c_str());
    if (!a.settle_note.empty()) std::printf("%s\n", a.settle_note.c_str());
    if (!a.note.empty()) std::printf("%s\n", a.note.c_str());
    if (!a.search_note.empty()) std::printf("%s\n", a.search_note.c_str());
    std::fflush(stdout);  // before what comes next on stderr
}

// What `hinf train` and `hinf resume` print as the run goes: each run's summary and selection (the first, and another
// storage's run where one is kept), `first_notes` after the first, and each acceptance check's line and notes
TrainingRunHooks printing_hooks(const std::string& dir,
                                std::function<void(const RunConfig&, const TrainSummary&)> first_notes) {
    TrainingRunHooks h;
    h.before_training = install_stop_handlers;
    h.trained = [dir, first_notes](const RunConfig& cfg, const TrainSummary& s, const Selection* best, bool again) {
        print_summary(s, dir);
        if (best) std::printf("%s\n", selection_line(cfg, *best, dir).c_str());
        if (!again && first_notes) first_notes(cfg, s);
    };
    h.checked = print_acceptance;
    return h;
}

// The exit of a run: its status where it stopped; 5 where it failed its acceptance check and the config requires it
void exit_as(const TrainingRun& run) {
    if (run.summary.status != 0) throw CLI::RuntimeError(run.summary.status);
    const AcceptanceOutcome& a = run.acceptance;
    if (a.ran && !a.pass && run.cfg.require_acceptance) {
        std::fprintf(stderr, "hinf: error: the trained filter failed its acceptance check (%s: attenuation ratio or "
                             "worst-case ratio above [filter] rho, or a diverged run); training.require_acceptance "
                             "is set (train longer or with another seed, or unset it)\n", a.file.c_str());
        throw CLI::RuntimeError(5);
    }
}

// `hinf sweep --worst`: each value's level against what hinf worst's full search found on its checkpoint, and the
// smallest level kept
void print_sweep_levels(const std::string& key, const std::vector<SweepRow>& rows) {
    std::printf("\nthe level each value's filter keeps (hinf worst's full search on the checkpoint its acceptance "
                "check judged; DIR/<value>/worst/worst.h5):\n");
    std::printf("%-24s %10s %12s %10s %10s %10s\n", key.c_str(), "rho", "worst found", "EKF", "UKF", "keeps rho");
    const SweepRow* smallest = nullptr;
    bool unsearched = false;
    for (const auto& r : rows) {
        const SweepVerdict& v = r.verdict;
        const std::string keeps = v.keeps_level();
        std::printf("%-24s %10.4g %11.4g%s %10.4g %10.4g %10s\n", r.value.c_str(), v.rho, v.search_ratio,
                    v.search_diverged == 1 ? "!" : " ", v.search_ratio_ekf, v.search_ratio_ukf, keeps.c_str());
        unsearched = unsearched || keeps == "-";
        if (keeps == "yes" && (!smallest || v.rho < smallest->verdict.rho)) smallest = &r;
    }
    if (smallest)
        std::printf("the smallest level kept: rho = %.6g (%s = %s; worst ratio found %.4g); the search is a lower "
                    "bound on each filter's worst case (docs/compare.md)\n", smallest->verdict.rho, key.c_str(),
                    smallest->value.c_str(), smallest->verdict.search_ratio);
    else
        std::printf("no value's filter keeps its level under the search: a higher filter.rho is a weaker promise, "
                    "easier to keep (hinf rho gives the smallest level any filter can keep)\n");
    if (unsearched)
        std::printf("(-: no search: no acceptance check ran (the value's run did not reach t_final, ran in a group "
                    "of more than one process, was finished by an earlier job, or training.acceptance_runs = 0), or "
                    "the run has no energy budget or under two time steps; ! = the filter diverged under its worst "
                    "signals)\n");
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
        // the directory is this command's until it ends: the training, the selection, the acceptance check and a
        // second run swapped in (a `train --force` started during the check removed best.h5 under it)
        const RunDirLock lock(opt.out_dir, "hinf train");
        HINF_CHECK(args->force || !std::filesystem::exists(opt.out_dir + "/checkpoint.h5"),
                   opt.out_dir + " already holds a run (checkpoint.h5): continue it with `hinf resume " + opt.out_dir +
                       "/checkpoint.h5`, or start afresh with --force or another --out");
        opt.until = args->until;
        opt.quiet = args->quiet;
        const auto mpi_notes = [](const RunConfig& c, const TrainSummary&) {
            if (c.select_every > 0 && par_world_size() > 1 && par_root())
                std::printf("select: skipped under mpirun (run hinf compare on the checkpoints)\n");
            if (c.acceptance_runs > 0 && par_world_size() > 1 && par_root())
                std::printf("acceptance: skipped under mpirun (run hinf operate --mode measured on the checkpoint)\n");
        };
        exit_as(training_run_fresh(std::move(cfg), opt, printing_hooks(opt.out_dir, mpi_notes)));
    });

    auto sw = std::make_shared<TrainArgs>();
    auto vary = std::make_shared<std::string>();
    auto search = std::make_shared<bool>(false);
    CLI::App* sweep = app.add_subcommand(
        "sweep", "Train one config for several values of one key as one job (mpirun: one training per process group), "
                 "each ending as `hinf train` does (best.h5, the acceptance check); choose by the validation MSE");
    sweep->add_option("config", sw->config, "Scenario config (TOML)")->required();
    sweep->add_option("--vary", *vary, "KEY=V1,V2,...: one training per value, e.g. training.seed=1,2,3")->required();
    sweep->add_option("--out", sw->out, "Output directory (default runs/out/<config name>/sweep); one KEY=V inside per value");
    sweep->add_option("--until", sw->until, "Stop each training at this simulated time [s]");
    sweep->add_option("--threads", sw->threads, "OpenMP threads per process");
    sweep->add_option("--set", sw->sets, "Override a config key for every value (repeatable)");
    sweep->add_flag("--quiet", sw->quiet, "No progress lines (neither the line after each value nor the trainings')");
    sweep->add_flag("--worst", *search,
                    "After each value's acceptance check, run hinf worst's full search (its defaults: dnn, ekf, ukf) "
                    "on the checkpoint it judged and say whether the filter keeps that value's rho (e.g. --vary "
                    "filter.rho=...: the smallest level kept); DIR/<value>/worst/worst.h5");
    sweep->callback([sw, vary, search]() {
        apply_threads(sw->threads);
        SweepOptions opt;
        const std::size_t eq = vary->find('=');
        HINF_CHECK(eq != std::string::npos && eq > 0, "--vary " + *vary + ": expected KEY=V1,V2,... (e.g. training.seed=1,2,3)");
        opt.key = vary->substr(0, eq);
        std::stringstream in(vary->substr(eq + 1));
        for (std::string v; std::getline(in, v, ',');) opt.values.push_back(v);
        HINF_CHECK(!opt.values.empty(), "a sweep needs at least one value: --vary " + opt.key + "=V1,V2,...");
        opt.sets = sw->sets;
        opt.until = sw->until;
        opt.quiet = sw->quiet;
        opt.out_dir = sw->out.empty() ? default_out_dir(sw->config, "sweep") : sw->out;
        const int groups = std::min<int>(int(opt.values.size()), par_world_size());
        std::printf("sweep: %zu value(s) of %s over %d process group(s) of %d process(es)\n", opt.values.size(),
                    opt.key.c_str(), std::max(groups, 1), par_world_size() / std::max(groups, 1));
        std::fflush(stdout);
        // each value ends as `hinf train` does: the checkpoint selection during training, the acceptance check after
        const bool full_search = *search;
        opt.around = [full_search](const RunConfig& cfg, const std::string& dir, bool resumed, TrainOptions o,
                                   TrainSummary& s) {
            SweepVerdict v;
            const RunDirLock lock(dir, "hinf sweep");  // the value's directory to the end of its check, as train's
            const TrainingRun run = resumed ? training_run_resume(dir + "/checkpoint.h5", o, "hinf sweep", {})
                                            : training_run_fresh(cfg, o, {});
            s = run.summary;
            v.rho = run.cfg.rho;
            const AcceptanceOutcome& a = run.acceptance;
            if (run.best && run.best->step >= 0) {  // after the check: it may keep the last checkpoint instead
                v.best_step = run.best->step;
                v.select_score = run.best->score;
            }
            if (a.ran) {
                v.acceptance = a.pass ? "pass" : "fail";
                v.rmse_position = a.rmse_position;
                v.worst_ratio = a.worst_ratio;
                v.rmse_settled = a.rmse_position_settled;
                v.rmse_settled_ekf = a.rmse_position_settled_ekf;
                v.rms_q_settled = a.rms_q_settled;
                v.rms_q_settled_ekf = a.rms_q_settled_ekf;
                // the level kept: the acceptance's search is short; hinf worst's, on the checkpoint it judged
                if (full_search) {
                    const LevelSearch l = level_search(run.cfg, a.file, dir + "/worst", /*quiet=*/true);
                    v.search_ratio = l.dnn;
                    v.search_ratio_ekf = l.ekf;
                    v.search_ratio_ukf = l.ukf;
                    if (l.skipped.empty()) v.search_diverged = l.diverged ? 1 : 0;
                }
            }
            return v;
        };
        std::vector<SweepRow> rows = sweep_run(sw->config, opt);
        std::printf("%-24s %-12s %6s %9s %10s %12s %9s %12s %10s %10s %10s %8s %9s\n", opt.key.c_str(), "how", "status",
                    "steps", "wall [s]", "final loss", "best step", "valid. MSE", "accept", "RMSE pos", "worst", "x EKF",
                    "knots ran");
        for (const auto& r : rows) {
            const SweepVerdict& v = r.verdict;
            std::printf("%-24s %-12s %6d %9lld %10.2f %12.4g %9s %12.4g %10s %10.4g %10.4g %8.3g %9s\n", r.value.c_str(),
                        r.how.c_str(), r.summary.status, static_cast<long long>(r.summary.last_step),
                        r.summary.wall_seconds, r.summary.final_loss,
                        v.best_step >= 0 ? std::to_string(v.best_step).c_str() : "-", v.select_score,
                        v.acceptance.c_str(), v.rmse_position, v.worst_ratio, v.behind_ekf(),
                        r.summary.runaway_step >= 0 ? std::to_string(r.summary.runaway_step).c_str() : "-");
        }
        if (*search) print_sweep_levels(opt.key, rows);
        std::printf("files: %s/sweep.csv and one directory per value (checkpoint.h5, trajectory.h5, summary.csv, "
                    "best.h5 where the selection runs; valid. MSE: best.h5's settled Q-weighted MSE on the validation "
                    "noise, the one to choose by; x EKF: the acceptance runs' settled error over the EKF's on the same "
                    "runs, the larger of position and all states Q-weighted; knots ran: the time step after which a "
                    "knot of S(t) ran away, docs/method.md section 16.7)\n", opt.out_dir.c_str());
        // training.require_acceptance: a sweep is for finding a value that passes, so it fails when none does
        bool required = false, checked = false, passed = false;
        for (std::size_t i = 0; i < rows.size(); ++i) {
            std::vector<std::string> sets = opt.sets;
            sets.push_back(opt.key + "=" + opt.values[i]);
            required = required || load_config_with_overrides(sw->config, sets).require_acceptance;
            checked = checked || rows[i].verdict.acceptance != "-";
            passed = passed || rows[i].verdict.acceptance == "pass";
        }
        if (required && checked && !passed) {
            if (par_root())  // every rank holds the gathered table; one line
                std::fprintf(stderr, "hinf: error: no value of %s passed its acceptance check (sweep.csv, column "
                                     "acceptance) and training.require_acceptance is set (try other values, or unset "
                                     "it)\n", opt.key.c_str());
            throw CLI::RuntimeError(5);
        }
    });

    CLI::App* resume = app.add_subcommand("resume", "Continue a training run from its checkpoint (bit-identical)");
    resume->add_option("checkpoint", args->checkpoint, "DIR/checkpoint.h5 written by `hinf train`")->required();
    resume->add_option("--until", args->until, "Stop at this simulated time [s] (default: the config's t_final)");
    resume->add_option("--threads", args->threads, "OpenMP threads (default: all cores)");
    resume->add_option("--set", args->sets,
                       "Change a key that may change on resume, e.g. --set training.learning_rate=1e-4 (repeatable; "
                       "recorded in the config of the checkpoint and trajectory)");
    resume->add_flag("--quiet", args->quiet, "No progress lines");
    resume->callback([args]() {
        apply_threads(args->threads);
        TrainOptions opt;
        opt.until = args->until;
        opt.quiet = args->quiet;
        opt.sets = args->sets;
        std::string dir = std::filesystem::path(args->checkpoint).parent_path().string();
        if (dir.empty()) dir = ".";
        const auto changed_note = [args](const RunConfig&, const TrainSummary& s) {
            if (args->sets.empty()) return;
            std::string changed;
            for (const auto& v : args->sets) changed += " " + v;
            std::printf("changed on resume at step %lld:%s (recorded as a '# hinf resume' line in the config of the "
                        "checkpoint and trajectory)\n", static_cast<long long>(s.first_step), changed.c_str());
        };
        exit_as(training_run_resume(args->checkpoint, opt, "hinf resume", printing_hooks(dir, changed_note)));
    });
}

}  // namespace hinf::cli
