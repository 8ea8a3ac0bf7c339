// What a training run does around the trainer, for `hinf train`/`resume` and the library's hinf::train/resume alike:
// keeping the best validated checkpoint (training.select_every, docs/method.md section 16.9) and the acceptance
// check at t_final (a validation Monte Carlo and a short worst-case search, section 16.5). Both run the checkpoints
// as the filter a user runs (operate's engine, `measured`); neither changes the training.
#pragma once
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "config/run_config.hpp"
#include "gain_params.hpp"
#include "train/trainer.hpp"

namespace hinf {

/// The selection so far: the kept checkpoint (DIR/best.h5) and the lowest-scoring one, each with its score, step
/// (-1: none yet) and per-run scores (the same validation noise at every step, so runs pair). Under
/// training.select_rule = "lowest" they are the same checkpoint.
struct Selection {
    double score = std::numeric_limits<double>::infinity();
    std::int64_t step = -1;
    std::vector<double> run_scores;
    double lowest_score = std::numeric_limits<double>::infinity();
    std::int64_t lowest_step = -1;
    std::vector<double> lowest_run_scores;  // empty after resuming a best.h5 written before they were kept
};

/// The mean of the run-by-run differences a[r] - b[r] and its standard error (sample standard deviation / sqrt(R)).
/// Both NaN unless a and b have the same size R >= 2 and every entry is finite.
struct PairedDifference {
    double mean = std::numeric_limits<double>::quiet_NaN();
    double se = std::numeric_limits<double>::quiet_NaN();
};
PairedDifference paired_difference(const std::vector<double>& a, const std::vector<double>& b);
/// The selection rule: a validation scoring `score` (+inf: a run diverged) is kept when it is the lowest so far, or,
/// under rule "one_se", when its paired excess over the lowest so far is at most its standard error (d.mean <= d.se;
/// NaN keeps nothing).
bool select_keeps(const std::string& rule, double score, bool lowest, const PairedDifference& d);

/// Starts the selection of a run in `dir` when cfg.select_every > 0 and the run is one process (the whole job, or
/// its group of one in a sweep; null otherwise):
/// a fresh run removes an earlier run's best.h5, select.csv and alternative/ (choose_held_start), a resumed one
/// continues from its best.h5. Chains the validation after opt.on_step (the caller's progress callback, if any). A
/// fresh run also gets opt.start_diverged: the check of a Riccati start on the same validation runs (DIR/start/).
std::shared_ptr<Selection> selection_begin(const RunConfig& cfg, const std::string& dir, bool fresh, TrainOptions& opt);
/// The one summary line of a selection ("select: best validated checkpoint at step ...").
std::string selection_line(const RunConfig& cfg, const Selection& best, const std::string& dir);

/// The runs in dir and alt change places (a second run kept, below): the entries a training writes into its directory
/// (checkpoints, trajectory, the selection and the start check: kRunEntries in acceptance.cpp) move, each one that
/// exists, and nothing else does -- not the user's own files there (a log redirected into DIR), not DIR's lock, which
/// this process holds, and not DIR/acceptance, which the kept run's check replaces. Journalled (io/run_swap.hpp): an
/// exchange a kill interrupts is finished by the next lock of DIR.
void swap_runs(const std::string& dir, const std::string& alt);

/// A Riccati start held at once (docs/method.md section 16.7, "Held at once: both storages trained"): where the game's
/// Riccati equation falls to the storage's floor before its first knot, the knots start flat, and on some systems a
/// constant storage does far better (on others far worse). So after a run of such a config that trained (fresh, or
/// resumed: it ends as the run uninterrupted) to t_final with a kept best checkpoint, on one process, and whose config
/// names none of network.storage_knots,
/// network.storage_init and network.knot_ratio, this trains the same config with network.storage_knots = 0 in
/// DIR/alternative (with its own selection) and keeps the run whose best checkpoint validated lower in DIR; the other
/// run's files go to DIR/alternative. cfg, s and best then describe the kept run (true). Prints its notes; does
/// nothing (false) elsewhere. An interrupted second run keeps the first and sets s->status to its status
/// (128 + signal).
bool choose_held_start(RunConfig* cfg, TrainSummary* s, std::shared_ptr<Selection>* best, const std::string& dir,
                       bool quiet);

/// No validated checkpoint (docs/method.md section 16.7): where a fresh run of a `gain` config at the default level
/// (1.25 rho*) whose [online] noise_std and disturbance_std are plain numbers reached t_final on one process and its
/// selection kept no checkpoint (every validation diverged), this trains the game in units of each channel's noise
/// (game_in_noise_units, at that game's 1.25 rho*) in DIR/alternative and, if a checkpoint of it validates, keeps it
/// in DIR and the first run in DIR/alternative; cfg, s and best then describe the kept run (true). Prints its notes;
/// does nothing (false) elsewhere. An interrupted second run keeps the first and sets s->status (128 + signal).
bool choose_game_in_noise_units(RunConfig* cfg, TrainSummary* s, std::shared_ptr<Selection>* best,
                                const std::string& dir, bool quiet);

/// The acceptance check's outcome.
struct AcceptanceOutcome {
    bool ran = false;   // it ran (the run reached t_final on one process, training.acceptance_runs > 0)
    bool pass = false;  // no run diverged, attenuation ratio <= rho, worst ratio found <= rho without divergence, and
                        // the small-signal worst ratio <= rho (docs/compare.md "The linear start")
    std::string file;   // the checkpoint judged: DIR/best.h5 where a selection kept one, else DIR/checkpoint.h5
    std::string line;   // its one summary line ("acceptance (5 measured runs, ...): PASS|FAIL; files: ...")
    std::string advice; // after a FAIL: what to try, one line ("acceptance: next: ..."); empty after a PASS
    // after a PASS whose settled error is above kBehindEkf times the EKF's on the same runs (variant gain): the level
    // to try for a lower mean error, one line ("acceptance: note: ..."); empty otherwise
    std::string note;
    // where the config names no settle_time and the EKF's error is still falling after the default one: that
    // window's figures hold its transient (compare.hpp settle_note), one line ("acceptance: note: ..."); else empty
    std::string settle_note;
    // after a PASS whose worst-case search ran: the check's short search found no ratio above rho, which is not a
    // proof; the full search's command, one line ("acceptance: note: ..."); empty otherwise
    std::string search_note;
    double rmse_position = std::numeric_limits<double>::quiet_NaN();  // the Monte Carlo's position RMSE
    // the Monte Carlo's attenuation ratio the verdict judges (less V(x~(0)) where V is defined)
    double attenuation_ratio = std::numeric_limits<double>::quiet_NaN();
    // the DNN filter's and the EKF's on the same runs after settle_time (the whole run where that is empty; the DNN
    // filter's is NaN when a run diverged): the mean error the verdict, which judges rho, does not
    double rmse_position_settled = std::numeric_limits<double>::quiet_NaN();
    double rmse_position_settled_ekf = std::numeric_limits<double>::quiet_NaN();
    // the same runs' error over all states weighted by the game's Q, sqrt(sum_j Q_jj (mean_j^2 + std_j^2)) (the
    // selection's score, as an RMS), the DNN filter's (NaN when a run diverged) and the EKF's
    double rms_q_settled = std::numeric_limits<double>::quiet_NaN();
    double rms_q_settled_ekf = std::numeric_limits<double>::quiet_NaN();
    double worst_ratio = std::numeric_limits<double>::quiet_NaN();    // the search's largest ratio (NaN: none ran)
    // the small-signal worst ratio (docs/compare.md "The linear start"; NaN: no search ran, or not had)
    double worst_small_signal = std::numeric_limits<double>::quiet_NaN();
    bool worst_diverged = false;  // the filter diverged under the search's worst signals
    // the EKF's two figures from the same search (NaN: no search ran, or not had)
    double worst_ratio_ekf = std::numeric_limits<double>::quiet_NaN();
    double worst_small_signal_ekf = std::numeric_limits<double>::quiet_NaN();
    // where best.h5 was an earlier checkpoint than the last and FAILed: what the same check found on the last one,
    // kept as best.h5 where it PASSed (acceptance_after), one line ("acceptance: note: ..."); empty otherwise
    std::string selection_note;
};

/// Every `from` in a's notes and advice (the commands they name) replaced by `to`: after the last checkpoint was
/// judged and kept as best.h5, the commands name best.h5 (acceptance_after).
void rename_in_notes(AcceptanceOutcome& a, const std::string& from, const std::string& to);

/// The settled error, over the EKF's on the acceptance runs (the larger of the position and the all-state Q-weighted
/// ratio), above which a PASS gets AcceptanceOutcome::note
inline constexpr double kBehindEkf = 1.25;
/// The settled error, over the EKF's on the acceptance runs, above which the advice after a FAIL, and the note after
/// a PASS, say to use the EKF or UKF until a training does better (a coordinated turn of one's own settled 9.7-59x
/// behind it, docs/byos.md section 4; Lorenz-96 PASSed at 4 rho* 7x behind it, docs/method.md section 16.7); beyond
/// it, a run with knots also trains a constant storage (choose_storage_far_behind)
inline constexpr double kFarBehindEkf = 2.0;
/// Between this ratio and kFarBehindEkf on the check's runs, choose_storage_far_behind decides on
/// kFarBehindRecheckRuns runs (the check's among them) rather than on the check's few
inline constexpr double kFarBehindRecheck = 1.5;
inline constexpr std::int64_t kFarBehindRecheckRuns = 25;
/// That note: a higher level, a weaker promise, lets the gain trade worst case for mean error (docs/method.md
/// section 16.12, "Kept, and behind the EKF"), and beyond kFarBehindEkf the EKF or UKF is the filter; `position`
/// and `all_q` the settled position RMSE and the all-state Q-weighted RMS error over the EKF's, the larger said first;
/// `furthest` the states furthest behind ("om 2.8x, th 2.7x"; "" says none). Empty where rho* is not known (the
/// linearised game's level not bracketed).
std::string acceptance_behind_note(const RunConfig& cfg, const std::string& path, double position, double all_q,
                                   const std::string& furthest = "");
/// What the acceptance's worst-case search found, for the advice after a FAIL.
struct AcceptanceSearch {
    bool ran = false;        // a search ran (training.acceptance_worst_evals > 0 and the run long enough)
    double ratio = std::numeric_limits<double>::quiet_NaN();  // the largest attenuation ratio found (small signals too)
    bool small_signal = false;  // that ratio is the small-signal one (docs/compare.md "The linear start")
    bool diverged = false;   // the filter diverged under the worst signals found
    std::int64_t nominal_diverged = 0, nominal_runs = 0;  // the check's own runs ([online] noise) that diverged, of all
    // the DNN filter's settled error over the EKF's on those runs, the larger of the position and the all-state
    // Q-weighted ratio (NaN: a run diverged, or no EKF figure)
    double behind_ekf = std::numeric_limits<double>::quiet_NaN();
    // the EKF's worst figure on the same search, the larger of its ratio at the budget and for small signals (as
    // `ratio` is the DNN filter's; NaN: no search, or none had)
    double ekf = std::numeric_limits<double>::quiet_NaN();
    // where the true state went under the DNN filter's worst signals, if beyond the region training's estimates
    // covered (worst_outside_training): "vy reached 88.5 where training's estimates spanned [-2.6, 2.5]"; "" if not
    std::string outside;
};
/// After a FAIL: what to try, one line "acceptance: next: ...", from the level against rho* (hinf rho), the run's
/// Adam updates, and what the search found (docs/byos.md section 4); `path` is the judged checkpoint. Where the level
/// was not kept but the filter's worst figure is at least kRobustAgainstEkf times below the EKF's, with neither a
/// divergence nor a settled error beyond kFarBehindEkf times the EKF's, the line says so too.
std::string acceptance_advice(const RunConfig& cfg, const std::string& path, const AcceptanceSearch& search);
/// The factor below the EKF's worst figure at which the advice calls the filter the more robust one. Four, because
/// the check's search is short and can under-read a filter's worst case: on examples/systems/brusselator.toml it found
/// 4.17 and the full search 11.17 (2.7 times; docs/method.md section 16.12); on the Moore-Greitzer compressor of
/// docs/gain.md the check read 22.3 against the EKF's 108.6 (4.9 times lower) and the full search 15.5 against 251.7.
inline constexpr double kRobustAgainstEkf = 4.0;

/// The level a trained filter keeps, searched as `hinf worst` searches with its defaults (WorstOptions{}: random,
/// scenario and cross starts, 200 evaluations a restart, the nominal draws' energy): the checkpoint `network`'s DNN
/// filter (`measured`) beside the EKF and the UKF told the nominal statistics, from x^(0) = x(0); written to
/// out_dir/worst.h5. `hinf sweep --worst` runs it for each value: the acceptance's short search is a lower bound too
/// weak to tell levels a few per cent apart (docs/method.md section 16.7b, "Which level the trained filter keeps").
struct LevelSearch {
    // the largest attenuation ratio found for each filter, at the budget or for small signals (the linear start)
    double dnn = std::numeric_limits<double>::quiet_NaN();
    double ekf = std::numeric_limits<double>::quiet_NaN();
    double ukf = std::numeric_limits<double>::quiet_NaN();
    bool diverged = false;  // the DNN filter diverged under its own worst signals
    double wall_seconds = 0;
    std::string skipped;  // why no search ran, as the acceptance's ("" when it ran; the ratios then NaN)
};
LevelSearch level_search(const RunConfig& cfg, const std::string& network, const std::string& out_dir, bool quiet);

/// The acceptance check of a run in `dir` that stopped with `s`, when it reached t_final (a resumed run: and
/// trained at least one step), on one process (or a sweep's group of one), with cfg.acceptance_runs > 0; its
/// verdict and figures are written into the judged checkpoint's root attributes, its runs into DIR/acceptance/.
/// Where a selection kept an earlier checkpoint than the last as best.h5 and it FAILs, the last checkpoint gets the
/// same check (DIR/acceptance/last/); where that PASSes it becomes best.h5 (root attribute select_kept_by =
/// "acceptance"; `best` updated), the validation's pick moves to DIR/best_average.h5, and the last's outcome is
/// returned; either way selection_note says what the second check found (docs/method.md section 16.9).
AcceptanceOutcome acceptance_after(const RunConfig& cfg, const std::string& dir, const TrainSummary& s,
                                   Selection* best, bool resumed, bool quiet);

/// Far behind the EKF (docs/method.md section 16.7, "Far behind the EKF: a constant storage tried"): where the
/// acceptance check `a` of a `gain` run with a time-varying storage (network.storage_knots > 0) found it settled above
/// kFarBehindEkf times the EKF's error, or above kFarBehindRecheck where its worst case found is above the EKF's too
/// (worst_above_ekf: "Behind on both counts") (between kFarBehindRecheck and kFarBehindEkf: on kFarBehindRecheckRuns
/// runs),
/// the run trained (fresh or resumed) to t_final with a kept best checkpoint on one process, its
/// config names none of network.storage_knots, network.storage_init and network.knot_ratio, and its start was not
/// held at once (choose_held_start trained both there), this trains the same config with network.storage_knots = 0
/// in DIR/alternative and keeps the run whose best checkpoint validated lower in DIR, as choose_held_start does.
/// Where the run's knots started on a Riccati solution held at the floor after the first knot
/// (riccati_start_held_later; "Far behind the EKF, held later: flat knots tried"), flat knots are trained and chosen
/// first, then the constant storage against the run kept (DIR/alternative: the other run of the last choice).
/// true: another storage is kept, cfg, s and best describe it, and its acceptance check is yet to run (the
/// caller's `a` is the first run's). Prints its notes; does nothing (false) elsewhere. An interrupted second run keeps
/// the first and sets s->status (128 + signal).
bool choose_storage_far_behind(RunConfig* cfg, TrainSummary* s, std::shared_ptr<Selection>* best,
                               const std::string& dir, bool quiet, const AcceptanceOutcome& a);

/// Whether the check's worst-case search found the DNN filter's worst case above the EKF's (each the larger of its
/// figure at the budget and for small signals; a DNN filter diverged under its worst signals is above any); false
/// where no search ran.
bool worst_above_ekf(const AcceptanceOutcome& a);
/// After choose_storage_far_behind kept another storage: the line that sets the worst case found for the kept run
/// (`kept`, its own check) beside the replaced run's (`replaced`, the first check; the same search settings), "" where
/// either search did not run. Where the kept run's is higher, it says the exchange traded the worst case for the
/// validation's mean error and how to search both (DIR/best.h5, DIR/alternative/best.h5).
std::string storage_exchange_note(const AcceptanceOutcome& replaced, const AcceptanceOutcome& kept,
                                  const std::string& dir);

/// The settled error over the EKF's above which choose_storage_far_behind trains other storages for a run whose check
/// is `a`: kFarBehindRecheck where worst_above_ekf(a), else kFarBehindEkf.
double far_behind_line(const AcceptanceOutcome& a);

}  // namespace hinf
