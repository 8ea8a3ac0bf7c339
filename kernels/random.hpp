// Counter-based random numbers (Random123 Philox4x32-10): every draw is a pure function of
// (seed, stream, a, b, index), so threads share no generator state and a resumed run draws exactly
// what an uninterrupted one would. Not a sampler of any particular distribution of errors: see sampling.hpp.
#pragma once
#include <cstdint>

namespace hinf::kern {

/// Independent streams of one run's seed; values are part of the file format (never renumber).
enum RngStream : std::uint32_t {
    RNG_STREAM_INIT = 1,       // network initialisation
    RNG_STREAM_SAMPLES = 2,    // training samples around x~(t)      (a = time step)
    RNG_STREAM_MINIBATCH = 3,  // minibatch choice                   (a = time step, b = Adam step)
    RNG_STREAM_NOISE = 4,      // on-line disturbance and noise      (a = run, b = time step)
    RNG_STREAM_WIENER = 5,     // seed 002 delay system: Wiener increments and initial function (a = run, b = 0: x(theta), 1: dW)
    RNG_STREAM_PARTICLES = 6,  // particle filter: initial cloud and process noise (a = run, b = 0: init, k+1: step k)
    RNG_STREAM_RESAMPLE = 7,   // particle filter: systematic resampling offset (a = run, b = step)
    RNG_STREAM_HEAVY_TAIL = 8, // compare scenarios: chi-square draws of Student-t noise (a = run, b = time step)
    RNG_STREAM_ROUGHEN = 9,    // particle filter roughening jitter after resampling (a = run, b = step)
    RNG_STREAM_WORST = 10,     // worst-case search: random start points (a = start, b = 0), the same for every filter
    RNG_STREAM_GAIN = 11,      // variant gain: (x^, x~) samples (a = time step, b = 0: normals, 1: uniforms); on-line
                               // check and retraining (a = 2^40 + step, b as before)
};

/// out[i] ~ N(0,1), i in [0, count), for the counter (seed, stream, a, b). Thread-count independent.
void rng_normal(double* out, std::int64_t count, std::uint64_t seed, std::uint32_t stream, std::uint64_t a,
                std::uint64_t b);
/// out[i] ~ U(0,1] likewise.
void rng_uniform(double* out, std::int64_t count, std::uint64_t seed, std::uint32_t stream, std::uint64_t a,
                 std::uint64_t b);

}  // namespace hinf::kern
