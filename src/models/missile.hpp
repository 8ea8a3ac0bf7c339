// Incoming ballistic missile tracked by a radar (seed 000 Section IV, eqs. (21)-(25)): drag in an
// exponential atmosphere, the guidance law folded into A(X) as printed, radar at (300, 200, 0).
// Not the maneuvering missile of seed 001 (a separate model).
#pragma once
#include "models/system.hpp"

namespace hinf {

struct MissileParams {
    double gravity = 9.81;         // g [m/s^2] (not given in seed 000)
    double ballistic = 40000.0;    // beta [kg/(m s^2)] (not given in seed 000)
    double radar[3] = {300.0, 200.0, 0.0};  // radar position [m]
    double rho_high = 1.75, alpha_high = 1.49e-4;   // density above 9144 m: rho_h e^{-alpha_h z}
    double rho_low = 1.227, alpha_low = 1.093e-4;   // below 9144 m
    double switch_altitude = 9144.0;                 // [m]
    double position_gain[3] = {0.1, 0.1, 0.08};      // guidance law folded into A: -k_i x_i
    double velocity_damping = 0.01;                  // -0.01 x_{4..6}
};

class MissileSystem : public System {
public:
    explicit MissileSystem(const MissileParams& p) : p_(p) {}
    std::string name() const override { return "missile"; }
    int state_dim() const override { return 6; }
    int disturbance_dim() const override { return 1; }
    int output_dim() const override { return 6; }
    void drift(double* a, const double* x, double t, std::int64_t count) const override;
    void disturbance_gain(double* B, const double* x, double t, std::int64_t count) const override;
    void measurement(double* c, const double* x, double t, std::int64_t count) const override;
    void drift_jacobian(double* J, const double* x, double t) const override;
    void measurement_jacobian(double* H, const double* x, double t) const override;
    std::vector<std::string> state_names() const override { return {"x", "y", "z", "vx", "vy", "vz"}; }
    std::vector<std::string> state_units() const override { return {"m", "m", "m", "m/s", "m/s", "m/s"}; }
    /// Air density rho(z) [kg/m^3] and its derivative.
    double density(double z, double* d_dz = nullptr) const;
    const MissileParams& params() const { return p_; }

private:
    MissileParams p_;
};

}  // namespace hinf
