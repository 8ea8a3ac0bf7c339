// The `gain` variant on discrete-time systems (issue 14, docs/method.md section 16.8): the one-step dissipation
// inequality of x~_{k+1} = e + G w for the storage V = x~'S x~ and the gain K(x^), its closed-form sup over
// w = (v, n), its relative hinge, the concavity hinge and the per-step H2 term, with their gradients with respect
// to K and S. One sample per call; the same interface as gain_sample_forward / gain_sample_backward (gain.hpp),
// which dispatch here when GainLossParams::discrete is set. Not the continuous-time inequality (gain.cpp).
//
// Shape legend: n = states, nv = disturbance inputs, m = outputs, p = nv + m (the game's w = (v, n)),
//   K [n x m] row-major gain, S [n x n] storage matrix, G = [B, -K] [n x p].
#pragma once
#include <cstdint>

#include "gain.hpp"

namespace hinf::kern {

/// Loss pieces of one sample (x^_i, x~_i) of a discrete system x_{k+1} = f(x_k) + B v_k, y_k = h(x_k) + n_k with
/// the filter x^_{k+1} = f(x^_k) + K (y_k - h(x^_k)):  x~_{k+1} = e + G w, e = dA - K dC, G = [B, -K], w = (v, n).
///   Gh = G'S G, A = rho I - Gh (concave in w iff A > 0), u = G'S e, w* = A^-1 u
///   H_i   = x~'Qx~ - x~'S x~ + e'S e + u'A^-1 u
///           (= sup_w x~'Qx~ + V(x~_{k+1}) - V(x~_k) - rho |w|^2; +inf where A is not positive definite)
///   S_i   = |x~'Qx~| + x~'S x~ + e'S e + u'A^-1 u   (its scale: H_i / S_i in (-1, 1])
///   hinge = relu(H_i / S_i + margin)^2 + relu(lambda_max(Gh) / rho - (1 - margin))^2
///           (where A is not positive definite H_i / S_i is taken at its limit 1: the second term alone pushes back)
///   h2    = (x~0'S x~0 / T + sv2 tr(B'S B) + sn2 tr(K'S K)) / h2_reference   (E[V(x~_{k+1})] - V(e): the per-step
///           noise part, sv2, sn2 the per-step variances, T in steps)
/// residual = H_i (+inf where not concave), abs_sum = S_i (there: its finite part). S is used through (S + S')/2.
GainSampleValue gain_discrete_sample_forward(const double* K, const double* S, const HjieSystemView& s, std::int64_t i,
                                             const GainLossParams& gp);
/// gK [n x m] = dL/dK (overwritten); gS [n x n] += dL/dS (accumulated), for dL/dhinge_i = d_hinge, dL/dh2_i = d_h2.
void gain_discrete_sample_backward(double* gK, double* gS, const double* K, const double* S, const HjieSystemView& s,
                                   std::int64_t i, const GainLossParams& gp, double d_hinge, double d_h2);

}  // namespace hinf::kern
