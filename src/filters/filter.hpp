// The one on-line interface every filter implements (EKF, UKF, PF, open-loop, DNN adapters), and the
// discrete model they all share. Not the simulation of the truth (eval/compare.cpp) nor any metric.
//
// Time convention (the sampled-data filter of seed 000 eq. (19)): before step k, estimate() is the
// estimate of x(t_k) from y(t_0) ... y(t_{k-1}); step(y(t_k)) moves it to the estimate of x(t_{k+1}).
// Every filter is scored on this one-step prediction, i.e. on the same information. Filters with a measurement
// update also give the filtered estimate x^_{k|k} of x(t_k) from y(t_0) ... y(t_k) after step(y(t_k)): the score
// published tables use (docs/compare.md, "Predicted and filtered scores").
// Shape legend: n = states, nv = disturbance inputs, m = outputs.
#pragma once
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Dense>

#include "config/run_config.hpp"
#include "models/system.hpp"

namespace hinf {

/// The discrete model x_{k+1} = x_k + dt (A(x_k) + B(x_k) v_k) (continuous-time systems: the Euler step) or
/// x_{k+1} = A(x_k) + B(x_k) v_k (discrete-time systems), y_k = C(x_k) + n_k with v_k ~ N(0, sv^2 I), n_k ~ N(0, sn^2 I):
/// the step the truth is simulated with (sim/truth.cpp, models/system_advance). The system and statistics are what
/// the filter is *told*; robustness scenarios and [baseline] tell it other ones.
struct FilterModel {
    const System* system = nullptr;
    double dt = 0.01;
    double disturbance_std = 20.0;  // sv
    double noise_std = 20.0;        // sn
    /// Per-input and per-output factors of sv and sn ([baseline] lists that differ, models/weighted_system.hpp);
    /// empty: all 1.
    std::vector<double> disturbance_weight, noise_weight;
    /// Correlated ([online] or [baseline] noise_cov / disturbance_cov): lower-triangular factors L [nv x nv] and
    /// [m x m], row-major, the told covariances sv^2 L L' and sn^2 L L'; they take the weights' place; empty: none.
    std::vector<double> disturbance_chol, noise_chol;
    double disturbance_std_of(int k) const {
        return disturbance_weight.empty() ? disturbance_std : disturbance_std * disturbance_weight[std::size_t(k)];
    }
    double noise_std_of(int j) const { return noise_weight.empty() ? noise_std : noise_std * noise_weight[std::size_t(j)]; }
};

/// A lower-triangular factor of FilterModel as a matrix.
inline Eigen::MatrixXd chol_matrix(const std::vector<double>& L, int k) {
    return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(L.data(), k, k);
}

/// The told measurement noise covariance R [m x m]: sn^2 L L', diag(sn_j^2) or sn^2 I.
inline Eigen::MatrixXd noise_covariance(const FilterModel& model, int m) {
    if (!model.noise_chol.empty()) {
        const Eigen::MatrixXd L = chol_matrix(model.noise_chol, m);
        return model.noise_std * model.noise_std * L * L.transpose();
    }
    Eigen::MatrixXd R = Eigen::MatrixXd::Zero(m, m);
    for (int j = 0; j < m; ++j) R(j, j) = model.noise_std_of(j) * model.noise_std_of(j);
    return R;
}

/// The process noise G diag(sv_k^2) G' of a step whose d x_next / dv is G [n x nv] (sv^2 G G' with one sv;
/// sv^2 G L L' G' correlated).
inline Eigen::MatrixXd process_noise(const Eigen::MatrixXd& G, const FilterModel& model) {
    if (!model.disturbance_chol.empty()) {
        const Eigen::MatrixXd GL = G * chol_matrix(model.disturbance_chol, int(G.cols()));
        return model.disturbance_std * model.disturbance_std * GL * GL.transpose();
    }
    if (model.disturbance_weight.empty()) return model.disturbance_std * model.disturbance_std * G * G.transpose();
    Eigen::VectorXd q(G.cols());
    for (int k = 0; k < int(G.cols()); ++k) q[k] = model.disturbance_std_of(k) * model.disturbance_std_of(k);
    return G * q.asDiagonal() * G.transpose();
}

/// The exact model of cfg: its system, dt and the [online] statistics.
inline FilterModel filter_model(const RunConfig& cfg) {
    return FilterModel{cfg.system.get(), cfg.dt, cfg.disturbance_std, cfg.noise_std, {}, {}, {}, {}};
}

struct FilterStart {
    std::vector<double> xhat0;  // [n] initial estimate (the same for every filter)
    std::vector<double> P0;     // [n x n] initial error covariance (filters that have one)
    std::uint64_t seed = 7;     // random filters (PF): draws keyed by (seed, run, step)
    std::uint64_t run = 0;
};

struct FilterInput {
    const double* y = nullptr;       // [m] y(t_k); nullptr: no measurement at t_k (a dropout): predict only
    double t = 0;                    // t_k
    std::int64_t step = 0;           // k
    const double* x_true = nullptr;  // [n] x(t_k): read only by `oracle` DNN filters (the papers' protocol)
};

enum FilterStatus {
    FILTER_OK = 0,
    FILTER_DIVERGED = 1,  // non-finite or |x^| >= 1e12, or a covariance lost positive definiteness
};

class OnlineFilter {
public:
    virtual ~OnlineFilter() = default;
    virtual std::string name() const = 0;
    virtual void reset(const FilterStart& start) = 0;
    /// Consumes y(t_k), or with in.y == nullptr (a missing measurement) only predicts to t_{k+1} (every filter:
    /// the correction term is dropped, the covariance grows by the process noise alone); on FILTER_DIVERGED the
    /// estimate is left at its last finite value.
    virtual FilterStatus step(const FilterInput& in) = 0;
    /// [n] estimate of x(t_k) before step k.
    virtual const double* estimate() const = 0;
    /// [n] after step(y(t_k)): the filtered estimate x^_{k|k} of x(t_k) (the measurement at t_k used), or nullptr
    /// for filters without one. Unspecified before the first step and after FILTER_DIVERGED.
    virtual const double* filtered() const { return nullptr; }
    /// [n x n] error covariance of estimate(), or nullptr for filters without one.
    virtual const double* covariance() const { return nullptr; }
    /// Whether covariance() is the filter's own statement of its error's statistics (EKF, UKF, PF), against which its
    /// errors can be checked (the NEES of hinf compare, docs/compare.md "Consistency"); not the game's P of the
    /// extended H-infinity filter.
    virtual bool covariance_is_statistical() const { return covariance() != nullptr; }
    /// After step(y(t_k)): the normalised innovation squared nu'S^-1 nu of nu = y(t_k) - C(x^_k), S the covariance
    /// of nu the filter itself expected (EKF: H P H' + R; UKF: its sigma points' output covariance + R; PF: its prior
    /// cloud's output covariance + R), all in the filter's own (model) units. Its mean is m for a filter whose
    /// statistics hold, and it needs no true state: the consistency check of recorded data (docs/compare.md
    /// "Consistency without the truth"). NaN: the step had no measurement, S was not positive definite, or the
    /// filter states none.
    virtual double nis() const { return NAN; }
    /// Whether step() reads x_true (the comparison says so next to every figure).
    virtual bool uses_true_state() const { return false; }
    /// Figures a filter keeps about its own run since reset() (e.g. the retraining gain filter's check and trigger
    /// counts, train/online_retrain.hpp); the Monte Carlo engine keeps them in FilterRunStats::reported. Most: none.
    virtual std::vector<double> run_report() const { return {}; }
    /// A sentence on what the filter met in its own run since reset() that its estimates and figures do not say, or
    /// "" (the gain filter: its estimate went far beyond the region its network was trained on, method.md 16.10).
    virtual std::string run_note() const { return ""; }
    /// An independent copy (own workspace) for another thread.
    virtual std::unique_ptr<OnlineFilter> clone() const = 0;
};

/// The runs on which a filter had something to say (FilterRunStats::note), for a summary: how many, and the first.
struct RunNotes {
    std::int64_t runs = 0;        // runs with a note
    std::int64_t first_run = -1;  // the first of them (its index)
    std::string first;            // its note
    void see(std::int64_t run, const std::string& note) {
        if (note.empty()) return;
        if (runs++ == 0) {
            first_run = run;
            first = note;
        }
    }
};

/// nu' S^-1 nu through a Cholesky factor of S; NaN where S is not positive definite (OnlineFilter::nis).
inline double normalised_square(const Eigen::LLT<Eigen::MatrixXd>& S, const Eigen::VectorXd& nu) {
    if (S.info() != Eigen::Success) return NAN;
    const double q = nu.dot(S.solve(nu));
    return std::isfinite(q) && q >= 0 ? q : NAN;
}

/// true when every entry is finite and |x| < 1e12 (the divergence bound of eval/operate.cpp).
inline bool filter_estimate_ok(const double* x, int n) {
    for (int i = 0; i < n; ++i)
        if (!(x[i] == x[i]) || x[i] >= 1e12 || x[i] <= -1e12) return false;
    return true;
}

}  // namespace hinf
