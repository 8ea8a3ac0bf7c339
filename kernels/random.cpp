// Philox4x32-10 draws keyed by (seed, stream) with counter (block, a, b); Box-Muller for normals.
#include "random.hpp"

#include <Random123/boxmuller.hpp>
#include <Random123/philox.h>
#include <Random123/uniform.hpp>

namespace hinf::kern {

namespace {

using Philox = r123::Philox4x32;

// One block of 4 x 32 random bits for block index `block`.
inline Philox::ctr_type draw_block(std::uint64_t seed, std::uint32_t stream, std::uint64_t a, std::uint64_t b,
                                   std::uint64_t block) {
    Philox gen;
    Philox::key_type key = {{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32)}};
    // The counter packs block (32 bits), a (32 bits), b (32 bits) and stream: 2^32 blocks per (a, b).
    Philox::ctr_type ctr = {{static_cast<std::uint32_t>(block), static_cast<std::uint32_t>(a),
                             static_cast<std::uint32_t>(b), stream ^ (static_cast<std::uint32_t>(a >> 32) << 8) ^
                                                               (static_cast<std::uint32_t>(b >> 32) << 20)}};
    return gen(ctr, key);
}

}  // namespace

// Calls emit(block, u0, u1) for every block of two 64-bit draws covering `count` outputs.
template <typename Emit>
void for_each_block(std::int64_t count, std::uint64_t seed, std::uint32_t stream, std::uint64_t a, std::uint64_t b,
                    Emit emit) {
    const std::int64_t blocks = (count + 1) / 2;
#pragma omp parallel for schedule(static) if (blocks > 4096)
    for (std::int64_t blk = 0; blk < blocks; ++blk) {
        Philox::ctr_type r = draw_block(seed, stream, a, b, static_cast<std::uint64_t>(blk));
        emit(blk, (static_cast<std::uint64_t>(r[0]) << 32) | r[1], (static_cast<std::uint64_t>(r[2]) << 32) | r[3]);
    }
}

void rng_normal(double* out, std::int64_t count, std::uint64_t seed, std::uint32_t stream, std::uint64_t a,
                std::uint64_t b) {
    for_each_block(count, seed, stream, a, b, [&](std::int64_t blk, std::uint64_t u0, std::uint64_t u1) {
        r123::double2 z = r123::boxmuller(u0, u1);
        out[2 * blk] = z.x;
        if (2 * blk + 1 < count) out[2 * blk + 1] = z.y;
    });
}

void rng_uniform(double* out, std::int64_t count, std::uint64_t seed, std::uint32_t stream, std::uint64_t a,
                 std::uint64_t b) {
    for_each_block(count, seed, stream, a, b, [&](std::int64_t blk, std::uint64_t u0, std::uint64_t u1) {
        out[2 * blk] = r123::u01<double>(u0);
        if (2 * blk + 1 < count) out[2 * blk + 1] = r123::u01<double>(u1);
    });
}

}  // namespace hinf::kern
