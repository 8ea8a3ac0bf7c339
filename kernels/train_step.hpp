// One training step's gradient over a minibatch, split over OpenMP threads in fixed-size chunks:
// each chunk runs forward -> head -> HJIE loss -> backward and writes its own partial gradient; the
// partials are summed in chunk order, so the result does not depend on the number of threads.
// Not the time-step loop or the sampling of errors (src/train/trainer.cpp, src/train/samples.cpp), not the Adam update (adam.hpp).
//
// Shape legend: M = minibatch, C = chunk size, n = states, P = parameters, O = network outputs.
#pragma once
#include <cstdint>
#include <cstdlib>
#include <new>
#include <vector>

#include "gain_params.hpp"
#include "head.hpp"
#include "hjie.hpp"
#include "mlp.hpp"

namespace hinf::kern {

struct StepConfig {
    MlpShape shape;
    HeadParams head;
    HjieParams hjie;
    HjieObjective objective = HJIE_OBJECTIVE_DISSIPATIVE;
    double input_scale = 1.0;  // network input = x~ / input_scale (seed 000 Remark 6)
    int chunk = 100;           // samples per chunk: fixed, never derived from the thread count
    GainSpec gain;             // variant `gain` only (enabled): K(x^) head and storage S (gain.hpp)
};

/// Allocator of cache-line (64 B) aligned storage: the own kernels' vector loads of packed panels and
/// activation rows then never straddle two lines (std::vector's large blocks start 16 B past a page).
template <typename T>
struct LineAligned {
    using value_type = T;
    LineAligned() = default;
    template <typename U>
    LineAligned(const LineAligned<U>&) {}
    T* allocate(std::size_t n) {
        const std::size_t bytes = (n * sizeof(T) + 63) / 64 * 64;
        if (void* p = std::aligned_alloc(64, bytes ? bytes : 64)) return static_cast<T*>(p);
        throw std::bad_alloc();
    }
    void deallocate(T* p, std::size_t) { std::free(p); }
    template <typename U>
    bool operator==(const LineAligned<U>&) const { return true; }
    template <typename U>
    bool operator!=(const LineAligned<U>&) const { return false; }
};
template <typename T>
using LineVector = std::vector<T, LineAligned<T>>;

/// Elements per chunk in StepWorkspace::acts (a multiple of 16, so that every chunk starts on a line).
std::int64_t step_acts_stride(const StepConfig& cfg);
/// Elements per chunk in StepWorkspace::partial (P rounded up to a multiple of 16).
std::int64_t step_partial_stride(const MlpShape& shape);
/// Doubles per chunk in StepWorkspace::work.
std::int64_t step_work_stride(const StepConfig& cfg);

template <typename T>
struct StepWorkspace {
    int capacity = 0;  // samples
    LineVector<T> input, acts, dout, scratch, partial;
    LineVector<T> pack;  // mlp_pack_weights(theta) of the current call (GEMM_OWN)
    std::vector<double> p, P;
    std::vector<double> K;  // gain variant: per-sample K [n x m]; P then holds per-sample dL/dS
    std::vector<double> storage;  // gain variant with S(t): per sample S, dS/dt, chol(S), M, dM/dt [5 x n x n]
    std::vector<HjieSampleValue> values;
    std::vector<double> work;  // per chunk: step_work_stride doubles of scratch (sized from n: any state count)
    void reserve(const StepConfig& cfg, int max_batch);
};

struct StepLoss {
    double loss = 0;   // L = sqrt(mean hinge) + eta * mean h2 (paper: sqrt(mean eps^2))
    double hinge = 0;  // sqrt(mean hinge)
    double h2 = 0;     // mean h2 (before eta)
};

/// A data-parallel split of step_gradient's chunks over processes (issue 16). Process `rank` of `ranks`
/// computes chunks [step_split_begin(chunks, rank, ranks), step_split_begin(chunks, rank + 1, ranks)) of the
/// minibatch; `allgather` then gives every process every process's items (base holds [begin[r], begin[r + 1])
/// of item_bytes each from rank r). The chunks, and so the sums in chunk order, do not depend on `ranks`.
struct StepSplit {
    int rank = 0, ranks = 1;
    void (*allgather)(void* base, std::int64_t item_bytes, const std::int64_t* begin) = nullptr;
};
/// First chunk of rank r: consecutive blocks of chunks.
inline int step_split_begin(int chunks, int r, int ranks) { return int(std::int64_t(chunks) * r / ranks); }

/// grad [P] = dL/dtheta over samples idx[0..M) of sys (overwritten). Returns the loss at theta. With a split,
/// every process passes the same theta, idx and M and gets the same bits as one process without a split.
template <typename T>
StepLoss step_gradient(T* grad, const T* theta, const HjieSystemView& sys, const std::int64_t* idx, int M,
                       const StepConfig& cfg, StepWorkspace<T>& ws, const StepSplit* split = nullptr);

/// grad [P] = 0 + partial_0 + partial_1 + ... (partial [chunks x stride], each chunk's first P entries), summed
/// in chunk order for every component, whatever the thread count. The one deterministic reduction of every
/// variant's gradient.
template <typename T>
void sum_chunk_partials(T* grad, const T* partial, int chunks, std::int64_t stride, std::int64_t P);

/// The own GEMM kernels' weight panels of theta (mlp_pack_weights) in `pack`, resized, and a pointer to them; null
/// where the shape's GEMM path is not GEMM_OWN (the others need none). What the `pack` argument of mlp_forward,
/// network_eval and gain_network_eval takes: a caller whose theta does not change between calls (a frozen network)
/// packs once instead of once a call.
template <typename T>
const T* step_pack_weights(LineVector<T>& pack, const T* theta, const MlpShape& shape);

/// step_pack_weights for a caller whose theta changes rarely (a frozen network; the on-line retrainer, between its
/// retrainings): packed at the first get() after construction or stale(), not at every evaluation. It keeps no
/// pointer into itself, so a copy is safe.
template <typename T>
class PackedWeights {
public:
    const T* get(const T* theta, const MlpShape& shape) {
        if (stale_) {
            step_pack_weights(pack_, theta, shape);
            stale_ = false;
        }
        return pack_.empty() ? nullptr : pack_.data();
    }
    void stale() { stale_ = true; }  ///< theta changed: pack again at the next get()

private:
    LineVector<T> pack_;
    bool stale_ = true;
};

/// Forward only: p [count x n] = dV/dx~ at xt [count x n]; P [count x n x n] for the quadratic head
/// (may be null). count <= ws.capacity. pack: step_pack_weights(theta) or null (then packed here, into ws.pack).
template <typename T>
void network_eval(double* p, double* P, const T* theta, const double* xt, std::int64_t count, const StepConfig& cfg,
                  StepWorkspace<T>& ws, const T* pack = nullptr);

}  // namespace hinf::kern
