// Sample generation around x~(t) and minibatch choice (see sampling.hpp).
#include "sampling.hpp"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "random.hpp"

namespace hinf::kern {

void sample_errors(double* out, const double* center, const double* floor, int n, std::int64_t N,
                   const SamplingParams& sp, std::uint64_t seed, std::uint64_t step) {
    // normals for every component, then one uniform per sample for the radius of the wide ones
    rng_normal(out, N * n, seed, RNG_STREAM_SAMPLES, step, 0);
    std::vector<double> radius(static_cast<std::size_t>(N));
    rng_uniform(radius.data(), N, seed, RNG_STREAM_SAMPLES, step, 1);
    const std::int64_t local = static_cast<std::int64_t>(std::llround(sp.local_fraction * double(N)));
    for (std::int64_t i = 0; i < N; ++i) {
        double* x = out + i * n;
        if (i < local) {
            for (int j = 0; j < n; ++j) x[j] = center[j] + sp.local_spread * (std::fabs(center[j]) + floor[j]) * x[j];
        } else {
            const double r = std::pow(10.0, -sp.radius_decades * radius[i]);
            for (int j = 0; j < n; ++j) x[j] = r * (std::fabs(center[j]) + floor[j]) * x[j];
        }
    }
}

void sample_minibatch(std::int64_t* idx, int M, std::int64_t N, std::uint64_t seed, std::uint64_t step,
                      std::uint64_t k, double* work, std::int64_t* perm) {
    // partial Fisher-Yates driven by counter-based uniforms
    rng_uniform(work, M, seed, RNG_STREAM_MINIBATCH, step, k);
    for (std::int64_t i = 0; i < N; ++i) perm[i] = i;
    for (int i = 0; i < M; ++i) {
        std::int64_t span = N - i;
        std::int64_t j = i + std::min<std::int64_t>(span - 1, static_cast<std::int64_t>(work[i] * double(span)));
        std::swap(perm[i], perm[j]);
        idx[i] = perm[i];
    }
}

}  // namespace hinf::kern
