// Training samples around the current estimation error x~(t) (seed 000 Fig. 3: "randomly select N
// sample vectors near the error x~(t)"), and the minibatch choice. Counter-based: thread- and
// resume-independent. How the samples spread is documented in docs/method.md ("Sampling").
//
// Shape legend: N = samples, n = states, M = minibatch.
#pragma once
#include <cstdint>

namespace hinf::kern {

struct SamplingParams {
    double local_fraction = 0.5;  // share of samples near x~(t); the rest cover smaller errors (Remark 9)
    double local_spread = 0.1;    // local: x~(t)_j + spread * (|x~(t)_j| + floor_j) * xi_j
    double radius_decades = 4.0;  // wide: 10^(-decades*u) * (|x~(t)_j| + floor_j) * xi_j, u ~ U(0,1)
};

/// out [N x n]: samples around center [n]; floor [n] keeps the spread alive when x~(t)_j ~ 0.
void sample_errors(double* out, const double* center, const double* floor, int n, std::int64_t N,
                   const SamplingParams& sp, std::uint64_t seed, std::uint64_t step);

/// idx [M]: M distinct indices out of [0, N) for Adam step k of time step `step`.
/// work [N] is scratch (doubles).
void sample_minibatch(std::int64_t* idx, int M, std::int64_t N, std::uint64_t seed, std::uint64_t step,
                      std::uint64_t k, double* work, std::int64_t* perm);

}  // namespace hinf::kern
