// A system seen in units of its own noise: y~_j = w_j C_j(x, t) and B~ = B diag(u), so that measurement noise
// n~ = w (.) n and disturbance v~ = v / u are white with one standard deviation each when [online] noise_std or
// disturbance_std are lists (one entry per output or input). Every filter, the training game and the truth then run
// on this system unchanged; the game's |n~|^2 and |v~|^2 are the noise- and disturbance-weighted energies
// (docs/method.md section 16.13). Not the conversions at the user's side (config/run_config.hpp).
#pragma once
#include <memory>
#include <vector>

#include "models/system.hpp"

namespace hinf {

class WeightedSystem : public System {
public:
    /// w [m]: output weights (empty: all 1); u [nv]: disturbance scales (empty: all 1).
    WeightedSystem(std::shared_ptr<const System> inner, std::vector<double> w, std::vector<double> u);
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

    const System& inner() const { return *inner_; }
    const std::vector<double>& output_weights() const { return w_; }
    const std::vector<double>& disturbance_scales() const { return u_; }

private:
    std::shared_ptr<const System> inner_;
    std::vector<double> w_, u_;
};

}  // namespace hinf
