// The trained object: an MLP plus its head and scales, i.e. one fixed function x~ -> dV/dx~
// (seed 000 Remark 6: the standardisation constants are part of the network, stored with it).
// Not the training loop (trainer.cpp) and not the file layout (io/checkpoint.cpp).
#pragma once
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "config/run_config.hpp"
#include "train_step.hpp"

namespace hinf {

template <typename T>
struct Network {
    kern::StepConfig step;  // shape, head, HJIE parameters, input scale, chunk size
    std::vector<T> theta;   // flat parameters (layout: kernels/mlp.hpp)
};

/// Shapes and scales from the config; weights drawn from (seed, RNG_STREAM_INIT) (He-uniform for
/// LeakyReLU, last layer x0.1 so the quadratic head starts at P ~ c I).
template <typename T>
Network<T> network_create(const RunConfig& cfg);

/// Shapes and scales only, all weights zero (for loading: no random draws, no OpenMP — checkpoints are
/// also read in a forked child, where libgomp's thread pool is unusable).
template <typename T>
Network<T> network_shell(const RunConfig& cfg);

/// Whether network_create starts the knots of this config's S(t) flat because the game's Riccati equation falls to
/// the storage's floor before its first knot (docs/method.md section 16.7, "Initial knots"): a gain run with knots
/// and network.storage_init = "riccati". One walk of the Riccati recursion; no network is drawn.
bool riccati_start_held_at_once(const RunConfig& cfg);
/// Where the Riccati start is held at the storage's floor later than that (the knots keep it, the later ones at the
/// floor): the time it is first held; -1 where it is not held, is held at once, or the config has no Riccati start.
double riccati_start_held_later(const RunConfig& cfg);
/// The game's Riccati equation of that start without the storage's floor, along the same trajectory: the first time
/// its information loses positive definiteness (no H-infinity filter of level rho from this start for the linearised
/// system); -1 where it keeps it over the run; NaN where it could not be followed or the config has no Riccati start.
double riccati_start_lost(const RunConfig& cfg);

/// The same StepConfig a config implies (used to check a checkpoint against its config).
kern::StepConfig network_step_config(const RunConfig& cfg);

/// A time-varying storage's lowest knot log-diagonal (M's diagonal is exp of it): its value, knot and state;
/// knot = -1 for a storage without knots.
struct StorageLow {
    double value = 0;
    int knot = -1, state = -1;
};
template <typename T>
StorageLow storage_lowest_log_diagonal(const Network<T>& net);

/// The log-diagonal below which a knot has run away (docs/method.md section 16.7, "Why 280 knots fail"): below
/// 0.5 ln(eps) its exp(2 v) adds less than eps to M M' + eps I, and 3 below that, less than 0.25 % of eps, so S
/// no longer moves with it. In every missile training where a knot went there the filter failed (5-30 times the
/// EKF's error); in every one that trained well, none did (lowest -4.9).
double storage_runaway_level(const kern::GainSpec& g);

/// Variant gain on a discrete system: lambda_max(B(x0)'Q B(x0)), the floor rho must exceed (S >= Q from the one-step
/// inequality, B'S B <= G'S G < rho from its concavity; docs/method.md section 16.8).
double gain_discrete_rho_floor(const RunConfig& cfg);

/// Variant gain, network.gain_structure = "components" (docs/method.md section 16.17): which entries K_aj of the gain
/// may be non-zero. States and outputs are nodes of one graph; an edge joins states k and l where dA_l/dx_k or
/// dA_k/dx_l is non-zero, states one disturbance input enters (B), states Q couples, and output j with each state
/// its C_j depends on. K_aj is kept (1) where state a and output j are in one connected component, 0 elsewhere:
/// outside it, y_j is independent of x_a's error given the rest, so a non-zero K_aj only lets noise in. The
/// Jacobians and B are read at x0, x^0 and 16 points of the training estimates' region over [0, t_final] (a
/// structural zero is zero at all of them); component (may be null) gets each state's then each output's
/// component number. Row-major [n x m].
/// mean, sd (may be null): the noise-free trajectory's moments (nominal_moments), when the caller has them.
std::vector<double> gain_component_mask(const RunConfig& cfg, std::vector<int>* component = nullptr,
                                        const std::vector<double>* mean = nullptr,
                                        const std::vector<double>* sd = nullptr);

/// How far a path of states went beyond the box of training's estimates (network.input_box, docs/method.md
/// section 16.10), where a gain network's filter holds its input at the box's edge: the state furthest beyond it, in
/// box widths, and its value there. Only an excursion of more than the box's own width is kept (the box leaves a
/// share q of training's estimates outside on each side, so a short step past its edge is routine).
struct BoxExcursion {
    int state = -1;      // the state furthest beyond the box (-1: none more than a width beyond)
    double widths = 1;   // how far beyond, in widths of the box (inf: a non-finite value)
    double value = 0;    // its value there
    double lo = 0, hi = 0;  // the box of that state, in state units
    double first_t = NAN;   // when a state first went more than a width beyond (NaN: never, or times not given)
    int first_state = -1;   // which state that was
    /// Takes the states x [count x n] into account, row k at time t0 + k dt (t0 NaN: times unknown); a gain without
    /// a box changes nothing.
    void see(const kern::GainSpec& g, const double* x, std::int64_t count, int n, double t0 = NAN, double dt = 0);
    /// "v reached 88.5 where training's estimates spanned [-2.6, 2.5]" ("ran away" for a non-finite value), with
    /// the states' names, and where times were given ", first more than a width beyond at t = 3.2 (w)"; "" where no
    /// state went more than a width beyond.
    std::string text(const std::vector<std::string>& names) const;
    /// What a gain filter says after its run (OnlineFilter::run_note): text() in a sentence; "" where text() is.
    std::string filter_note(const std::vector<std::string>& names) const;
};

/// A frozen network as a function, whatever its precision: for the on-line phase.
class FrozenNetwork {
public:
    virtual ~FrozenNetwork() = default;
    /// p [count x n] = dV/dx~ at xt [count x n].
    virtual void gradient(double* p, const double* xt, std::int64_t count) = 0;
    /// V(x~) by Gauss-Legendre quadrature of p along the segment 0 -> x~ (exact for the gradient of a
    /// quadratic V; for the `paper` head p need not be a gradient, so V is path-dependent).
    double value(const double* xt, int n);
    /// Variant `gain`: K [count x n x m] = K(x^, t) at estimates xhat [count x n], all at time t, and the storage
    /// S(t), dS/dt [n x n] (either may be null; dS/dt = 0 for a constant storage). The Riccati-form head of a
    /// time-varying storage needs sys's output Jacobian at each estimate. Other variants throw.
    virtual void gain(double* K, double* S, double* Sdot, const double* xhat, double t, const System& sys,
                      std::int64_t count);
    virtual const kern::StepConfig& step_config() const = 0;
    /// An independent copy (own workspace), for use from another thread.
    virtual std::unique_ptr<FrozenNetwork> clone() const = 0;
};

template <typename T>
std::unique_ptr<FrozenNetwork> network_freeze(Network<T> net);

}  // namespace hinf
