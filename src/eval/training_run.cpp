// A training run from its first step to its verdict (training_run.hpp).
#include "eval/training_run.hpp"

#include <cstdio>
#include <exception>
#include <filesystem>
#include <optional>
#include <utility>

#include "eval/observability.hpp"
#include "io/checkpoint.hpp"
#include "io/run_lock.hpp"
#include "io/run_swap.hpp"
#include "par/par.hpp"

namespace hinf {

namespace {

// The run trained (and chosen): its check, and where it is far behind the EKF another storage's run and its check
TrainingRun finish(RunConfig cfg, TrainSummary s, std::shared_ptr<Selection> best, const std::string& dir,
                   bool resumed, bool quiet, const TrainingRunHooks& hooks) {
    if (hooks.trained) hooks.trained(cfg, s, best.get(), /*again=*/false);
    AcceptanceOutcome a = acceptance_after(cfg, dir, s, best.get(), resumed, quiet);
    if (hooks.checked) hooks.checked(a);
    if (choose_storage_far_behind(&cfg, &s, &best, dir, quiet, a)) {  // the other storage kept: its own check
        if (hooks.trained) hooks.trained(cfg, s, best.get(), /*again=*/true);
        const AcceptanceOutcome replaced = a;
        a = acceptance_after(cfg, dir, s, best.get(), /*resumed=*/false, quiet);
        const std::string exchange = storage_exchange_note(replaced, a, dir);  // its worst case beside the first's
        if (!exchange.empty()) a.selection_note += (a.selection_note.empty() ? "" : "\n") + exchange;
        if (hooks.checked) hooks.checked(a);
    }
    return TrainingRun{std::move(cfg), s, std::move(best), std::move(a)};
}

}  // namespace

TrainingRun training_run_fresh(RunConfig cfg, TrainOptions opt, const TrainingRunHooks& hooks) {
    const std::string dir = opt.out_dir;
    if (par_root() && opt.config_notes) {  // a state the outputs do not see: said before the training's time is spent
        const std::string note = unseen_states_note(cfg, state_information(cfg));
        if (!note.empty()) std::fprintf(stderr, "%s\n", note.c_str());
    }
    std::shared_ptr<Selection> best = selection_begin(cfg, dir, /*fresh=*/true, opt);
    if (hooks.before_training) hooks.before_training();
    TrainSummary s = train_start(cfg, opt);
    // each choice trains a second run only after a first that reached t_final (s.status == 0), and stops where the
    // second is interrupted (s.status = 128 + signal): the first run stays in DIR
    if (s.status == 0) choose_held_start(&cfg, &s, &best, dir, opt.quiet);  // a Riccati start held at once: both
    if (s.status == 0) choose_game_in_noise_units(&cfg, &s, &best, dir, opt.quiet);  // none validated: the other game
    if (s.status != 0) return TrainingRun{std::move(cfg), s, std::move(best), {}};
    return finish(std::move(cfg), s, std::move(best), dir, /*resumed=*/false, opt.quiet, hooks);
}

TrainingRun training_run_resume(const std::string& checkpoint, TrainOptions opt, const std::string& command,
                                const TrainingRunHooks& hooks) {
    std::string dir = std::filesystem::path(checkpoint).parent_path().string();
    if (dir.empty()) dir = ".";
    if (std::filesystem::exists(dir + "/" + kSwapFolder)) {  // a kill during two runs' exchange: finished first
        const RunDirLock settle(dir, command);                // (the checkpoint may be in that folder)
    }
    // the selection reads the file's config; it is read in a child first (a damaged file may crash the HDF5 library)
    RunConfig before;
    bool readable = false;
    try {
        ckpt_verify(checkpoint);
        before = ckpt_config(checkpoint);
        readable = true;
    } catch (const std::exception&) {
        // a checkpoint that cannot be read: train_resume says so, with its hint about checkpoint.prev.h5
    }
    std::optional<RunDirLock> lock;  // held to the end, as a fresh run's: the check and a run swapped in included
    if (readable) lock.emplace(dir, command);  // (no lock file beside a file that is not a checkpoint)
    std::shared_ptr<Selection> best = readable ? selection_begin(before, dir, /*fresh=*/false, opt) : nullptr;
    if (hooks.before_training) hooks.before_training();
    TrainSummary s = train_resume(checkpoint, opt);
    if (s.status != 0) return TrainingRun{std::move(before), s, std::move(best), {}};
    // with the keys changed on resume, as given (the keys hinf chose, such as the start check's flat knots, are not
    // the user's; its default level is read as such): resumed to t_final, it ends as the same run uninterrupted, which
    // decides from the config it was given -- a Riccati start held at once trains both storages, a run none of whose
    // checkpoints validated the game in noise units, one far behind the EKF the other storages
    RunConfig after = config_as_given(ckpt_config(checkpoint));
    choose_held_start(&after, &s, &best, dir, opt.quiet);
    if (s.status == 0) choose_game_in_noise_units(&after, &s, &best, dir, opt.quiet);
    if (s.status != 0) return TrainingRun{std::move(after), s, std::move(best), {}};
    return finish(std::move(after), s, std::move(best), dir, /*resumed=*/true, opt.quiet, hooks);
}

}  // namespace hinf
