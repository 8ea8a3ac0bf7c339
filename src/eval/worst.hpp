// The worst-case search (issue 13, part 2): for each filter, the disturbance v(t) and noise n(t) of a fixed
// energy budget that maximise its attenuation ratio int x~'Qx~ dt / int (v'v + n'n) dt, found by a
// derivative-free optimiser (NLopt) over a low-dimensional parametrisation; and the replay of saved worst
// signals against any filter set. Not the argument parsing (cli/worst_cmd.cpp) nor the truth (sim/truth).
//
// Shape legend: K = steps, n = states, nv = disturbance inputs, m = outputs, C = nv + m signal channels,
// P = pieces per channel, S = sinusoids, F = filters, R = restarts, D = signal sets.
#pragma once
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/spelling.hpp"
#include "filters/filter.hpp"
#include "net/network.hpp"
#include "sim/truth.hpp"

namespace hinf {

/// The search's knobs. Defaults: docs/compare.md, "Worst case".
struct WorstOptions {
    double energy = -1;          // budget int (v'v + n'n) dt; -1: the nominal draws' expected (sv^2 nv + sn^2 m) T
    double until = -1;           // horizon (< 0: t_final)
    int pieces = 4;              // P: piecewise-constant segments per channel
    int sines = 2;               // S: sinusoids (one shared log-frequency each, a sin and a cos amplitude per channel)
    int random_starts = 4;       // starts from Philox draws (RNG_STREAM_WORST, a = start): the same for every filter
    std::vector<std::string> scenario_starts = {"nominal", "energy_pulse", "bias"};  // compare scenarios as starts
    bool game_start = true;      // a DNN filter with a network also starts from the game's v* = B'p / (2 rho), n* = -dC
    bool cross_starts = true;    // a filter whose cross-table column beats its own best searches on from those sets
    int linear_pieces = 20;      // the linear start: the small-signal worst case over signals of this many pieces a
                                 // channel (2 (nv + m) pieces runs a filter), doubled until it moves by less than 5 %;
                                 // 0: none (docs/compare.md "The linear start")
    double linear_steps = 1e7;   // ... no doubling past this many steps simulated in all for a filter
    int evals = 200;             // objective evaluations per restart
    std::string algorithm = "LN_SBPLX";  // a local derivative-free NLopt algorithm (worst_algorithms())
    bool keep_initial_error = false;     // false: every filter starts at x^0 = x0 (the pure energy gain)
    bool quiet = false;
    Spelling spelling = Spelling::program;  // how error lines name these knobs (the program's flags or the library's)
};

/// The game a DNN filter was trained for: its network gives p = dV/dx~ and rho its level (seed 000 eq. (6)).
struct WorstGame {
    const FrozenNetwork* network = nullptr;  // nullptr: the filter has no game (EKF, UKF, ...)
    double rho = 0;
};

/// One restart of one filter's search.
struct WorstRestart {
    std::string start;         // "random:3", "scenario:energy_pulse", "game"
    double start_ratio = 0;    // the ratio at the start point
    double ratio = 0;          // the best ratio this restart found
    int evals = 0;
    std::string nlopt_result;  // NLopt's return code, as text
};

/// One named pair of signals (the worst found for `source`), energy-normalised to the budget.
struct WorstSignals {
    std::string source;  // the filter they were found for
    double ratio = 0;    // that filter's ratio under them
    Signals signals;     // v [K x nv], n [K x m]
};

struct WorstFilterResult {
    std::string name;
    std::vector<WorstRestart> restarts;  // [R] in start order
    int best = 0;                        // index of the largest ratio
    WorstSignals worst;
    double linear_gain = NAN;            // the small-signal worst ratio over the linear start's signals (NaN: none)
    int linear_pieces = 0;               // ... found with this many pieces a channel (the start's, doubled)
    bool linear_converged = false;       // ... and the last doubling moved it by less than 5 % (false: not settled,
                                         // the step cap or the horizon stopped the doubling)
};

/// Every filter run on every signal set (the same signals against every filter).
struct WorstReplay {
    std::vector<std::string> sets, filters;  // [D], [F]
    std::vector<double> ratio;               // [D x F]
    std::vector<double> diverged_at;         // [D x F] (< 0: never)
    std::vector<double> signal_energy;       // [D]
    std::int64_t stride = 1;                 // err keeps every stride-th step
    std::vector<std::vector<double>> err;    // [D x F][ceil(K / stride) x n] x - x^
    std::vector<std::string> note;           // [D x F] OnlineFilter::run_note() after the replay ("": none)
};

struct WorstResult {
    double energy = 0;
    std::int64_t steps = 0;
    int parameters = 0;  // dimension of the search space (without the start's own amplitude)
    std::vector<WorstFilterResult> filters;
    WorstReplay cross;   // every worst set against every filter
    double wall_seconds = 0;
};

/// The local NLopt algorithms the search accepts, comma-separated.
std::string worst_algorithms();

/// The config the search scores under: cfg itself, or unless keep_initial_error with x^0 = x0 and, where cfg gives
/// no [baseline] initial_std, the one that keeps the P0 compare tells EKF/UKF/PF (|x0 - x^0| of cfg): the filters a
/// user runs, started at the truth (docs/compare.md, "Worst case").
RunConfig worst_config(const RunConfig& cfg, const WorstOptions& opt);

/// The budget opt.energy resolves to on cfg over `steps` steps (checks it is finite and positive).
double worst_energy(const RunConfig& cfg, const WorstOptions& opt, std::int64_t steps);

/// The attenuation ratio of filter f (a clone is stepped) under the given signals on cfg (initial estimate
/// engine_filter_start(cfg, 0)): int x~'Qx~ dt / int (v'v + n'n) dt, the sums of eval/engine.cpp.
double worst_ratio(const RunConfig& cfg, const OnlineFilter& f, const Signals& s, std::int64_t steps);

/// The search: R restarts per filter, OpenMP over (filter, restart), each a pure function of its inputs:
/// the result does not depend on the thread count; with opt.linear_pieces > 0 each filter also starts from its
/// small-signal worst case ("linear", WorstFilterResult::linear_gain); under mpirun the restarts are dealt out over the processes
/// (worst_rank_of) and the result is the same bits for any number of them. games: [F] (or empty). Ends with the replay of every
/// worst set against every filter (WorstResult::cross); with opt.cross_starts, every other filter's worst set that
/// beats a filter's own best is one more start for it ("cross:<name>"), and so is, where a filter's worst set came
/// from its linear start, its best set from the other starts ("cross:<name>:searched"); the table is replayed again,
/// for up to three rounds. Runs on worst_config(cfg, opt).
WorstResult worst_search(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                         const std::vector<WorstGame>& games, const WorstOptions& opt);

/// The DNN filters' networks of a filter set built with the checkpoints `paths` (filters/factory.hpp: a dnn filter is
/// named dnn_<variant>_<mode>), and the game each filter starts from: the network and level of a DNN filter whose
/// network gives dV/dx~ (variants dissipative, paper), the game's v* = B'p / (2 rho), n* = -dC; none for the gain
/// variant's and the other filters (searched from the other starts).
struct WorstNetworks {
    std::vector<std::unique_ptr<FrozenNetwork>> nets;  // [paths]
    std::vector<std::string> prefixes;                 // "dnn_<variant>_" of each network's filters
    std::vector<double> rhos;                          // each network's level
    std::vector<WorstGame> games;                      // [filters], for worst_search
};
WorstNetworks worst_networks(const std::vector<const OnlineFilter*>& filters, const std::vector<std::string>& paths);

/// The small-signal worst ratio of filter f on worst_config(cfg, opt) over signals of opt.linear_pieces pieces a
/// channel: the figure the linear start reports (WorstFilterResult::linear_gain; docs/compare.md "The linear start"),
/// without a search. NaN where it cannot be had (opt.linear_pieces = 0, a basis run ran away or diverged).
double worst_small_signal(const RunConfig& cfg, const OnlineFilter& f, const WorstOptions& opt);

/// The process that computes restart (or replayed set) `task` among `ranks` under mpirun.
std::int64_t worst_rank_of(std::int64_t task, int ranks);

/// Every filter on every set, through the engine (one run per set, run 0's initial estimate); under mpirun the
/// sets are split over the processes and every process ends with the whole table.
WorstReplay worst_replay(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                         const std::vector<WorstSignals>& sets, std::int64_t steps, bool quiet = true);

/// Where a `gain` network's input box (network.input_box: the box of training's estimates, docs/method.md section
/// 16.10) is known: the state whose true values along `x` [K x n] went furthest beyond it, by more than the box's own
/// width, said as "vy reached 88.5 where training's estimates spanned [-2.6, 2.5]" ("ran away" for a non-finite
/// value), and with row k at time t0 + k dt where t0 is given, when a state first went that far (BoxExcursion::text);
/// "" where none did or the network has no box.
std::string worst_outside_training(const kern::GainSpec& g, const std::vector<std::string>& names,
                                   const std::vector<double>& x, int n, double t0 = NAN, double dt = 0);
/// worst_outside_training along the true state under `s` over `steps` steps of cfg (the truth does not depend on the
/// filters: run 0's initial state, no scenario), for the note of `hinf worst` and the acceptance's advice.
std::string worst_truth_outside_training(const RunConfig& cfg, const kern::GainSpec& g, const Signals& s,
                                         std::int64_t steps);

/// worst.h5 (atomically): the search's restarts, worst signals and cross table (layout: docs/formats.md).
void worst_write(const std::string& path, const RunConfig& cfg, const WorstOptions& opt, const WorstResult& r);
/// replay.h5 (atomically): saved sets (from the file `source`) replayed against a filter set.
void worst_write_replay(const std::string& path, const RunConfig& cfg, const std::string& source,
                        const std::vector<WorstSignals>& sets, const WorstReplay& r, std::int64_t steps,
                        bool keep_initial_error);

/// The signal sets of a worst.h5; checks that the file was written for cfg's system (name, dimensions, dt,
/// horizon) and throws naming the file (as `spelling` names the option) and the difference. steps_out: the horizon
/// the file was made for; keep_initial_error_out: how the search scored (a replay scores the same way).
std::vector<WorstSignals> worst_read(const std::string& path, const RunConfig& cfg, std::int64_t* steps_out,
                                     bool* keep_initial_error_out, Spelling spelling = Spelling::program);

/// A replay of saved worst signals (`hinf worst --replay`, hinf::replay_worst).
struct WorstReplayRun {
    std::vector<WorstSignals> sets;  // the file's sets, in its order
    WorstReplay table;               // every filter under every set
    std::int64_t steps = 0;          // the horizon the sets were found for
    bool keep_initial_error = false; // how the search scored them (and so the replay)
    std::string file;                // out_dir/replay.h5
};
/// The sets of `source` (a worst.h5, or a replay.h5) against `filters`, scored as the search scored them (its
/// horizon, its initial error; opt gives quiet and spelling), written to out_dir/replay.h5 under out_dir's lock
/// (`who` names the caller in the lock's line).
WorstReplayRun worst_replay_file(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                                 const std::string& source, const std::string& out_dir, const WorstOptions& opt,
                                 const std::string& who);

}  // namespace hinf
