// The side-by-side comparison (issue 5): every filter on the same truth, the same measurement noise
// realisations and the same initial estimate, R Monte Carlo runs, confidence intervals. Not the filters
// (src/filters) and not the argument parsing (cli/compare_cmd.cpp).
#pragma once
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "filters/filter.hpp"
#include "sim/truth.hpp"

namespace hinf {

struct CompareOptions {
    std::string out_dir = "runs/out/compare";
    std::int64_t runs = 50;
    double until = -1;  // < 0: t_final
    Scenario scenario;
    bool quiet = false;
};

struct CompareFilterResult {
    std::string name, mode;  // mode: "oracle" (reads the true state) or "measured"
    std::int64_t diverged_runs = 0;
    // per state, over the non-diverged runs: error x - x^ mean and std over time within a run (full horizon
    // and t >= settle_time), averaged over runs, with 95% half-widths 1.96 sd / sqrt(runs)
    std::vector<double> mean, mean_ci, std, std_ci;
    std::vector<double> mean_settled, mean_settled_ci, std_settled, std_settled_ci;
    double rmse_position = 0, rmse_velocity = 0, rmse_position_settled = 0, rmse_velocity_settled = 0;
    double attenuation_ratio = 0, attenuation_ratio_ci = 0;  // int x~'Qx~ / int (v'v + n'n), over non-diverged runs
    // MSE over all states and steps of a run, averaged over the kept runs, and 10 log10 of it [dB] (the metric of
    // published tables, e.g. KalmanNet's); of the one-step prediction x^_{k|k-1} and of the filtered estimate
    // x^_{k|k} (NaN: the filter has none)
    double mse = 0, mse_db = 0, mse_filtered = NAN, mse_filtered_db = NAN;
    double us_per_step = 0;                                    // filter time only, per step
    std::uint64_t stream_hash = 0;                             // FNV-1a of every y this filter was fed
    // OnlineFilter::run_report() summed entry by entry over the runs whose truth did not run away, and how many of
    // them reported anything non-zero (ehf: the steps where its level failed; docs/compare.md)
    std::vector<double> report_sum;
    std::int64_t report_runs = 0;
    RunNotes notes;  // OnlineFilter::run_note() over the same runs (a gain filter: its estimate far beyond its box)
    // whether its error has settled in the settled window (settle_check below, over its Q-weighted mean square error
    // across the kept runs at t_sub)
    double settle_halves = NAN, settled_after = NAN;
    // consistency: the mean over the kept runs' settled steps of e'P^-1 e / n, P the filter's own covariance (about 1
    // for a filter whose covariance is its error's; NaN: it states none, OnlineFilter::covariance_is_statistical)
    double nees_per_state = NAN;
    // the same steps' normalised innovation squared nu'S^-1 nu / m, S the innovations' covariance the filter expected
    // (OnlineFilter::nis): the check `hinf filter` makes on recorded data, where no truth gives the NEES
    double nis_per_output = NAN;
};

struct CompareSummary {
    std::string scenario;
    std::int64_t runs = 0, steps = 0;
    std::uint64_t truth_stream_hash = 0;  // FNV-1a of the simulated measurements, in run and step order
    std::int64_t truth_escaped_runs = 0;  // runs whose true state or measurement ran away (counted
    double first_truth_escape = -1;       // for no filter), and the earliest time one did (-1: none)
    std::vector<CompareFilterResult> filters;
    double wall_seconds = 0;
    std::vector<double> rank_seconds;  // [MPI processes] time each spent on its runs (one entry without mpirun)
};

/// sum_j Q_jj (mean_j^2 + sd_j^2) over the n states of per-state error means and stds: the Q-weighted mean square
/// error (the checkpoint selection's score, the acceptance's all-state figure, the settle check's series)
double q_weighted_ms(const RunConfig& cfg, const double* mean, const double* sd);

/// Whether an error has settled by t0 (docs/compare.md, "Settled"), from its mean square over runs ms[k] at the
/// increasing times t[k]: `halves`, its mean over the first half of the samples at t >= t0 over its mean over the
/// second half (NaN with fewer than 8 such samples or a second half of 0); `settled_after`, the run cut into 20 blocks
/// of equal sample counts (at least 40 samples, else NaN), the start of the first block from which every block's mean
/// stays within kSettleFactor times the mean of the last 5 blocks.
struct SettleCheck {
    double halves = NAN, settled_after = NAN;
};
inline constexpr double kSettleFactor = 2.0;
SettleCheck settle_check(const std::vector<double>& t, const std::vector<double>& ms, double t0);

/// One line when the config names no [online] settle_time and the reference filter of s (ekf, else ukf, else pf)
/// is still falling in the default window: its halves above kSettleFactor. It names where that filter settles and
/// the key to set; "" otherwise. `who` starts the line ("compare", "acceptance").
std::string settle_note(const RunConfig& cfg, const CompareSummary& s, const char* who);

/// Whether the config names [online] settle_time (else the default window, or none on a short run): the settle note
/// speaks only of a default, and the acceptance check's window on a short run replaces only a default.
bool settle_time_named(const RunConfig& cfg);

/// Above this mean NEES per state a filter's covariance() understates its error by more than sqrt(10) = 3.2 times in
/// RMS: chosen by measurement on 40 systems (docs/compare.md "Consistency": EKF and UKF at 0.87-1.26 where they track,
/// the PF at 0.93-5.8 where it is at most 1.5 times behind the EKF, the EKF at 18-47 on UNGM, and 307 to 10^42 for
/// the 12 particle clouds that collapsed).
constexpr double kOverconfidentNees = 10.0;

/// One line where a filter's settled errors are far larger than its own covariance says (nees_per_state above
/// kOverconfidentNees): "note: pf: its settled errors are about 156 times ... (docs/compare.md "Consistency")"; ""
/// otherwise (a consistent filter, or one that states no covariance).
std::string consistency_note(const RunConfig& cfg, const CompareFilterResult& fr);

/// Runs every filter (prototypes, cloned per thread) on the same R simulated runs of cfg's system; writes
/// out_dir/compare.h5 and out_dir/compare.csv. OpenMP over runs; results do not depend on the thread count.
CompareSummary compare_run(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                           const CompareOptions& opt);

}  // namespace hinf
