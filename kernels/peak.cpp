// Register-FMA peak loop (see peak.hpp): 12 independent accumulators hide the FMA latency.
#include "peak.hpp"

#include <immintrin.h>

namespace hinf::kern {

namespace {
constexpr int kAcc = 12;
}

std::string simd_name() {
#if defined(__AVX512F__)
    return "AVX-512";
#elif defined(__AVX2__) && defined(__FMA__)
    return "AVX2+FMA";
#else
    return "SSE2 (no FMA)";
#endif
}

double fma_peak_loop(std::int64_t iterations, bool use_double) {
#if defined(__AVX512F__)
    if (use_double) {
        __m512d acc[kAcc];
        for (int i = 0; i < kAcc; ++i) acc[i] = _mm512_set1_pd(1.0 + 1e-3 * i);
        const __m512d a = _mm512_set1_pd(0.999999), b = _mm512_set1_pd(1e-7);
        for (std::int64_t it = 0; it < iterations; ++it)
            for (int i = 0; i < kAcc; ++i) acc[i] = _mm512_fmadd_pd(acc[i], a, b);
        double sink = 0;
        for (int i = 0; i < kAcc; ++i) sink += _mm512_reduce_add_pd(acc[i]);
        volatile double keep = sink;
        (void)keep;
        return 2.0 * 8 * kAcc * double(iterations);
    }
    __m512 acc[kAcc];
    for (int i = 0; i < kAcc; ++i) acc[i] = _mm512_set1_ps(1.0f + 1e-3f * i);
    const __m512 a = _mm512_set1_ps(0.999999f), b = _mm512_set1_ps(1e-7f);
    for (std::int64_t it = 0; it < iterations; ++it)
        for (int i = 0; i < kAcc; ++i) acc[i] = _mm512_fmadd_ps(acc[i], a, b);
    float sink = 0;
    for (int i = 0; i < kAcc; ++i) sink += _mm512_reduce_add_ps(acc[i]);
    volatile float keep = sink;
    (void)keep;
    return 2.0 * 16 * kAcc * double(iterations);
#elif defined(__AVX2__) && defined(__FMA__)
    if (use_double) {
        __m256d acc[kAcc];
        for (int i = 0; i < kAcc; ++i) acc[i] = _mm256_set1_pd(1.0 + 1e-3 * i);
        const __m256d a = _mm256_set1_pd(0.999999), b = _mm256_set1_pd(1e-7);
        for (std::int64_t it = 0; it < iterations; ++it)
            for (int i = 0; i < kAcc; ++i) acc[i] = _mm256_fmadd_pd(acc[i], a, b);
        alignas(32) double out[4];
        double sink = 0;
        for (int i = 0; i < kAcc; ++i) {
            _mm256_store_pd(out, acc[i]);
            sink += out[0] + out[1] + out[2] + out[3];
        }
        volatile double keep = sink;
        (void)keep;
        return 2.0 * 4 * kAcc * double(iterations);
    }
    __m256 acc[kAcc];
    for (int i = 0; i < kAcc; ++i) acc[i] = _mm256_set1_ps(1.0f + 1e-3f * i);
    const __m256 a = _mm256_set1_ps(0.999999f), b = _mm256_set1_ps(1e-7f);
    for (std::int64_t it = 0; it < iterations; ++it)
        for (int i = 0; i < kAcc; ++i) acc[i] = _mm256_fmadd_ps(acc[i], a, b);
    alignas(32) float out[8];
    float sink = 0;
    for (int i = 0; i < kAcc; ++i) {
        _mm256_store_ps(out, acc[i]);
        for (float v : out) sink += v;
    }
    volatile float keep = sink;
    (void)keep;
    return 2.0 * 8 * kAcc * double(iterations);
#else
    double acc[kAcc];
    for (int i = 0; i < kAcc; ++i) acc[i] = 1.0 + 1e-3 * i;
    for (std::int64_t it = 0; it < iterations; ++it)
        for (int i = 0; i < kAcc; ++i) acc[i] = acc[i] * 0.999999 + 1e-7;
    double sink = 0;
    for (double v : acc) sink += v;
    volatile double keep = sink;
    (void)keep;
    (void)use_double;
    return 2.0 * kAcc * double(iterations);
#endif
}

}  // namespace hinf::kern
