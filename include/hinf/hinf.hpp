// The public library facade: what a program that links hinf::hinf (find_package(hinf)) or the Python module
// calls. Load a config and a trained network, build a filter by name, step it or run it over a record, train.
// Not the command line (src/cli) and none of the internals (src/): this header includes only the standard
// library and hinf/error.hpp. docs/library.md shows it in use.
#pragma once
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "hinf/error.hpp"

/// @file
/// Errors: every function here reports bad input (a missing or malformed file, a config key out of range, a
/// wrong-sized array, an unknown filter name, a network trained for another system) by throwing hinf::Error
/// (hinf/error.hpp), a std::runtime_error whose what() is one line "<what is wrong> (<how to fix>) [file:line]",
/// the same line the `hinf` program prints. Nothing here exits the process or prints to stdout.
///
/// Arrays are row-major: a state is n doubles, a record of K measurements is K x m, a covariance n x n.

namespace hinf {

/// The library's version, "0.1.0".
std::string version();

/// A checked run config (the TOML file `hinf train` reads; keys: docs/formats.md).
class Config {
public:
    /// Reads and checks path; each override is "section.key=value" (as `hinf ... --set`).
    static Config load(const std::string& path, const std::vector<std::string>& overrides = {});
    /// The same from TOML text; `name` stands for the file in error messages.
    static Config from_text(const std::string& toml, const std::string& name = "<text>",
                            const std::vector<std::string>& overrides = {});

    int states() const;        ///< n
    int outputs() const;       ///< m
    int disturbances() const;  ///< nv
    double dt() const;         ///< [filter] dt [s]
    double t_final() const;    ///< [filter] t_final [s]
    /// [filter] rho, the attenuation level it trains at (a system of one's own naming none: 1.25 rho_bound())
    double rho() const;
    /// rho*, the smallest level any filter can promise for the system linearised along its noise-free trajectory
    /// (docs/method.md 16.12; computed on each call, as `hinf rho`); 0 where no level brackets
    double rho_bound() const;
    /// rho*_on >= rho*, the smallest level where the run goes on past t_final, which a gain of the estimate alone
    /// needs (docs/method.md 16.12, "Where the run ends"; computed on each call, as `hinf rho`); 0 where none brackets
    double rho_run_on() const;
    /// A discrete-time `gain` config: the least violation any constant storage S leaves of the one-step inequality
    /// along the errors the outputs do not see, over the Q term's size there (docs/method.md 16.8, "Errors the
    /// outputs do not see"; computed on each call, as `hinf rho`). Above 1e-6: no constant storage exists, training
    /// cannot satisfy its inequality, and the DNN filter has no certificate of its level; <= 0: one exists. NaN:
    /// nothing to check (continuous time, another variant, every error seen within a step) or no verdict from the
    /// solver.
    double constant_storage_violation() const;
    /// Per state: the share of the open-loop predictor's error variance that the EKF's covariance equation keeps over
    /// the run's second half along the noise-free run, told every measurement with a thousandth of its noise
    /// (docs/method.md 16.18; computed on each call, as `hinf rho`). From 0.9 on, the outputs tell next to nothing
    /// about that state and no filter does much better there than the model's own prediction; NaN: nothing to tell
    /// (no error there without the outputs either); empty where the covariance equation left the finite numbers.
    std::vector<double> unseen_share() const;
    std::string system() const;                    ///< "missile", "maneuvering_missile" or "expr"
    std::vector<std::string> state_names() const;  ///< n names
    std::vector<std::string> state_units() const;  ///< n units
    /// The known inputs' names ([system] inputs, docs/byos.md "Known inputs"), in the table's order; empty without.
    std::vector<std::string> input_names() const;
    /// u(t) [inputs]: the table's values at time t, held or interpolated as f, g and h read them.
    std::vector<double> inputs_at(double t) const;
    /// This config with the known inputs of another run in the place of its table (a record's, as `hinf filter` takes a
    /// log's input columns): t [R] strictly increasing, values [R x inputs] in input_names()'s order, R >= 2, finite.
    /// The table need not cover [0, t_final]: Filter::run checks that it covers the record it runs over, and train
    /// refuses it unless it covers [0, t_final].
    Config with_inputs(const std::vector<double>& t, const std::vector<double>& values) const;
    std::vector<double> initial_state() const;     ///< [filter] x0 [n]
    std::vector<double> initial_estimate() const;  ///< [filter] xhat0 [n]
    std::string text() const;                      ///< the effective TOML (overrides applied)

    /// y = C(x, t) [m] of the config's system, for simulating or checking a record.
    std::vector<double> measure(const std::vector<double>& x, double t) const;
    /// x + dt (A(x, t) + B(x, t) v), the one Euler step the truth and every filter take (v [nv], empty: 0).
    std::vector<double> advance(const std::vector<double>& x, const std::vector<double>& v, double t, double dt) const;

    struct Impl;
    std::shared_ptr<const Impl> impl;  ///< internal
};

/// A trained network, frozen, from a checkpoint (DIR/checkpoint.h5 of `hinf train`).
class TrainedNetwork {
public:
    static TrainedNetwork load(const std::string& checkpoint_path);
    std::string path() const;
    Config config() const;        ///< the config it was trained with (stored in the checkpoint)
    std::string variant() const;  ///< "gain", "dissipative" or "paper"
    std::string precision() const;  ///< "float" or "double"
    /// p = dV/dx~ [count x n] at x~ [count x n].
    std::vector<double> gradient(const std::vector<double>& xtilde) const;
    /// V(x~) (Gauss-Legendre quadrature of p along 0 -> x~).
    double value(const std::vector<double>& xtilde) const;
    /// Variant "gain": its gain K(x^, t) [count x n x m] (row-major n x m each) at estimates x^ [count x n].
    /// gradient() and value() are for the other variants, gain() for this one (each refuses the other in one line).
    std::vector<double> gain(const std::vector<double>& xhat, double t) const;

    struct Impl;
    std::shared_ptr<Impl> impl;  ///< internal
};

/// How a filter is built. Defaults are those of `hinf filter`.
struct FilterOptions {
    std::vector<TrainedNetwork> networks;  ///< for "dnn": one filter per network (measured mode); required for dnn
    double dt = 0;                  ///< step interval [s] for step(); 0: the config's dt (run() uses the record's)
    std::vector<double> initial_estimate;  ///< x^(t_0) [n]; empty: the config's [filter] xhat0
    /// EKF/UKF/PF: standard deviation of x^(t_0)'s error [n]; empty: the config's [baseline] initial_std, else
    /// |x0 - xhat0| of the config (0 where they agree: a known start)
    std::vector<double> initial_std;
    std::int64_t particles = 2000;  ///< pf: particle count
    double roughening = 0;          ///< pf: roughening constant K
    int glf_vertices = 8;           ///< glf: vertex count N
    /// dnn: one filter, dnn_gain_ensemble, with the mean gain of every network (two or more variant-gain networks
    /// trained on one model; docs/method.md 16.15) instead of one filter per network
    bool ensemble = false;
};

/// What a filter gave over a record of K measurements (the layout of `hinf filter`'s estimates.h5).
struct FilterTrace {
    std::string name;
    std::int64_t steps = 0;            ///< K
    int n = 0, m = 0;
    std::vector<double> xhat;          ///< [K x n]: row k estimates x(t_k) from y(t_0) .. y(t_{k-1})
    std::vector<double> covariance;    ///< [K x n x n] the filter's error covariance of row k; empty if it has none
    std::vector<double> innovation;    ///< [K x m] y_k - C(xhat_k, t_k)
    std::vector<double> xhat_final;    ///< [n] the estimate of x(t_{K-1} + dt) after the last measurement
    double diverged_at = -1;           ///< time [s] the filter diverged at (frozen after it); < 0: never
    std::vector<double> innovation_rms, innovation_mean;  ///< [m] over the steps before a divergence
    /// [K] normalised innovation squared of y_k against the covariance the filter expected for it (EKF, UKF, PF; NaN
    /// where y_k is missing); empty for filters that state none
    std::vector<double> nis;
    /// the mean of nis / m from t_0 + [online] settle_time (from t_0 on a shorter record): about 1 where the filter's
    /// model and told statistics hold for the record; NaN: none stated
    double nis_per_output = NAN;
    /// What the filter met on the record that the arrays do not say, or "" (a DNN gain filter: its estimate went far
    /// beyond the region its network was trained on, where its gain is the region's edge's)
    std::string note;
};

/// One on-line filter: dnn (a trained network, measured mode), ekf, ukf, pf, ehf, glf or open_loop. A Filter is a
/// handle: copies share one filter and its state (make another with create for an independent one).
class Filter {
public:
    /// The names create() knows: "ekf, ukf, pf, ehf, open_loop, glf, dnn".
    static std::string names();
    /// Builds the filter `name` for cfg's system. For "dnn" with several networks, one filter per network:
    /// use create_all. Throws hinf::Error for an unknown name, a dnn without a network, or a network trained
    /// for another system.
    static Filter create(const Config& cfg, const std::string& name, const FilterOptions& options = {});
    /// Every filter of a comma list ("dnn,ekf,ukf"), dnn once per network.
    static std::vector<Filter> create_all(const Config& cfg, const std::string& names,
                                          const FilterOptions& options = {});

    std::string name() const;  ///< e.g. "ekf", "dnn_dissipative_measured"
    int states() const;
    int outputs() const;
    double dt() const;  ///< the step interval step() advances by
    bool has_covariance() const;

    /// The options it was built with (networks, initial estimate, ...).
    const FilterOptions& options() const;
    /// Back to x^(t_0) (and its covariance) of the options.
    void reset();
    /// Consumes y(t_k) [m] at time t_k; afterwards estimate() is the estimate of x(t_k + dt). Returns false
    /// when the filter diverged (it then stays at its last finite estimate and ignores further steps).
    bool step(const double* y, double t);
    bool step(const std::vector<double>& y, double t);
    std::vector<double> estimate() const;    ///< [n]
    std::vector<double> covariance() const;  ///< [n x n] (ekf, ukf); empty for filters without one (dnn, pf, glf, open_loop)
    bool diverged() const;

    /// Runs a fresh copy of the filter over a record: t [K] strictly increasing and uniformly spaced, y [K x m],
    /// checked as `hinf filter` checks a file. The filter steps on the record's own interval, exactly as
    /// `hinf filter` does: the same numbers, bit for bit. Does not change this filter's state.
    FilterTrace run(const std::vector<double>& t, const std::vector<double>& y) const;
    FilterTrace run(const double* t, const double* y, std::int64_t K) const;

    struct Impl;
    std::shared_ptr<Impl> impl;  ///< internal
};

/// One time step of training, as the progress line of `hinf train` shows it.
struct TrainProgress {
    std::int64_t step = 0;       ///< time steps completed
    std::int64_t last_step = 0;  ///< where this run stops
    double t = 0;                ///< simulated time [s] reached
    double loss_first = 0, loss_last = 0;  ///< loss before and after the step's Adam steps
    double rel_residual = 0;     ///< median |HJIE residual| / scale over the samples
    double violation = 0;        ///< share of samples violating HJIE <= 0 by more than 1 % of the scale
};

/// How to train. A callback that throws stops training: the last checkpoint stays, `resume` continues it.
struct TrainSettings {
    std::string out_dir;  ///< required: DIR/trajectory.h5, DIR/checkpoint.h5
    double until = -1;    ///< stop at this simulated time [s]; < 0: the config's t_final
    bool quiet = true;    ///< no progress lines on stderr
    bool force = false;   ///< start over when out_dir already holds a checkpoint (else that is an error)
    int threads = 0;      ///< OpenMP threads; 0: OpenMP's default
    std::function<void(const TrainProgress&)> on_progress;  ///< after every time step
};

/// What a training run reached (the summary `hinf train` prints).
struct TrainReport {
    bool diverged = false;         ///< stopped on numerical trouble (the last good checkpoint is kept)
    std::int64_t first_step = 0, last_step = 0;
    double wall_seconds = 0;
    double final_loss = 0;
    double median_rel_residual = 0;
    double fraction_steps_violation_ok = 0;  ///< share of time steps with <= 1 % of samples violating HJIE <= 0
    double mean_cosine = 0;                  ///< mean cos(p, x~)
    std::string checkpoint;                  ///< DIR/checkpoint.h5 (the last network: the point to resume from)
    /// variant gain keeps its best validated checkpoint (training.select_every, docs/method.md 16.9): DIR/best.h5,
    /// the network to use, and its step ("" and -1: no selection, or none kept)
    std::string best_checkpoint;
    std::int64_t best_step = -1;
    /// the acceptance check at t_final (docs/method.md 16.5): "pass", "fail", or "" where it did not run (a run
    /// stopped before t_final, training.acceptance_runs = 0); the checkpoint it judged; its one summary line; after
    /// a "fail", what to try (the line `hinf train` prints under it, "acceptance: next: ..."; "" otherwise); after a
    /// "pass" whose settled error (position, or all states Q-weighted) is above 1.25 times the EKF's on the check's
    /// runs, the level to try for a lower mean error ("acceptance: note: ..."; "" otherwise)
    std::string acceptance, acceptance_checkpoint, acceptance_line, acceptance_advice, acceptance_note;
    /// where the config names no [online] settle_time and the EKF's error on the check's runs is still falling after
    /// the default one, so the settled figures hold its transient: the time to name ("acceptance: note: ..."; "" else)
    std::string acceptance_settle_note;
    /// where best.h5 was an earlier checkpoint than the last and failed its check: what the same check found on the
    /// last checkpoint, which becomes best.h5 (and best_step) where it passed, the earlier one kept as
    /// DIR/best_average.h5 (docs/method.md 16.9; "acceptance: note: ..."; "" otherwise)
    std::string acceptance_selection_note;
    /// outside the verdict: the check's runs again with the EKF beside the filter, each one's position RMSE after
    /// settle_time (where the config names none and the default leaves no step, after t_final / 2; the whole run where
    /// a named window is empty); NaN where the check did not run (or, the DNN
    /// filter's, where a run diverged)
    double acceptance_rmse_settled = std::numeric_limits<double>::quiet_NaN();
    double acceptance_rmse_settled_ekf = std::numeric_limits<double>::quiet_NaN();
    /// the same runs' error over all states weighted by the config's Q, sqrt(sum_j Q_jj (mean_j^2 + std_j^2)) after
    /// settle_time (the selection's score as an RMS): a directly measured position can be close to the EKF's while
    /// the unmeasured states are not
    double acceptance_rms_q_settled = std::numeric_limits<double>::quiet_NaN();
    double acceptance_rms_q_settled_ekf = std::numeric_limits<double>::quiet_NaN();
    /// variant gain with knots: the first time step after which a knot's log-diagonal lay where it no longer moves
    /// S(t), the sign of every failed training measured (the note `hinf train` prints; docs/method.md 16.7); -1: none
    std::int64_t knot_runaway_step = -1;
    int knot_runaway_knot = -1;  ///< that knot (0 .. network.storage_knots)
};

/// What `hinf export` wrote: the C99 pair of a trained DNN filter (docs/export.md).
struct ExportReport {
    std::vector<std::string> files;     ///< DIR/PREFIX.h, DIR/PREFIX.c
    long long parameters = 0;           ///< network weights and biases (all members of an ensemble)
    long long weight_bytes = 0;         ///< const data of the weights
    long long flops_per_step = 0;       ///< per filter step, besides the system's A, C, dC/dx
    int networks = 1;                   ///< an ensemble's member count
    std::string variant, precision, system;
};

/// Writes the trained filter of one checkpoint (or, ensemble = true, the mean gain of two or more `gain` networks
/// trained on one model) as dependency-free C99 into dir/prefix.h and dir/prefix.c, as `hinf export`.
ExportReport export_c99(const std::vector<std::string>& checkpoints, const std::string& dir,
                        const std::string& prefix = "hinf_filter", bool ensemble = false);

/// Trains a network for cfg (the offline phase, as `hinf train`). Where the game's Riccati equation gives the storage
/// no start (held before its first knot) and cfg names neither network.storage_knots nor storage_init, it also trains
/// a constant storage in out_dir/alternative and keeps the run that validates lower in out_dir (docs/method.md
/// section 16.7, "Held at once"). Where a `gain` run at the default level with plain [online] stds keeps no validated
/// checkpoint, it also trains the game in units of each channel's noise there and keeps it if it validates ("No
/// validated checkpoint"; its config then gives noise_std as a list, and Filter converts measurements for it). Where
/// its acceptance check finds a run with knots settled beyond twice the EKF's error, it trains a constant storage
/// too, and first flat knots where the Riccati start was held after its first knot, keeping the lowest validation
/// ("Far behind the EKF"). The report describes the kept run.
TrainReport train(const Config& cfg, const TrainSettings& settings);
/// Continues the run of a checkpoint into its directory (as `hinf resume`); settings.out_dir is ignored.
TrainReport resume(const std::string& checkpoint_path, const TrainSettings& settings);

/// What `hinf compare` runs (docs/compare.md): every filter named, on the same simulated runs of the config's system.
struct CompareSettings {
    std::string out_dir;                                ///< required: DIR/compare.h5, DIR/compare.csv
    std::string filters = "dnn,ekf,ukf,pf,open_loop";   ///< comma list of Filter::names() (`--filters`)
    std::vector<TrainedNetwork> networks;               ///< the dnn filters' networks, one filter per network and mode
    std::string modes = "oracle,measured";              ///< the dnn filters' modes, comma list (`--mode`)
    bool ensemble = false;  ///< one dnn filter with the mean gain of every network (variant gain; `--ensemble`)
    std::int64_t runs = 50;
    std::string scenario = "nominal";  ///< what the EKF, UKF and PF are told, or the noise drawn (`--scenario`)
    double until = -1;                 ///< simulate up to this time [s]; < 0: t_final
    std::int64_t particles = 2000;     ///< the particle filter's
    double roughening = 0.0;           ///< the particle filter's roughening constant (0: the plain bootstrap PF)
    int glf_vertices = 8;              ///< the global-linearization filter's vertex count
    bool quiet = true;                 ///< no progress lines on stderr
    int threads = 0;                   ///< OpenMP threads over the runs (0: OpenMP's default); the same results
};

/// One filter's row of the table `hinf compare` prints (docs/compare.md; the per-state figures are in compare.h5).
struct CompareRow {
    std::string name, mode;  ///< mode: "oracle" (reads the true state) or "measured"
    std::int64_t diverged_runs = 0;
    /// RMS of the position / velocity errors over the runs that did not diverge, the whole run and after
    /// [online] settle_time
    double rmse_position = NAN, rmse_position_settled = NAN, rmse_velocity = NAN, rmse_velocity_settled = NAN;
    double attenuation_ratio = NAN;  ///< int x~'Q x~ dt / int (v'v + n'n) dt, mean over the runs that did not diverge
    double mse_db = NAN, mse_filtered_db = NAN;  ///< 10 log10 MSE over all states: one-step prediction / filtered
    double us_per_step = NAN;                    ///< time inside the filter's step
    double nees_per_state = NAN;  ///< settled e'P^-1 e / n (about 1 for a consistent filter; NaN: it states no P)
};

/// What a comparison found.
struct CompareReport {
    std::string scenario, file;  ///< file: DIR/compare.h5
    std::int64_t runs = 0, steps = 0;
    std::int64_t truth_escaped_runs = 0;  ///< runs whose truth ran away (they count for no filter)
    bool streams_identical = true;        ///< every filter was fed the same measurements
    double wall_seconds = 0;
    std::vector<CompareRow> filters;      ///< in the order `hinf compare` prints them
};

/// Runs `hinf compare` on cfg (the same runs, the same bits, the same files).
CompareReport compare(const Config& cfg, const CompareSettings& settings);

/// What `hinf worst` searches (docs/compare.md "Worst case"): each filter's worst disturbance and noise under one
/// energy budget, from zero initial error, the EKF, UKF and PF told the nominal statistics.
struct WorstSettings {
    std::string out_dir;                               ///< required: DIR/worst.h5
    std::string filters = "dnn,ekf,ukf,pf,open_loop";  ///< comma list of Filter::names() (`--filters`)
    std::vector<TrainedNetwork> networks;              ///< the dnn filters' networks, one filter per network and mode
    std::string modes = "oracle,measured";             ///< the dnn filters' modes, comma list (`--mode`)
    bool ensemble = false;  ///< one dnn filter with the mean gain of every network (variant gain; `--ensemble`)
    double energy = NAN;    ///< the budget int (v'v + n'n) dt; NaN: the nominal draws' expected energy (`--energy`)
    double until = -1;      ///< horizon [s]; < 0: t_final
    int evals = 200;           ///< objective evaluations per restart (`--evals`)
    int random_starts = 4;     ///< random starts per filter (`--random-starts`)
    int linear_pieces = 20;    ///< the linear start's pieces a channel; 0: none (`--linear-pieces`)
    bool keep_initial_error = false;  ///< start the filters at the config's x^0 instead of x0 (`--keep-initial-error`)
    std::int64_t particles = 2000;    ///< the particle filter's
    double roughening = 0.0;          ///< the particle filter's roughening constant
    int glf_vertices = 8;             ///< the global-linearization filter's vertex count
    bool quiet = true;                ///< no progress lines on stderr
    int threads = 0;                  ///< OpenMP threads over the restarts (0: OpenMP's default); the same results
};

/// One filter's worst case found.
struct WorstRow {
    std::string name;
    double ratio = NAN;         ///< the largest attenuation ratio the search found at the budget
    double small_signal = NAN;  ///< the ratio small signals reach (the linear start; NaN: none)
    bool diverged = false;      ///< the filter diverged under its own worst signals (frozen there)
    std::string found_from;     ///< the start the worst was found from ("random:2", "linear", "cross:ekf", ...)
};

/// What a search found.
struct WorstReport {
    std::string file;         ///< DIR/worst.h5 (`hinf worst --replay` runs its signals against any filter set)
    double energy = 0;        ///< the budget searched at
    std::int64_t steps = 0;
    double wall_seconds = 0;
    std::vector<WorstRow> filters;  ///< in the order `hinf worst` prints them
};

/// Runs `hinf worst`'s search on cfg (the same starts, bits and worst.h5).
WorstReport worst(const Config& cfg, const WorstSettings& settings);

/// What a replay of saved worst signals found: every filter under every set.
struct ReplayReport {
    std::string file;                  ///< DIR/replay.h5 (layout: docs/formats.md, as `hinf worst --replay` writes it)
    std::int64_t steps = 0;            ///< the horizon the sets were found for
    bool keep_initial_error = false;   ///< how the search scored them, and so this replay
    std::vector<std::string> sets;     ///< [D] the filter each set was found for
    std::vector<double> energy;        ///< [D] each set's int (v'v + n'n) dt
    std::vector<std::string> filters;  ///< [F] the settings' filters, in `hinf worst`'s order
    std::vector<double> ratio;         ///< [D x F] row d: filter f's attenuation ratio under set d
    std::vector<bool> diverged;        ///< [D x F] the filter diverged under the set (frozen there)
};

/// `hinf worst CONFIG --replay worst_file`: the signal sets a search saved (worst.h5, or a replay.h5) run against
/// the settings' filters, scored as the search scored them (its horizon and initial error: the settings' energy,
/// until, evals, random_starts, linear_pieces and keep_initial_error are the search's and not used); the same bits
/// and DIR/replay.h5. The file must be for cfg's system (kind, [system] table, channels, dt).
ReplayReport replay_worst(const Config& cfg, const std::string& worst_file, const WorstSettings& settings);

}  // namespace hinf
