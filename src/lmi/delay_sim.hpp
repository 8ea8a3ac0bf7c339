// Simulation of an Itô time-varying-delay system (seed 002 eq. 1) by Euler-Maruyama with a history buffer,
// the globally linearized filter (21), the bounding constants of Assumption 1 (24) estimated from
// simulation, and the Monte Carlo of Table 3. Not the LMI design (delay_lmi.hpp).
#pragma once
#include <cstdint>
#include <vector>

#include "lmi/delay_system.hpp"

namespace hinf::lmi {

/// x(s) for s in [t_start, t_last] on a uniform grid, read back by linear interpolation (eq. 1's x(t - tau(t))).
class DelayHistory {
public:
    void reset(int n, double t_start, double dt);
    /// Appends the value at time t_last() + dt (the first push is at t_start).
    void push(const double* x);
    double t_last() const { return t_start_ + (rows_ - 1) * dt_; }
    std::int64_t rows() const { return rows_; }
    /// Linear interpolation between grid points; t is clamped to [t_start, t_last].
    void at(double t, double* out) const;

private:
    int n_ = 0;
    double t_start_ = 0, dt_ = 1;
    std::int64_t rows_ = 0;
    std::vector<double> values_;
};

enum DelayTauKind {
    DELAY_TAU_EXP = 0,       // tau(t) = exp(-(1 + t)^-1)  (seed 002 example)
    DELAY_TAU_CONSTANT = 1,  // tau(t) = tau2
};
double delay_tau(DelayTauKind kind, double tau2, double t);

/// Periodic rectangle wave: `high` on the first duty * period of every period, `low` on the rest.
struct DelayDisturbance {
    double high = 2, low = -2, period = 2, duty = 0.5;
    double at(double t) const;
};

struct DelaySimSpec {
    double final_time = 15, dt = 1e-3, tau2 = 1;
    DelayTauKind tau = DELAY_TAU_EXP;
    DelayDisturbance disturbance;
    Eigen::MatrixXd initial_covariance;  // n x n: x(theta) = x0 ~ N(0, M11) for all theta in [-tau2, 0]
    std::uint64_t seed = 1;
    int record_every = 10;  // steps between rows of the mean-square error trajectory
};

/// The filter (21): vertices, gains L_j (n x l), operating points and the coordinates the weights use.
struct DelayFilter {
    std::vector<DelayVertex> vertices;
    std::vector<Eigen::MatrixXd> gains;
    std::vector<std::vector<double>> points;
    std::vector<int> coordinates;
};

/// One Euler-Maruyama step of (1): x_next = x + (f + g v) dt + h dW, dy = (q + k v) dt + j dW.
void delay_em_step(const DelaySystem& sys, const double* x, const double* xd, const double* v, double dW, double dt,
                   double* x_next, double* dy);
/// One step of (21): xh_next = xh + sum_j a_j(xh) [(A0j xh + A1j xhd) dt + L_j (dy - dyhat)],
/// dyhat = sum_k a_k(xh) (Q0k xh + Q1k xhd) dt.
void delay_filter_step(const DelayFilter& filter, const double* xh, const double* xhd, const double* dy, double dt,
                       double* xh_next);

struct DelayRunResult {
    double error_energy = 0;            // int_0^T ||x - xh||^2 dt (trapezoid)
    std::vector<double> squared_error;  // ||e||^2 every record_every steps, from t = 0
    bool finite = true;
};
/// One run (index `run` keys its random numbers: thread-count independent).
DelayRunResult delay_simulate(const DelaySystem& sys, const DelayFilter& filter, const DelaySimSpec& spec,
                              std::int64_t run);

struct DelayMonteCarlo {
    std::vector<double> error_energy;      // per run
    double mean = 0, stddev = 0, ci95_low = 0, ci95_high = 0;
    std::vector<double> time, mean_squared_error;  // E||e(t)||^2 (Figs. 9-10)
    int diverged = 0;
};
/// R runs over `threads` OpenMP threads; runs are independent and summed in run order.
DelayMonteCarlo delay_monte_carlo(const DelaySystem& sys, const DelayFilter& filter, const DelaySimSpec& spec,
                                  int runs, int threads);

struct DelayBounds {
    double e1 = 0, e2 = 0, e3 = 0, e4 = 0, alpha = 0;
};
/// Table 1 Step 3: sup over simulated truth trajectories (v as in spec, R runs) of ||Df||/||zeta|| etc.,
/// with the weights of Step (e) evaluated at the true state.
DelayBounds delay_estimate_bounds(const DelaySystem& sys, const DelayFilter& filter, const DelaySimSpec& spec,
                                  int runs, int threads);

}  // namespace hinf::lmi
