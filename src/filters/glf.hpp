// The global-linearization H-infinity filter (Chen, Chen & Wu 2009, the comparison filter of seed 001) for
// a system without delay: N vertex linearizations along the nominal trajectory, one common Lyapunov
// matrix, one constant gain, designed by a discrete-time bounded-real LMI (docs/compare.md). Not seed
// 002's delay LMI (src/lmi/delay_lmi.*), which has its own system class.
#pragma once
#include <string>
#include <vector>

#include "config/run_config.hpp"
#include "filters/filter.hpp"

namespace hinf {

struct GlfDesign {
    int vertices = 8;
    std::vector<double> vertex_times;  // [N] s, along the noise-free trajectory from x0
    std::vector<double> gain;          // L [n x m]
    double rho = 0;                    // guaranteed level: sum x~'Qx~ <= V(x~0) + rho sum (v'v + n'n) on the polytope
    bool ok = false;
    std::string status;                // the solver's verdict in words
};

/// Vertices A_i = dA/dx, B_i, C_i = dC/dx at x(t_i), t_i = i T / (N-1) on the noise-free Euler trajectory
/// from x0 over the problem's time grid (steps_until(), time_of()); the LMIs (one per vertex), for the Euler filter x^_{k+1} = x^_k + dt (A(x^_k) + L (y_k - C(x^_k))):
///   [[P - dt Q, 0, (P Phi_i)'], [0, dt rho I, (P Gam_i)'], [P Phi_i, P Gam_i, P]] > 0,
///   P Phi_i = P + dt P A_i - dt Y C_i,  P Gam_i = [dt P B_i, -dt Y],  L = P^-1 Y.
/// rho_max > 0: rho <= rho_max (the DNN filter's prescribed level) and minimise trace P (the initial-error
/// term V(x~0) of the bound, for every direction of x~0); rho_max <= 0: minimise rho, which ignores the
/// initial error and barely corrects states without disturbance (docs/compare.md).
GlfDesign glf_design(const ProblemConfig& problem, int vertices, double rho_max);

/// x^_{k+1} = x^_k + dt (A(x^_k) + L (y_k - C(x^_k))) with the designed constant gain.
std::unique_ptr<OnlineFilter> make_glf_filter(const FilterModel& model, const GlfDesign& design);

}  // namespace hinf
