// Everything a training or on-line run reads from its TOML config, checked once before any work.
// Keys, defaults and units: docs/formats.md. Not the system's own keys ([system]: models/registry.cpp).
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "hinf/config.hpp"
#include "models/system.hpp"

namespace hinf {

/// What every phase reads: the system, the game ([filter]) and the time grid.
struct ProblemConfig {
    std::shared_ptr<System> system;
    int n = 0, nv = 0, m = 0;

    // [filter]
    std::string type = "hinf";            // "hinf" (seed 000) or "h2hinf" (seed 001: two coupled HJIEs)
    std::string variant = "gain";  // "gain" (K(x^), docs/method.md §16; default where it applies), "dissipative" or "paper"
    double rho = 0.03;                     // seed 000's rho = seed 001's r^2
    bool q_auto = false;                   // an expr system naming no Q: Q = I (written into the effective config)
    bool rho_auto = false;                 // an expr system naming no rho: rho = 1.25 rho_bound (config/game_level.hpp)
    double rho_bound = 0;                  // rho*, the linearised game's smallest level (set where rho_auto)
    std::string rho_unset;                 // rho_auto with no level bracketed (rho = 0): why; train and the GLF refuse
    std::vector<double> Q;                 // n x n
    std::vector<double> x0, xhat0;         // n
    double dt = 0.01, t_final = 70.0;
    /// [online] noise_std / disturbance_std given as lists, or noise_cov / disturbance_cov: `system` is seen in units
    /// of its noise (models/weighted_system.hpp), y~ = W y and v = U v~ with W = output_weight [m x m] and
    /// U = disturbance_scale [nv x nv], row-major and lower triangular: W = L_R^-1 and U = L_V for the covariances
    /// R = L_R L_R' and V = L_V L_V' (diagonal for lists: W = diag(1 / sn_j), U = diag(sv_k)); empty: none.
    std::vector<double> output_weight, disturbance_scale;

    /// The horizon of a run asked to stop at `until`: min(until, t_final); until < 0 means t_final.
    double final_time(double until = -1) const { return until >= 0 && until < t_final ? until : t_final; }
    /// The one place times become steps: llround(final_time(until) / dt).
    std::int64_t steps_until(double until = -1) const;
    /// t_k = k dt, the time of step k.
    double time_of(std::int64_t step) const { return double(step) * dt; }
};

/// What only the offline phase (train, resume, bench) reads: the network, Adam, sampling, the objective.
struct TrainingConfig {
    // [network]
    std::vector<int> hidden = {256, 128, 32};
    double slope_positive = 1.0, slope_negative = 0.01;
    std::string precision = "float";
    double input_scale = 0.0;   // 0: auto
    double output_scale = 0.0;  // 0: auto
    std::string storage_scaling = "output";  // variant gain with S(t): "output" (per state, from H(x^0)) or "mean" (one scale, before 2026-11-25)
    std::string storage_init = "riccati";  // variant gain with S(t): the knots start on the game's Riccati solution along the nominal trajectory ("riccati", §16.7) or at S(0) ("flat", before 2026-11-25)
    std::string gain_structure = "components";  // variant gain: K_aj = 0 where state a and output j are in different components of the system's dependency graph ("components", §16.17) or every entry learned ("full", before 2026-11-28)
    std::string gain_head = "direct";  // variant gain on a discrete-time system: K = rate D o diag(dy)^-1 ("direct") or F P H'(H P H' + diag(dy)^2)^-1 with a learned P(x^) ("kalman", §16.16)
    std::int64_t storage_knots = 0;  // variant gain: 0 = constant S; J > 0 = S(t) on J + 1 knots (§16.7); default 32 (gain, continuous), else 0
    double knot_ratio = 1.0;  // variant gain with S(t): the last knot interval over the first (1: evenly spaced; §16.7 "Graded knots")
    double eps = 0.0;  // 0: auto from max_step_correction
    std::string angle_inputs = "periodic";  // variant gain: the network sees an angle state ([system] angle_states) as (cos, sin) ("periodic", §16.19) or standardised as any state ("raw", before 2026-12-07)
    double input_box = 0.005;  // variant gain: the filter holds the network's input inside the box of all but this share of the training estimates on each side of each state (0: not held, §16.10)
    int chunk = 100;
    std::string gemm = "auto";  // GEMM kernels: "auto" (own where built, else openblas), "own", "openblas", "eigen"

    // [training]
    std::int64_t samples = 2000, batch = 800, adam_steps = 30;
    double learning_rate = 1e-3, beta1 = 0.9, beta2 = 0.999, tau = 1e-7;
    bool reset_adam = true;  // training.reset_adam_each_step: default true, false for variant gain (method.md 16.11)
    std::uint64_t seed = 1;
    std::int64_t checkpoint_every = 100;
    double loss_limit = 1e30;
    std::string on_divergence = "stop";  // "stop" (exit 4) or "rollback" (to the last checkpoint, smaller rate)
    double rollback_factor = 0.5;        // learning rate multiplier per roll-back
    std::int64_t max_rollbacks = 3;      // then stop as with "stop"
    std::int64_t acceptance_runs = 5;    // validation Monte Carlo at the end of `hinf train` (0: none)
    bool require_acceptance = false;     // exit 5 when the acceptance check fails
    std::int64_t select_every = 0;       // keep the best validated checkpoint as DIR/best.h5 every this many steps (0: off)
    std::int64_t select_runs = 5;        // its validation Monte Carlo's runs
    std::string select_rule = "one_se";  // "one_se": the latest checkpoint within one paired standard error of the
                                         // lowest score; "lowest": the lowest score (docs/method.md section 16.9)
    std::int64_t acceptance_worst_evals = 600;  // the acceptance's worst-case search: evaluations per filter (0: none)

    // [sampling]
    double local_fraction = 0.5, local_spread = 0.1, radius_decades = 4.0;
    std::vector<double> error_floor;  // n
    // [sampling] state_bounds: the region where the model is meant to hold, [lo, hi] per state (-inf/inf: open);
    // variant gain holds its training samples' x and x^ inside it (method.md 16.3). Empty: none
    std::vector<double> state_lo, state_hi;
    std::int64_t errors_per_estimate = 1;  // variant gain: errors x~ drawn around each estimate x^ (section 16.3)
    std::int64_t trajectories = 16;   // variant gain: simulated truth runs the estimates are sampled along

    // [objective] (dissipative variant)
    double margin = 0.02, h2_weight = 0.1, disturbance_intensity = 4.0, noise_intensity = 4.0;
    double horizon = 0.0;               // 0: t_final
    double initial_weight = 0.0;        // variant gain: weight of V(x~(0))/T in its H2 objective
    double max_step_correction = 0.5;   // kappa: dt * |k dC| <= kappa |x~| (sets eps when eps = 0)
    std::string step_cap = "error_scale";  // gain: the cap's norms, |.|_D^-2 ("error_scale") or |.|_S ("storage")
};

/// What only the on-line phase (operate, compare, filter) reads: the simulated noise and the Monte Carlo.
struct OnlineConfig {
    // [online]
    std::string mode = "oracle";
    double disturbance_std = 20.0, noise_std = 20.0;
    std::int64_t runs = 1;
    std::uint64_t online_seed = 7;
    double settle_time = 5.0;  // error statistics are also reported over t >= settle_time [s]
    // on-line retraining of the `gain` variant (issue 14 item 2, docs/method.md section 16.6; hinf operate only)
    bool retrain = false;
    double retrain_delta = 0.05;             // delta: retrain when max_j H_j/S_j over the check's errors > delta
    std::int64_t retrain_steps = 5;          // Adam steps per trigger
    std::int64_t retrain_samples = 64;       // errors drawn around the current x^ per trigger (one full batch)
    double retrain_learning_rate = 0;        // 0: the training's final rate (from the checkpoint)

    // [baseline]: what EKF, UKF and PF are told (their model) and how they are tuned; defaults: the truth
    std::shared_ptr<System> told_system;        // the filters' system ([baseline] parameters), else the true one
    double told_disturbance_std = -1, told_noise_std = -1;  // resolved to [online]'s when not given
    std::vector<double> told_disturbance_weight, told_noise_weight;  // per input / output factors (FilterModel)
    std::vector<double> told_disturbance_chol, told_noise_chol;      // correlated: Cholesky factors (FilterModel)
    std::vector<double> initial_std;            // [n] P0 = diag(initial_std^2); empty: diag((x0 - x^0)^2)
    double ukf_alpha = 1.0, ukf_beta = 2.0, ukf_kappa = 0.0;
    std::string pf_resampling = "systematic";   // "systematic" or "stratified"
    double pf_ess_fraction = 0.5;               // resample when ESS < fraction x particles (1: every step)
};

/// One config file, checked once: the three parts above plus the effective text. A function that needs only
/// one part takes that part.
struct RunConfig : ProblemConfig, TrainingConfig, OnlineConfig {
    ConfigDoc doc;  // the effective config (with --set applied)
    // the keys of doc that hinf set, not the user: the default level and Q of a system of one's own ("filter.rho",
    // "filter.Q", method.md 16.12), the start check's flat knots ("network.storage_init", "objective.margin", 16.7, "A
    // start that diverges"); a run's files carry them in a "# hinf chose:" line (config_record)
    std::vector<std::string> chosen;

    /// Resolved scales (auto values filled from x0, xhat0, rho).
    double resolved_input_scale() const;
    double resolved_output_scale() const;
    double resolved_eps() const;
    double resolved_horizon() const;
};

/// Between the user's units and the model's (ProblemConfig::output_weight, disturbance_scale), in place, for
/// `rows` rows of m outputs (y) or nv inputs (v, which only comes in: the library's Config::advance); no-ops where
/// no list or covariance was given. A NaN (a missing measurement) stays NaN (with a full W it
/// spreads to the later outputs of its row).
void outputs_to_model(const ProblemConfig& c, double* y, std::int64_t rows);
void outputs_to_user(const ProblemConfig& c, double* y, std::int64_t rows);
void disturbances_to_model(const ProblemConfig& c, double* v, std::int64_t rows);

/// Whether two configs (of two checkpoints) describe one trained-on model: the same [system] table and the same
/// noise weights. What an ensemble's members must share (compare --ensemble, export --ensemble; method.md 16.15).
bool same_trained_model(const RunConfig& a, const RunConfig& b);

/// Whether c's game weighs the disturbance and the noise in the config's own units: [online] noise_std and
/// disturbance_std plain numbers, no covariance (method.md 16.13); else each channel is in units of its own noise.
bool game_in_config_units(const RunConfig& c);
/// c's plain noise_std as a list of one entry per output, "[s, s]" with `digits` significant digits: the value of
/// online.noise_std that puts c's game in units of each channel's noise (game_in_noise_units, the acceptance advice).
std::string noise_std_as_list(const RunConfig& c, int digits);

/// The config of c with the game in units of each channel's noise (method.md 16.13): c's plain [online] noise_std given
/// as a list of one entry per output (its plain disturbance_std then weighs the inputs alike), and, where c's level was
/// the default 1.25 rho* (rho_auto), no [filter] rho, so that loading it finds rho* of that game. For a config whose
/// noise_std and disturbance_std are plain numbers and noise_std > 0 (method.md 16.7, "No validated checkpoint").
ConfigDoc game_in_noise_units(const RunConfig& c);

/// The text a run's files carry for c: its TOML, then, where hinf set some of its keys (c.chosen), the line
/// "# hinf chose: KEY KEY ..." (a TOML comment: the text loads as the config the run trained with).
std::string config_record(const RunConfig& c);
/// The keys a config text's "# hinf chose:" line names; none where it has no such line.
std::vector<std::string> chosen_keys(const std::string& text);
/// c as the user gave it: without the keys hinf chose (c.chosen), loaded again -- but for the level and Q, which stay
/// as the run trained with them, read as hinf's defaults (rho_auto, rho_bound = rho / 1.25, q_auto). What a run
/// resumed to t_final makes its choices from, as the same run uninterrupted does from the config it was given
/// (method.md 16.7).
RunConfig config_as_given(const RunConfig& c);
/// Adds to derived->chosen the keys hinf chose for `from` that derived (a config made from from's effective text, one
/// key changed: another storage, another game) holds with the same value: they stay hinf's choice in its record.
void inherit_chosen(RunConfig* derived, const RunConfig& from);

/// Parses and validates; throws hinf::Error naming the file, the key and the fix. need_level = false: a system of
/// one's own that names no [filter] rho keeps rho = 0 (rho_unset says why) instead of computing rho* (seconds for
/// a large system: docs/method.md section 16.12), for commands that design nothing at a level (compare and filter
/// without glf). need_run_span = false: a table of known inputs ([system] inputs) need not cover [0, t_final], for
/// `hinf filter`, which runs over a record's times and checks those (recorded_check_sampling).
RunConfig load_run_config(ConfigDoc doc, bool need_level = true, bool need_run_span = true);

/// [system] inputs := the table of known inputs given here (names [q], times t [rows], values [rows x q] row-major), in
/// the place of the config's own, as a file's is put there when the config is read: `hinf filter` on a record that has
/// the inputs beside the outputs. For kind = "expr"; the names must be the config's inputs (any order); the times must
/// increase strictly and every value be finite; any number of rows (a table file holds at most 100000: it is copied into
/// every checkpoint a training writes, where a record's inputs go into its one result file, whose size the record's
/// length sets anyway). Throws naming `source` (the record) and the fix.
void set_known_inputs(ConfigDoc& doc, const std::vector<std::string>& names, const std::vector<double>& t,
                      const std::vector<double>& values, const std::string& source);

/// A table of known inputs ([system] inputs) must cover the run, [0, t_final], where the run is simulated (training,
/// compare, operate): throws naming the table's span and the fix otherwise; a system without a table spans all time.
void check_inputs_cover_run(const ConfigDoc& doc, const System& sys, double dt, double t_final);

/// v as printf's %g, for messages ("0.9", "1e+12").
std::string format_g(double v);
/// [filter] variant when the config names none: "gain" for an H-infinity filter of at most kern::kGainMaxDim states,
/// outputs and disturbances, else "dissipative" (checkpoints written before this default read as they were trained)
std::string default_variant(const std::string& type, int n, int m, int nv);

/// Mean and standard deviation per state of the noise-free trajectory from x0 over [0, t_final] (steps_until() + 1
/// points, the one step system_advance), or over its first max_steps steps when that is fewer: where the estimates
/// will be (the gain variant's input standardisation) and how far a state moves (the default error floor).
void nominal_moments(const RunConfig& c, std::vector<double>* mean, std::vector<double>* sd, std::int64_t max_steps = -1);

/// The default sampling.error_floor of a system of one's own (docs/formats.md): a tenth of the initial error per
/// component; where that is zero, a tenth of the state's standard deviation along the noise-free trajectory (its
/// first 10^4 steps at most), or a
/// thousandth of its size where that is zero too (or not finite). `before`: the rule of checkpoints written before
/// 2026-11-27, a thousandth of the size wherever the initial error is zero. Missiles: 20 per state.
std::vector<double> error_floor_default(const RunConfig& c, bool before = false);

/// A short stable hash of the config text (FNV-1a 64, hex), stored in checkpoints.
std::string config_hash(const std::string& text);

}  // namespace hinf
