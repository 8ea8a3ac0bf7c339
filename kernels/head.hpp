// Output heads: what the network's raw output o means, per sample.
//   HEAD_GRADIENT  (variant `paper`, seed 000 Fig. 2): the network output is dV/dx~ itself, p = c*o.
//   HEAD_QUADRATIC (default): p = P(x~) x~ with P = c (M M^T + eps I), M = I + tril(o); so p^T x~ > 0
//                  for every x~ != 0 and V(x~) = int_0^1 p(s x~)^T x~ ds > 0 with V(0) = 0.
// Not the loss (hjie.hpp). Shape legend: n = states, O = head_outputs(kind, n).
#pragma once
#include <cstdint>

namespace hinf::kern {

enum Head { HEAD_GRADIENT = 0, HEAD_QUADRATIC = 1 };

struct HeadParams {
    Head kind = HEAD_QUADRATIC;
    int n = 0;           // state dimension
    double scale = 1.0;  // c: units of dV/dx~ per unit output (gradient) or of V / x~^2 (quadratic)
    double eps = 1e-3;   // quadratic head: floor of P's eigenvalues, relative to c
};

/// Network outputs the head needs: n (gradient) or n(n+1)/2 (quadratic).
int head_outputs(Head kind, int n);

/// Doubles of scratch head_forward and head_backward need (2 n^2 for the quadratic head, 0 for the gradient
/// head): the caller owns it, one block per thread, so any state count works without allocating per sample.
std::int64_t head_workspace(Head kind, int n);

/// p [n] = dV/dx~ at x~ [n]; P [n x n] (quadratic head only; may be null for the gradient head).
/// work [head_workspace(kind, n)] is scratch.
template <typename T>
void head_forward(double* p, double* P, const T* o, const double* xt, const HeadParams& hp, double* work);

/// dL/do [O] from gp = dL/dp [n] and gP = dL/dP [n x n] (null: zero). Overwrites d_o. work as head_forward.
template <typename T>
void head_backward(T* d_o, const double* gp, const double* gP, const T* o, const double* xt, const HeadParams& hp,
                   double* work);

}  // namespace hinf::kern
