// The `gain` variant (issue 14): a filter gain K(x^) from a network that sees only the estimate, a learned constant
// storage V(x~) = x~^T S x~ with S positive definite, and the dissipation inequality of the filtering game for that
// pair (docs/method.md section 14). Per-sample loss pieces and their gradients with respect to K and S, the
// storage's and the gain head's parameterisations, and the chunked minibatch gradient. Not the sampling of
// (x^, x~) pairs (src/train/gain_samples.cpp) and not any particular system.
//
// Shape legend: N = samples, M = minibatch, n = states, nv = disturbance inputs, m = outputs,
//   K [n x m] row-major gain, S [n x n] storage matrix, o [n x m] raw network output, s [n(n+1)/2] storage params.
#pragma once
#include <cstdint>

#include "hjie.hpp"
#include "train_step.hpp"

namespace hinf::kern {

/// Largest state, output and disturbance count of the gain variant's per-sample stack scratch (n, m, nv <= 32);
/// the config refuses larger systems for this variant in one line (src/config/run_config.cpp).
constexpr int kGainMaxDim = 32;

/// Loss pieces of one sample (x^_i, x~_i):
///   H_i   = x~'Qx~ + 2 s'(dA - K dC) + |B's|^2/rho + |K's|^2/rho,  s = S x~
///           (= sup over v, n of x~'Qx~ + dV/dt - rho |v|^2 - rho |n|^2 for x~' = dA - K dC + B v - K n)
///   S_i   = |x~'Qx~| + 2|s'dA| + 2|s'K dC| + |B's|^2/rho + |K's|^2/rho   (its scale)
///   hinge = relu(H_i / S_i + margin)^2
///   h2    = (x~0'S x~0 / T + sv2 tr(B'S B) + sn2 tr(K'S K)) / h2_reference   (the H2 bound per unit time;
///           with a time-varying storage the initial part is tr(S(0) D^2) / T, once per step, not per sample)

struct GainSampleValue {
    double residual = 0, abs_sum = 0, hinge = 0, h2 = 0;
};

/// With a time-varying storage, Sdot = dS/dt at the sample's time (null: constant S) adds x~'Sdot x~ to H_i and
/// |x~'Sdot x~| to S_i (dV/dt = x~'Sdot x~ + 2 s'x~').
GainSampleValue gain_sample_forward(const double* K, const double* S, const HjieSystemView& s, std::int64_t i,
                                    const GainLossParams& gp, const double* Sdot = nullptr);
/// gK [n x m] = dL/dK (overwritten); gS [n x n] += dL/dS (accumulated), for dL/dhinge_i = d_hinge, dL/dh2_i = d_h2;
/// gSd [n x n] += dL/dSdot when Sdot is given.
void gain_sample_backward(double* gK, double* gS, const double* K, const double* S, const HjieSystemView& s,
                          std::int64_t i, const GainLossParams& gp, double d_hinge, double d_h2,
                          const double* Sdot = nullptr, double* gSd = nullptr);

/// The per-sample H2 term, (w x~0'S x~0 / T + sv2 tr(B'S B) + sn2 tr(K'S K)) / h2_reference (w = initial_weight),
/// for B [n x nv] and K [n x m], the same in continuous and discrete time; and its gradient: gK [n x m] and
/// gS [n x n] += d_h2 * its derivatives (S symmetric).
double gain_h2_value(const double* S, const double* K, const double* B, int n, int nv, int m, const GainLossParams& gp);
void gain_h2_backward(double* gK, double* gS, const double* S, const double* K, const double* B, int n, int nv, int m,
                      const GainLossParams& gp, double d_h2);

/// Time-varying storage (g.knots > 0): S(t) = c D^-1 (M M' + eps I) D^-1 and Sdot = dS/dt, M(t) = diag(exp(.)) +
/// strict tril(.) of the knot vectors interpolated linearly in t (knot j at j span / J; clamped: Sdot = 0 after span).
template <typename T>
void storage_tv_forward(double* S, double* Sdot, const T* s, double t, const GainSpec& g, int n);
/// The two knots' shares of dL/ds for dL/dS = gS, dL/dSdot = gSd (either may be null): d0, d1 [n(n+1)/2]
/// (overwritten) belong to knots *j and *j + 1.
template <typename T>
void storage_tv_backward(double* d0, double* d1, int* j, const double* gS, const double* gSd, const T* s, double t,
                         const GainSpec& g, int n);

/// The Riccati-form head (g.knots > 0): K = rho S^-1 (Hx' + D^-1 o diag(dy)), Hx [m x n] the output Jacobian at
/// the estimate.
/// Lout [n x n] (may be null) receives the Cholesky factor of S, for the backward pass.
template <typename T>
void gain_riccati_forward(double* K, const T* o, const double* S, const double* Hx, const GainSpec& g, int n, int m,
                          double rho, double* Lout = nullptr);
/// d_o = dL/do; gS [n x n] += dL/dS through K (= -S^-1 gK K'). Lin: the forward's Cholesky factor of S (null:
/// recomputed).
template <typename T>
void gain_riccati_backward(T* d_o, double* gS, const double* gK, const double* K, const double* S, const GainSpec& g,
                           int n, int m, double rho, const double* Lin = nullptr);

/// The Kalman-form head (g.kalman: discrete-time systems, docs/method.md section 16.16): P = c D (M M' + eps I) D with
/// M = I + tril(o), D = diag(dx), c = g.kalman_scale; W = H P H' + diag(dy)^2, A = P H' W^-1, K = F A, F [n x n] and
/// H [m x n] the map's and the output's Jacobians at the estimate. K H = F A H with A H similar to a matrix whose
/// eigenvalues lie in [0, 1) for every H: the correction cannot over-correct however steep the sensor.
/// A [n x m] (may be null) receives P H' W^-1, the filtered estimate's gain (x^_k|k = x^ + A e).
template <typename T>
void gain_kalman_forward(double* K, double* A, const T* o, const double* Fx, const double* Hx, const GainSpec& g,
                         int n, int m);
/// d_o [n(n+1)/2] = dL/do (overwritten) for gK = dL/dK: dL/dP = (I - H'A') F'gK W^-1 H, then through P's packing.
template <typename T>
void gain_kalman_backward(T* d_o, const double* gK, const T* o, const double* Fx, const double* Hx, const GainSpec& g,
                          int n, int m);

/// S = c D^-1 (M M' + eps I) D^-1, M = I + tril(s) (row-major lower-triangular packing), D = diag(d).
template <typename T>
void storage_forward(double* S, const T* s, const double* d, int n, double c, double eps);
/// ds [n(n+1)/2] = dL/ds from gS = dL/dS (overwritten).
template <typename T>
void storage_backward(T* ds, const double* gS, const T* s, const double* d, int n, double c);

/// K_ij = rate * dx_i * o_ij / dy_j.
template <typename T>
void gain_head_forward(double* K, const T* o, const double* dx, const double* dy, int n, int m, double rate);
template <typename T>
void gain_head_backward(T* d_o, const double* gK, const double* dx, const double* dy, int n, int m, double rate);

/// grad [P + n(n+1)/2] = dL/dtheta (overwritten), theta = [MLP parameters | storage parameters]; the network input
/// of sample i is row i of z [. x D0] (D0 = shape.inputs() = gain.input_count(n), GainSpec::input_row).
/// L = sqrt(mean hinge) + eta mean h2 over idx[0..M).
/// Fixed chunks of cfg.chunk samples, partials summed in chunk order: the bits do not depend on the thread count.
/// With a split (MPI data parallelism), every process passes the same theta, z, idx and M and gets the same bits
/// as one process without a split; it works on chunks [step_split_begin(chunks, rank, ranks), ...) of
/// gain_step_chunks(M, cfg).
template <typename T>
StepLoss gain_step_gradient(T* grad, const T* theta, const HjieSystemView& sys, const double* z,
                            const std::int64_t* idx, int M, const StepConfig& cfg, StepWorkspace<T>& ws,
                            const StepSplit* split = nullptr);
/// The chunks of a minibatch of M samples: ceil(chunk / G) estimates (rows) each.
int gain_step_chunks(int M, const StepConfig& cfg);

/// The naive twin of gain_step_gradient, the reference for it in tests: one sample at a time through the naive
/// MLP, S(t) and M(t) from the knots by plain loops, K and the backward's S^-1 by Gaussian elimination with
/// partial pivoting (not the fast path's Cholesky), nothing kept between the passes, sums in sample order
/// (so equal to the fast path up to rounding, not bit for bit). Single-threaded.
template <typename T>
StepLoss gain_step_gradient_naive(T* grad, const T* theta, const HjieSystemView& sys, const double* z,
                                  const std::int64_t* idx, int M, const StepConfig& cfg);

/// K [count x n x m] at network inputs z [count x D0] (GainSpec::input_row; the Riccati-form head needs the times
/// t [count] and Hx [count x m x n], the output Jacobians at the estimates; both may be null for knots = 0; the
/// Kalman-form head needs Hx and Fx [count x n x n], the map's Jacobians). A [count x n x m] (may be null; Kalman-form head only)
/// receives the filtered estimate's gains P H' W^-1. pack: step_pack_weights(theta) or null (then packed here, into
/// ws.pack: once a call, which a filter evaluating one estimate a step should not pay).
template <typename T>
void gain_network_eval(double* K, const T* theta, const double* z, const double* Hx, const double* t,
                       std::int64_t count, const StepConfig& cfg, StepWorkspace<T>& ws, const double* Fx = nullptr,
                       double* A = nullptr, const T* pack = nullptr);
/// S [n x n] and Sdot [n x n] (either may be null) at time t: constant S and Sdot = 0 when knots = 0.
template <typename T>
void gain_storage_eval(double* S, double* Sdot, const T* theta, double t, const StepConfig& cfg);

}  // namespace hinf::kern
