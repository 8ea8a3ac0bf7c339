// A register-only FMA loop that measures this machine's floating-point peak, the yardstick for
// `hinf bench`'s fraction-of-peak figures. Not a kernel of the filter.
#pragma once
#include <cstdint>
#include <string>

namespace hinf::kern {

/// Runs `iterations` rounds of independent vector FMAs per calling thread; returns the flops done
/// (2 per multiply-add per lane). `use_double` selects f64 lanes.
double fma_peak_loop(std::int64_t iterations, bool use_double);

/// The vector instruction set the loop (and the compiler's code for the kernels) uses.
std::string simd_name();

}  // namespace hinf::kern
