// `hinf filter`: on-line filters run on recorded measurements, no truth anywhere. Writes the estimates
// (and covariances where a filter has them) and truth-free diagnostics (innovation statistics).
// Not the reading of the record (io/measurements.cpp) nor the filters (src/filters).
#pragma once
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "filters/filter.hpp"
#include "io/measurements.hpp"
#include "config/run_config.hpp"

namespace hinf {

struct RecordedOptions {
    std::string out_dir;
    std::string source;        // the measurement file, recorded in the output
    std::vector<double> P0;    // [n x n] initial covariance told to EKF/UKF/PF
    std::vector<double> xhat0;  // [n] initial estimate
    bool quiet = false;
};

struct RecordedResult {
    std::string name;
    std::int64_t steps = 0;
    double diverged_at = -1;             // time [s] of the record the filter diverged at; < 0: never
    std::vector<double> innovation_rms;  // [m] sqrt(mean_k (y_k - C(x^_k))^2), per output, before divergence
    std::vector<double> innovation_mean;  // [m]
    double us_per_step = 0;
    std::string note;  // OnlineFilter::run_note() after the record ("": nothing to say)
    // consistency without a truth: the mean normalised innovation squared nu'S^-1 nu / m over the measured steps at
    // t >= nis_from (OnlineFilter::nis, S the innovations' covariance the filter expected); about 1 where its model
    // and told statistics hold for the record. NaN: the filter states no S (not a Bayesian filter), or no step.
    double nis_per_output = NAN;
    double nis_from = NAN;  // t_0 + [online] settle_time, or t_0 where the record is shorter than that
    double nis_dof = 0;     // the degrees of freedom behind the mean: m per measured step in the window
};

/// Mean NIS per output above which `hinf filter` says the filter is overconfident on the record (it expects less than
/// a third of its innovations' variance), and below which it says the filter expects more than three times it; only
/// over at least kNisMinDof degrees of freedom (below, chance alone crosses 3 or 1/3 too often: chi-square(30)/30
/// exceeds 3 with probability 1e-7 and falls below 1/3 with 4e-4). Measured on 39 configs (docs/compare.md
/// "Consistency without the truth"): 0.90-1.18 on single records wherever the NEES was 0.8-1.3, 13.7 to 3e7 on 8 of
/// the 13 overconfident filters, 1.01-1.7 on the other 5 (they lost states the outputs barely see); an EKF told
/// covariances 10 times too small or large reads 10 or 0.1, which a threshold of 10 / 0.1 left to chance.
constexpr double kOverconfidentNis = 3.0, kUnderconfidentNis = 1.0 / 3.0, kNisMinDof = 30.0;

/// One line where a filter's innovations on the record are far from what it expects (nis_per_output above
/// kOverconfidentNis or below kUnderconfidentNis, over at least kNisMinDof degrees of freedom): "note: ekf: its
/// innovations are about ..."; "" otherwise.
std::string innovation_consistency_note(const RecordedResult& r);

/// Throws unless the record fits the system: a discrete-time system needs the record sampled at its [filter] dt, and a
/// table of known inputs ([system] inputs) must cover the record's times.
void recorded_check_sampling(const RunConfig& cfg, const Measurements& ms, const std::string& source);

/// Runs every filter (each reset to opt.xhat0 / opt.P0) over the whole record, feeding y_k at time t_k;
/// writes out_dir/estimates.h5 (one group per filter) and out_dir/estimates_<filter>.csv.
/// Filters that read the true state are refused (there is none).
std::vector<RecordedResult> filter_recorded(const RunConfig& cfg, const std::vector<OnlineFilter*>& filters,
                                            const Measurements& ms, const RecordedOptions& opt);

/// One filter's path over a record (the arrays of estimates.h5).
struct RecordedPath {
    std::vector<double> xhat, P, innov;  // [K x n], [K x n x n] (covariance filters), [K x m]
    std::vector<double> xhat_final;      // [n]
    std::vector<double> xhat_filtered;   // [K x n] x^_{k|k} (filters that have one; docs/compare.md)
    std::vector<double> nis;             // [K] OnlineFilter::nis() of y_k (NaN: none); empty: the filter states no S
    bool has_cov = false;
};

/// Resets f to xhat0 / P0 and steps it over the whole record; *out receives its path. The one loop of
/// `hinf filter` and of the library's Filter::run.
RecordedResult filter_record_path(OnlineFilter& f, const RunConfig& cfg, const Measurements& ms,
                                  const std::vector<double>& xhat0, const std::vector<double>& P0, bool quiet,
                                  RecordedPath* out);

}  // namespace hinf
