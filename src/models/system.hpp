// The system interface: x' = A(x,t) + B(x,t) v,  y = C(x,t) + n  (seed 000 eq. (1)), or in discrete time
// x_{k+1} = A(x_k, t_k) + B(x_k, t_k) v_k, y_k = C(x_k, t_k) + n_k, evaluated on a batch of states at once, with
// Jacobians. Not the filters or the training: they only call this (through system_advance for the dynamics).
//
// Shape legend: count = states in the batch, n = states, nv = disturbance inputs, m = outputs.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace hinf {

class ConfigDoc;

class System {
public:
    virtual ~System() = default;
    virtual std::string name() const = 0;
    virtual int state_dim() const = 0;        // n
    virtual int disturbance_dim() const = 0;  // nv
    virtual int output_dim() const = 0;       // m
    /// a [count x n] = A(x, t) for x [count x n].
    virtual void drift(double* a, const double* x, double t, std::int64_t count) const = 0;
    /// B [count x n x nv] (row-major per state) = B(x, t).
    virtual void disturbance_gain(double* B, const double* x, double t, std::int64_t count) const = 0;
    /// c [count x m] = C(x, t).
    virtual void measurement(double* c, const double* x, double t, std::int64_t count) const = 0;
    /// J [n x n] = dA/dx at one state (analytic).
    virtual void drift_jacobian(double* J, const double* x, double t) const = 0;
    /// H [m x n] = dC/dx at one state (analytic).
    virtual void measurement_jacobian(double* H, const double* x, double t) const = 0;
    /// Names of the states, for files and tables ("x", "y", "z", "vx", ...).
    virtual std::vector<std::string> state_names() const = 0;
    /// Units of each state ("m", "m/s", ...).
    virtual std::vector<std::string> state_units() const = 0;
    /// true: A is the map x_{k+1} = A(x_k, t_k) + B v_k itself (a discrete-time system, t_k = k dt only stamps
    /// the steps); false: A is the vector field of x' = A + B v, stepped by forward Euler. system_advance is the
    /// one place that reads it.
    virtual bool discrete_time() const { return false; }
    /// The outputs that are angles in radians (0-based, ascending; [system] angle_outputs), in the user's units (a
    /// weighted system's are its inner system's): a difference of two of their values wraps into [-pi, pi]. Empty
    /// for every built-in system.
    virtual const std::vector<int>& angle_outputs() const;
    /// Whether output_difference is more than a subtraction (some output is an angle, seen through any weighting).
    virtual bool wraps_outputs() const { return !angle_outputs().empty(); }
    /// r [count x m] = y - c for outputs y, c [count x m]: an innovation y - C(x^), or C(x) - C(x^). The plain
    /// difference, with the angle outputs' wrapped into [-pi, pi] (docs/formats.md, [system] angle_outputs); every
    /// filter, the training samples and the on-line check take their output differences here. r may alias y or c.
    virtual void output_difference(double* r, const double* y, const double* c, std::int64_t count = 1) const;
    /// The states that are angles in radians (0-based, ascending; [system] angle_states): a heading, a pendulum that
    /// spins. Empty for every built-in system.
    virtual const std::vector<int>& angle_states() const;
    /// The times [first, last] over which the system is defined: a table of known inputs covers only its own rows
    /// ([system] inputs); every other system is defined at any time (-inf, inf). Runs check their span against it.
    virtual std::pair<double, double> time_span() const;
    /// d [count x n] = a - b for states a, b [count x n]: an estimation error x - x^, a sigma point's or particle's
    /// offset. The plain difference, with the angle states' wrapped into [-pi, pi] (bit for bit a - b where no state
    /// is an angle); every error statistic, the UKF's and PF's means, and the oracle networks' x~ take it here. d may
    /// alias a or b.
    void state_difference(double* d, const double* a, const double* b, std::int64_t count = 1) const;
};

/// x wrapped into [-pi, pi] (IEEE remainder by 2 pi: exact)
double wrap_angle(double x);

/// "discrete" or "continuous": for messages and result files.
inline const char* system_time_name(const System& sys) { return sys.discrete_time() ? "discrete" : "continuous"; }

/// The states of one unit, for error summaries in state units: group 0 holds the states with the first state's
/// unit (the missile's positions, "position" in tables), group 1 those with the next unit met (its velocities).
/// Empty when there is no such unit.
std::vector<int> state_unit_group(const System& sys, int group);

/// The one step the truth, every filter and the trainer share, for a batch x [count x n], v [count x nv]
/// (nullptr: v = 0):
///   continuous time: x_next = x + dt (A(x, t) + B(x, t) v)   (forward Euler, seed 000 eq. (18));
///   discrete time:   x_next = A(x, t) + B(x, t) v             (the model itself; dt is not used).
/// x_next may alias x.
void system_advance(const System& sys, double* x_next, const double* x, const double* v, double t, double dt,
                    std::int64_t count = 1);
/// Its Jacobians at (x, v = 0): F [n x n] = d x_next / dx, G [n x nv] = d x_next / dv; continuous time
/// F = I + dt dA/dx, G = dt B(x, t); discrete time F = dA/dx, G = B(x, t). Either pointer may be nullptr.
void system_advance_jacobian(const System& sys, double* F, double* G, const double* x, double t, double dt);

/// Builds the system named by [system] kind in the config (checks every key of [system]).
std::unique_ptr<System> make_system(const ConfigDoc& doc);

}  // namespace hinf
