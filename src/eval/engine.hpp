// The one Monte Carlo engine: a set of on-line filters over R runs of one scenario, every filter fed the same
// simulated measurements (sim/truth), per-run error accumulators, and per-step observers (e.g. the on-line HJI
// check). Also the one loop that steps a filter over a measurement stream (recorded data use it too).
// Not the statistics over runs nor any file layout (operate.cpp, compare.cpp, filter_recorded.cpp).
//
// Shape legend: R = runs, K = steps, n = states, m = outputs, F = filters.
#pragma once
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "filters/filter.hpp"
#include "sim/truth.hpp"

namespace hinf {

/// The normalised estimation error squared e'P^-1 e of an error e [n] against a covariance P [n x n] (symmetric);
/// NaN where P is not positive definite or not finite. About n on average for a filter whose P is its error's.
double nees(const double* P, const double* e, int n);

/// What stepping one filter over a stream gave.
struct StreamResult {
    double diverged_at = -1;  // time of the first FILTER_DIVERGED; < 0: never
    double seconds = 0;       // time spent inside step()
    std::int64_t stepped = 0;  // steps before the divergence (the filter is frozen after it)
};

/// An estimate with |x^_i| > kPlausibleFactor * scale_i for any state is reported as diverged (plausible_bound).
constexpr double kPlausibleFactor = 1000.0;

/// The physically plausible range of each state, from the system's own scales: bound_i = kPlausibleFactor *
/// max(|x0_i|, |x^0_i|, sd0_i, max_k |x_i(t_k)| of the truth (x_true [K x n], may be nullptr), the largest |y|
/// of the measurements y [K x m] (recorded data, where no truth gives the states' scale; may be nullptr)); +infinity
/// for a state where all of these are 0 (no scale to judge its estimate by); the largest double for an angle state
/// ([system] angle_states: it winds, so only a non-finite estimate of it leaves the range).
/// docs/compare.md "Divergence".
std::vector<double> plausible_bound(const RunConfig& cfg, const FilterStart& start, const double* x_true,
                                    const double* y, std::int64_t K);

/// Steps f over K measurements y [K x m] at times t [K]: before step k calls visit(k, xhat, frozen) with the
/// estimate of x(t_k); a filter that reports a divergence, or whose estimate leaves |x^_i| <= bound[i] (bound [n],
/// nullptr: no range), stays frozen at its last estimate (visit is still called, with frozen = true). x_true [K x n]
/// is handed to oracle filters (nullptr for recorded data). missing [K] (nullptr: none): rows without a
/// measurement, stepped with FilterInput::y = nullptr (predict only).
/// After step k calls after(k, xhat_filtered, frozen) with the filtered estimate x^_{k|k} (f.filtered(); a frozen
/// filter's last estimate; nullptr for filters without one), frozen = true when the filter was not stepped or
/// failed at this step (its f.nis() is then not of this measurement).
template <class Visit, class After>
StreamResult filter_stream(OnlineFilter& f, const double* y, int m, const double* t, std::int64_t K,
                           const double* x_true, int n, const double* bound, const unsigned char* missing,
                           Visit&& visit, After&& after) {
    StreamResult r;
    for (std::int64_t k = 0; k < K; ++k) {
        visit(k, f.estimate(), r.diverged_at >= 0);
        const bool was_frozen = r.diverged_at >= 0;
        if (!was_frozen) {
            auto c0 = std::chrono::steady_clock::now();
            const double* yk = missing != nullptr && missing[k] ? nullptr : y + k * m;
            FilterStatus st = f.step(FilterInput{yk, t[k], k, x_true != nullptr ? x_true + k * n : nullptr});
            r.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count();
            ++r.stepped;
            if (st != FILTER_OK) r.diverged_at = t[k];
            if (bound != nullptr && r.diverged_at < 0) {
                const double* xh = f.estimate();
                for (int i = 0; i < n; ++i)
                    if (!(std::fabs(xh[i]) <= bound[i])) {  // NaN too
                        r.diverged_at = t[k];
                        break;
                    }
            }
        }
        const bool frozen = r.diverged_at >= 0;
        after(k, f.filtered() == nullptr ? nullptr : frozen ? f.estimate() : f.filtered(), was_frozen || frozen);
    }
    return r;
}

template <class Visit>
StreamResult filter_stream(OnlineFilter& f, const double* y, int m, const double* t, std::int64_t K,
                           const double* x_true, int n, const double* bound, const unsigned char* missing,
                           Visit&& visit) {
    return filter_stream(f, y, m, t, K, x_true, n, bound, missing, visit, [](std::int64_t, const double*, bool) {});
}

/// Watches one filter's run step by step (one instance per thread: clone()). begin/end bracket each (filter,
/// run); end() returns the run's values, kept in FilterRunStats::observed.
class StepObserver {
public:
    virtual ~StepObserver() = default;
    virtual void begin(int filter, std::uint64_t run) = 0;
    /// Before step k: the truth x(t_k) and the filter's estimate of it.
    virtual void observe(std::int64_t k, double t, const double* x, const double* xhat) = 0;
    virtual std::vector<double> end() = 0;
    virtual std::unique_ptr<StepObserver> clone() const = 0;
};

/// One filter over one run: sums over the steps (divide by the counts for means).
struct FilterRunStats {
    double diverged_at = -1;
    std::vector<double> err_sum, err_sq;                  // [n] sums of e = x - x^ and e^2 over all steps
    std::vector<double> err_sq_filtered;                  // [n] sums of (x - x^_{k|k})^2; empty: no filtered estimate
    std::vector<double> err_sum_settled, err_sq_settled;  // [n] the same over t >= settle_time
    double settled_steps = 0;
    double sq_pos = 0, sq_vel = 0, sq_pos_settled = 0, sq_vel_settled = 0;  // sums of |e|^2 over unit groups 0, 1
    double error_energy = 0;        // int x~'Q x~ dt (rectangle rule)
    double signal_energy = 0;       // int (v'v + n'n) dt
    double seconds = 0;             // inside step()
    std::uint64_t stream_hash = 0;  // FNV-1a of every y this filter was fed
    std::vector<double> err_sub;    // [ceil(K / stride) x n] error every `stride` steps
    std::vector<double> xhat;       // run 0 only: [K x n]
    std::vector<double> observed;   // StepObserver::end() of this (filter, run)
    std::vector<double> reported;   // OnlineFilter::run_report() after the run
    std::string note;               // OnlineFilter::run_note() after the run ("": nothing to say)
    // over t >= settle_time, where the filter states its error's statistics (covariance_is_statistical): the sum of
    // the normalised estimation error squared e'P^-1 e (NEES) and the count of steps it was taken at (P positive
    // definite, the filter not frozen)
    double nees_sum = 0, nees_steps = 0;
    // over the same steps, where the filter states its innovations' covariance (OnlineFilter::nis finite): the sum
    // of the normalised innovation squared and the count of steps it was taken at
    double nis_sum = 0, nis_steps = 0;
};

struct EngineOptions {
    std::int64_t runs = 1;
    std::int64_t steps = 1;
    std::int64_t stride = 1;                        // error subsampling for err_sub
    Scenario scenario;
    const std::vector<Signals>* signals = nullptr;  // [R] explicit signals per run instead of the draws
    std::string label = "compare";                  // progress label
    bool quiet = false;
    bool split = true;  // under mpirun, deal the runs out over the processes; false: this process runs them all
                        // (for a caller that already split its work, e.g. the worst-case replay's sets)
};

struct EngineResult {
    std::vector<std::vector<FilterRunStats>> runs;  // [F][R]
    std::vector<std::uint64_t> truth_hash;          // [R] FNV-1a of each run's measurements
    // [R] t of the first step whose true state ran away (truth_escape_step: the model escaped under its noise;
    // -1: never). Every filter still runs on such a run; the reductions leave it out and say so (compare.md).
    std::vector<double> truth_escaped_at;
    TruthRun truth0;                                // run 0's truth (for plots and files)
    std::vector<double> t;                          // [K] t_k
    std::vector<double> rank_seconds;               // [processes] wall time each spent on its runs (load balance)
};

/// Runs every filter (prototypes, cloned per thread) on the same R simulated runs; OpenMP over runs, results in
/// run order: they do not depend on the thread count. Under mpirun the runs are dealt out over the processes
/// (engine_rank_of) and every process ends with the whole table, the same bits as one process computes
/// (unless opt.split is false: then no collective is called and this process computes every run).
EngineResult engine_run(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                        const EngineOptions& opt, const StepObserver* observer = nullptr);

/// The process that computes run `run` of a Monte Carlo among `ranks`.
std::int64_t engine_rank_of(std::int64_t run, int ranks);

/// The initial error covariance EKF, UKF and PF are told (docs/compare.md, "Initial estimate"): diag(initial_std^2)
/// with initial_std the argument, else [baseline] initial_std, else diag(d^2), d = x0 - x^0 of the config: the
/// actual initial error of the simulated runs, 0 where the start is exact. In each state's own units, with no floor.
std::vector<double> baseline_initial_covariance(const RunConfig& cfg, const std::vector<double>& initial_std = {});

/// One line for `hinf filter` when P0 (baseline_initial_covariance) is 0 in a state, i.e. the config's x0 and x^0
/// agree there: the Bayesian filters start certain of it, which a recorded run may not justify. "" otherwise.
std::string baseline_certain_note(const RunConfig& cfg, const std::vector<double>& P0);

/// The initial estimate every filter of a Monte Carlo run starts from: cfg.xhat0, P0 = baseline_initial_covariance.
FilterStart engine_filter_start(const RunConfig& cfg, std::uint64_t run);

/// FNV-1a 64 over bytes, continuing from h (start with hash_start).
constexpr std::uint64_t hash_start = 1469598103934665603ull;
std::uint64_t hash_bytes(std::uint64_t h, const void* data, std::size_t bytes);

}  // namespace hinf
