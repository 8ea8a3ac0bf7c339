// A system seen in units of its own noise: y~ = W C(x, t) and B~ = B U, so that the measurement noise n~ = W n and
// the disturbance v~ = U^-1 v are white with one standard deviation each when [online] noise_std or disturbance_std
// are lists (W, U diagonal: one entry per output or input) or noise_cov / disturbance_cov are given (W = L_R^-1,
// U = L_V, the covariances' Cholesky factors: lower triangular). Every filter, the training game and the truth then
// run on this system unchanged; the game's |n~|^2 and |v~|^2 are the noise- and disturbance-weighted energies
// n' R^-1 n and v' V^-1 v (docs/method.md section 16.13). Not the conversions at the user's side
// (config/run_config.hpp).
#pragma once
#include <cstdint>
#include <memory>
#include <vector>

#include "models/system.hpp"

namespace hinf {

/// x <- L x and x <- L^-1 x for a lower-triangular L [k x k] (row-major), in place; zero entries are skipped, so a
/// diagonal L gives exactly x_j L_jj and x_j / L_jj.
void lower_multiply(const std::vector<double>& L, int k, double* x);
void lower_solve(const std::vector<double>& L, int k, double* x);
/// L^-1 of a lower-triangular L [k x k] (row-major); lower triangular (1 / L_jj on a diagonal one).
std::vector<double> lower_inverse(const std::vector<double>& L, int k);
/// Whether a [k x k] matrix has no non-zero entry off its diagonal.
bool is_diagonal(const std::vector<double>& M, int k);
/// The diagonal of a diagonal [k x k] matrix; empty where M is empty or has an entry off its diagonal.
std::vector<double> diagonal_of(const std::vector<double>& M, int k);

class WeightedSystem : public System {
public:
    /// W [m x m]: output weight (empty: I); U [nv x nv]: disturbance scale (empty: I); both lower triangular.
    WeightedSystem(std::shared_ptr<const System> inner, std::vector<double> W, std::vector<double> U);
    std::string name() const override { return inner_->name(); }
    int state_dim() const override { return inner_->state_dim(); }
    int disturbance_dim() const override { return inner_->disturbance_dim(); }
    int output_dim() const override { return inner_->output_dim(); }
    void drift(double* a, const double* x, double t, std::int64_t count) const override {
        inner_->drift(a, x, t, count);
    }
    void disturbance_gain(double* B, const double* x, double t, std::int64_t count) const override;
    void measurement(double* c, const double* x, double t, std::int64_t count) const override;
    void drift_jacobian(double* J, const double* x, double t) const override { inner_->drift_jacobian(J, x, t); }
    void measurement_jacobian(double* H, const double* x, double t) const override;
    std::vector<std::string> state_names() const override { return inner_->state_names(); }
    std::vector<std::string> state_units() const override { return inner_->state_units(); }
    bool discrete_time() const override { return inner_->discrete_time(); }
    /// The angle outputs are the inner system's, in the user's units: a difference of weighted outputs wraps there,
    /// r~ = W wrap(W^-1 y~ - W^-1 c~) (a plain subtraction, bit for bit, where no output is an angle).
    const std::vector<int>& angle_outputs() const override { return inner_->angle_outputs(); }
    const std::vector<int>& angle_states() const override { return inner_->angle_states(); }  // states: unweighted
    std::pair<double, double> time_span() const override { return inner_->time_span(); }
    void output_difference(double* r, const double* y, const double* c, std::int64_t count = 1) const override;

    const System& inner() const { return *inner_; }
    const std::vector<double>& output_weight() const { return W_; }
    const std::vector<double>& disturbance_scale() const { return U_; }

private:
    std::shared_ptr<const System> inner_;
    std::vector<double> W_, U_;
    // lists: W and U diagonal, applied entry by entry (no scratch; the per-sample calls of training stay as cheap as
    // before the covariances); covariances: the triangular products
    std::vector<double> w_diag_, u_diag_;  // the diagonals where W, U are diagonal; else empty
};

}  // namespace hinf
