// Maneuvering (Tsien Hsueshen) ballistic missile tracked by a radar (seed 001 Section 4, eqs. (24)-(29)):
// the time-varying guidance law u(t) folded into f(X, t) as printed in (29), g = diag(0,0,0,1,1,1) (nv = 6),
// radar at (300, 300, 0). Not seed 000's missile (models/missile.hpp), whose disturbance enters through one input.
#pragma once
#include "models/missile.hpp"
#include "models/system.hpp"

namespace hinf {

struct ManeuverParams {
    MissileParams base;                // drag, atmosphere, gravity, position gains 0.1/0.1/0.08, damping 0.01
    double amplitude = 15000.0;        // A of a(t) = A e^{-decay t} (4/pi) sin(omega_a t)  [m/s]
    double decay = 0.1;                // the e^{-0.1 t} of a(t) and of the x4 term [1/s]
    double wave_frequency = 1.0;       // sin(t) in a(t) [rad/s]
    double maneuver_frequency = 10.0;  // -e^{-0.1 t} sin(10 t) x4 in row 4 [rad/s]
    ManeuverParams() {
        base.radar[0] = 300.0;
        base.radar[1] = 300.0;
        base.radar[2] = 0.0;
    }
};

class ManeuveringMissileSystem : public System {
  public:
    explicit ManeuveringMissileSystem(const ManeuverParams& p) : p_(p), drag_(p.base) {}
    std::string name() const override { return "maneuvering_missile"; }
    int state_dim() const override { return 6; }
    int disturbance_dim() const override { return 6; }
    int output_dim() const override { return 6; }
    void drift(double* a, const double* x, double t, std::int64_t count) const override;
    void disturbance_gain(double* B, const double* x, double t, std::int64_t count) const override;
    void measurement(double* c, const double* x, double t, std::int64_t count) const override;
    void drift_jacobian(double* J, const double* x, double t) const override;
    void measurement_jacobian(double* H, const double* x, double t) const override;
    std::vector<std::string> state_names() const override { return {"x", "y", "z", "vx", "vy", "vz"}; }
    std::vector<std::string> state_units() const override { return {"m", "m", "m", "m/s", "m/s", "m/s"}; }
    /// a(t) of eq. (28) [m/s] and the time-varying coefficient e^{-0.1 t} sin(10 t) of row 4 [1/s].
    double wave(double t) const;
    double maneuver_coefficient(double t) const;
    const ManeuverParams& params() const { return p_; }

  private:
    ManeuverParams p_;
    MissileSystem drag_;  // density(z) only
};

}  // namespace hinf
