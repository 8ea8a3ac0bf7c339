// Itô delay systems of seed 002 eq. (1) as function objects, the example (47), and the polytope vertices
// (19) computed from their Jacobians at chosen operating points. Not the simulation (delay_sim.hpp).
#pragma once
#include <functional>
#include <vector>

#include "lmi/delay_lmi.hpp"

namespace hinf::lmi {

/// dx = (f + g v) dt + h dW,  dy = (q + k v) dt + j dW  (seed 002 eq. 1), each a function of
/// x = x(t) and xd = x(t - tau(t)). Matrices (g: n x nv, k: l x nv) are written row-major.
/// A system without delay simply ignores xd.
struct DelaySystem {
    int n = 0, l = 0, nv = 0;
    using Fn = std::function<void(const double* x, const double* xd, double* out)>;
    Fn f, g, h, q, k, j;
};

/// Seed 002 eq. (47): the two-state example (l = nv = 1).
DelaySystem delay_example47();

/// Vertex i of (19) at operating point (x_i, xd_i): A0 = df/dx, A1 = df/dxd, C0 = dh/dx, C1 = dh/dxd,
/// Q0 = dq/dx, Q1 = dq/dxd, J0 = dj/dx, J1 = dj/dxd (central differences with relative step `step`),
/// B = g, K = k at the point. `points[i]` holds 2n numbers: x then xd.
std::vector<DelayVertex> delay_vertices_from_jacobians(const DelaySystem& sys,
                                                       const std::vector<std::vector<double>>& points,
                                                       double step = 1e-6);

/// Step (e) of seed 002: inverse-square-distance interpolation weights of the estimate over the vertices,
/// alpha_i = d_i^-2 / sum_m d_m^-2 with d_i the distance of x's chosen coordinates to operating point i.
/// At a vertex (d_i = 0) that vertex gets weight 1. w has one entry per operating point.
void delay_interp_weights(const double* x, const std::vector<std::vector<double>>& points,
                          const std::vector<int>& coordinates, double* w);

}  // namespace hinf::lmi
