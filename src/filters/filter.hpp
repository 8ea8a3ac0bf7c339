// The one on-line interface every filter implements (EKF, UKF, PF, open-loop, DNN adapters), and the
// discrete model they all share. Not the simulation of the truth (eval/compare.cpp) nor any metric.
//
// Time convention (the sampled-data filter of seed 000 eq. (19)): before step k, estimate() is the
// estimate of x(t_k) from y(t_0) ... y(t_{k-1}); step(y(t_k)) moves it to the estimate of x(t_{k+1}).
// Every filter is scored on this one-step prediction, i.e. on the same information.
// Shape legend: n = states, nv = disturbance inputs, m = outputs.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "models/system.hpp"

namespace hinf {

/// The discrete model x_{k+1} = x_k + dt (A(x_k) + B(x_k) v_k), y_k = C(x_k) + n_k with v_k ~ N(0, sv^2 I),
/// n_k ~ N(0, sn^2 I): the Euler step the truth is simulated with (eval/operate.cpp). The statistics are
/// what the filter is *told*; robustness scenarios tell it wrong ones.
struct FilterModel {
    const System* system = nullptr;
    double dt = 0.01;
    double disturbance_std = 20.0;  // sv
    double noise_std = 20.0;        // sn
};

struct FilterStart {
    std::vector<double> xhat0;  // [n] initial estimate (the same for every filter)
    std::vector<double> P0;     // [n x n] initial error covariance (filters that have one)
    std::uint64_t seed = 7;     // random filters (PF): draws keyed by (seed, run, step)
    std::uint64_t run = 0;
};

struct FilterInput {
    const double* y = nullptr;       // [m] y(t_k)
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
    /// Consumes y(t_k); on FILTER_DIVERGED the estimate is left at its last finite value.
    virtual FilterStatus step(const FilterInput& in) = 0;
    /// [n] estimate of x(t_k) before step k.
    virtual const double* estimate() const = 0;
    /// [n x n] error covariance of estimate(), or nullptr for filters without one.
    virtual const double* covariance() const { return nullptr; }
    /// Whether step() reads x_true (the comparison says so next to every figure).
    virtual bool uses_true_state() const { return false; }
    /// An independent copy (own workspace) for another thread.
    virtual std::unique_ptr<OnlineFilter> clone() const = 0;
};

/// true when every entry is finite and |x| < 1e12 (the divergence bound of eval/operate.cpp).
inline bool filter_estimate_ok(const double* x, int n) {
    for (int i = 0; i < n; ++i)
        if (!(x[i] == x[i]) || x[i] >= 1e12 || x[i] <= -1e12) return false;
    return true;
}

/// The open-loop predictor: x^_{k+1} = x^_k + dt A(x^_k), measurements ignored (gain zero).
std::unique_ptr<OnlineFilter> make_open_loop_filter(const FilterModel& model);
/// Extended Kalman filter on the discrete model, with the system's analytic Jacobians.
std::unique_ptr<OnlineFilter> make_ekf(const FilterModel& model);
/// Unscented Kalman filter (additive noise; alpha = 1, beta = 2, kappa = 0).
std::unique_ptr<OnlineFilter> make_ukf(const FilterModel& model);
/// Bootstrap particle filter: log-weights, systematic resampling when ESS < ess_fraction * particles;
/// roughening K > 0 jitters the resampled particles by K E_i N^(-1/n) N(0,1) per state (E_i: the cloud's
/// range; Gordon, Salmond & Smith 1993), against sample impoverishment. K = 0: the plain bootstrap filter.
std::unique_ptr<OnlineFilter> make_particle_filter(const FilterModel& model, std::int64_t particles,
                                                   double ess_fraction = 0.5, double roughening = 0.0);

}  // namespace hinf
