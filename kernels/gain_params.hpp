// Parameters of the `gain` variant (issue 14, docs/method.md section 14): the scales of its gain head and storage
// and the loss constants. Part of kern::StepConfig; the kernels are in gain.hpp.
#pragma once
#include <algorithm>
#include <cmath>
#include <vector>

namespace hinf::kern {

/// Loss constants of the gain variant (see gain.hpp for the per-sample pieces).
struct GainLossParams {
    double rho = 0.03, margin = 0.02;
    double disturbance_intensity = 4.0, noise_intensity = 4.0;  // sv2, sn2: white-noise intensities the H2 term plans for
    double horizon = 70.0;                                      // T [s]
    double h2_reference = 1.0;                                  // the H2 bound is divided by this constant
    const double* xt0 = nullptr;                                // [n] the initial error the user expects (x0 - x^0)
    double initial_weight = 0.0;  // weight of x~0'S x~0 / T in h2 (0: the stationary H2 rate alone)
    // sampled-data cap: dt |D^-1 K dC| <= kappa |D^-1 x~| (the Euler filter's correction per step stays below
    // kappa times the error; a hinge relu(dt |D^-1 K dC| / |D^-1 x~| - kappa)^2 added to the sample's hinge)
    double dt = 0.0, kappa = 0.5;  // dt = 0: no cap
    // the cap in the storage's metric instead, dt |K dC|_S <= kappa |x~|_S with |z|_S = sqrt(z'Sz): the step as V
    // measures it, whatever the error scales D (objective.step_cap = "storage"; docs/method.md section 16.2)
    bool cap_in_storage = false;
    // a discrete-time system: the one-step inequality of gain_discrete.hpp instead (per-step sv2, sn2; T in steps)
    bool discrete = false;
    const double* dx = nullptr;    // [n] D
};

/// What turns the network's raw outputs into K(x^) and its extra parameters into S (fixed at creation, from the config).
struct GainSpec {
    bool enabled = false;
    int m = 0;                       // outputs
    std::vector<double> dx, dy;      // error scale per state [n], innovation scale per output [m]
    std::vector<double> shift, spread;  // network input z = (x^ - shift) / spread  [n]
    // where the filter's network input is held (network.input_box, docs/method.md section 16.10): the box of the
    // training estimates' z, all but a share q on each side per state [n] each (empty: not held). The filter, its
    // on-line retraining and the C export evaluate the network at input(a, x^); training samples are not held.
    std::vector<double> zlo, zhi;
    double input(int a, double xhat) const {
        const double z = (xhat - shift[a]) / spread[a];
        return zlo.empty() ? z : std::min(zhi[a], std::max(zlo[a], z));
    }
    // network.angle_inputs = "periodic" (docs/method.md section 16.19): the states that are angles ([system]
    // angle_states) as flags [n] (empty: none). The network sees an angle state as the pair (cos x^_a, sin x^_a) in
    // its place, never held, so K(x^) is the same a turn on and the network's input has n + (angles) entries.
    std::vector<int> periodic;
    bool is_periodic(int a) const { return !periodic.empty() && periodic[a] != 0; }
    /// Entries of the network's input for n states.
    int input_count(int n) const {
        int c = n;
        for (int a = 0; a < n; ++a) c += is_periodic(a) ? 1 : 0;
        return c;
    }
    /// z [input_count(n)]: the network's input at the estimate x^ [n]; `held`: the filter's (input(a, .) per state,
    /// in the box where one is drawn), else training's (standardised, never held).
    void input_row(double* z, const double* xhat, int n, bool held) const {
        for (int a = 0, c = 0; a < n; ++a) {
            if (is_periodic(a)) {
                z[c++] = std::cos(xhat[a]);
                z[c++] = std::sin(xhat[a]);
            } else {
                z[c++] = held ? input(a, xhat[a]) : (xhat[a] - shift[a]) / spread[a];
            }
        }
    }
    std::vector<double> xt0;         // [n]
    double rate = 1.0;               // K = rate * diag(dx) o diag(dy)^-1  [1/s]
    double storage_scale = 1.0;      // S = c D^-1 (M M' + eps I) D^-1
    double eps = 1e-3;
    double h2_weight = 0.1;          // eta
    // errors per estimate G (sampling.errors_per_estimate): in a minibatch idx, samples idx[r G .. r G + G - 1]
    // share one estimate (z, t, Hx), so the network, S(t), its Cholesky factor and K run once per estimate
    // (docs/method.md section 16.3); M is a multiple of G. 1: every sample has its own estimate.
    int group = 1;
    GainLossParams loss;             // xt0 points into this spec's xt0 at call time
    // Time-varying storage (knots > 0, docs/method.md section 16.7): S(t) from knot vectors s_0..s_J at
    // t_j = knot_time(j) (linear between knots, constant after span), M = diag(exp(.)) + strict tril(.), and the gain
    // head K = rho S(t)^-1 (H(x^)' + D^-1 o diag(dy)) (the game's minimiser for the linearised output plus the
    // network's correction). knots = 0: the constant S and K = rate D o diag(dy)^-1 of sections 16.1-16.4.
    int knots = 0;
    double knot_span = 1.0;          // [s]
    // network.knot_ratio (section 16.7, "Graded knots"): the last knot interval over the first. 1: t_j = j span / J;
    // r > 1: intervals h_0 q^j, q = r^(1/(J - 1)), closer together near t = 0 where the filter's transient is
    double knot_ratio = 1.0;
    /// t_j, the time of knot j (0 before the first, span after the last)
    double knot_time(int j) const {
        if (j <= 0) return 0.0;
        if (j >= knots) return knot_span;
        if (knot_ratio == 1.0 || knots < 2) return j * knot_span / knots;
        const double lq = std::log(knot_ratio) / (knots - 1);
        return knot_span * std::expm1(j * lq) / std::expm1(knots * lq);
    }
    // The Kalman-form head (discrete-time systems, network.gain_head = "kalman", docs/method.md section 16.16): the
    // network's n(n+1)/2 outputs give P(x^) = kalman_scale D (M M' + eps I) D, M = I + tril(o), D = diag(dx), and
    // K = F P H' (H P H' + diag(dy)^2)^-1 with F, H the Jacobians at the estimate (HjieSystemView::Fx, Hx).
    bool kalman = false;
    double kalman_scale = 1.0;
    // the storage's per-state scale D_s in S(t) = c D_s^-1 (M M' + eps I) D_s^-1 (empty: dx); with
    // network.storage_scaling = "output" it makes the initial Riccati gain K H ~ rate on every measured state
    std::vector<double> sdx;
    // the Riccati head's correction scale w [n x m]: K = rho S^-1 (H' + o .* w) (empty: w_aj = dy_j / dx_a)
    std::vector<double> corr;
    // the gain's structural zeros (network.gain_structure = "components", docs/method.md section 16.17): K_aj is kept
    // only where state a and output j are in one component of the system's dependency graph, 0 elsewhere [n x m]
    // (1 or 0; empty: every entry kept). Applied to K where it is used (gain_mask below); the heads form K unmasked.
    std::vector<double> mask;
    // and the storage's: S(t)'s factor M has no entry between two components, so S is block-diagonal and V splits
    // into one storage per component [n(n+1)/2, the packing of tril] (1 or 0; empty: every entry). The entries held at
    // 0 start at 0 and their gradient is 0 (hold_storage)
    std::vector<double> smask;
    /// The storage parameters' (gradient's) entries between components set to 0, for every knot.
    template <typename T>
    void hold_storage(T* sparams, int n) const {
        const int np = n * (n + 1) / 2, sets = knots > 0 ? knots + 1 : 1;
        for (int j = 0; j < sets && !smask.empty(); ++j)
            for (int e = 0; e < np; ++e)
                if (smask[e] == 0.0) sparams[j * np + e] = T(0);
    }
    const double* storage_dx() const { return sdx.empty() ? dx.data() : sdx.data(); }
    /// Km = mask .* K (Km may be K); a copy when there is no mask.
    void gain_mask(double* Km, const double* K, int n, int m_out) const {
        for (int e = 0; e < n * m_out; ++e) Km[e] = mask.empty() || mask[e] != 0.0 ? K[e] : 0.0;
    }
    int storage_params(int n) const { return enabled ? (knots > 0 ? knots + 1 : 1) * (n * (n + 1) / 2) : 0; }
};

}  // namespace hinf::kern
