// One training step's gradient over a minibatch, split over OpenMP threads in fixed-size chunks:
// each chunk runs forward -> head -> HJIE loss -> backward and writes its own partial gradient; the
// partials are summed in chunk order, so the result does not depend on the number of threads.
// Not the time-step loop or the sampling of errors (src/train/driver.cpp), not the Adam update (adam.hpp).
//
// Shape legend: M = minibatch, C = chunk size, n = states, P = parameters, O = network outputs.
#pragma once
#include <cstdint>
#include <vector>

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
};

template <typename T>
struct StepWorkspace {
    int capacity = 0;  // samples
    std::vector<T> input, acts, dout, scratch, partial;
    std::vector<T> pack;  // mlp_pack_weights(theta) of the current call (GEMM_OWN)
    std::vector<double> p, P;
    std::vector<HjieSampleValue> values;
    void reserve(const StepConfig& cfg, int max_batch);
};

struct StepLoss {
    double loss = 0;   // L = sqrt(mean hinge) + eta * mean h2 (paper: sqrt(mean eps^2))
    double hinge = 0;  // sqrt(mean hinge)
    double h2 = 0;     // mean h2 (before eta)
};

/// grad [P] = dL/dtheta over samples idx[0..M) of sys (overwritten). Returns the loss at theta.
template <typename T>
StepLoss step_gradient(T* grad, const T* theta, const HjieSystemView& sys, const std::int64_t* idx, int M,
                       const StepConfig& cfg, StepWorkspace<T>& ws);

/// Forward only: p [count x n] = dV/dx~ at xt [count x n]; P [count x n x n] for the quadratic head
/// (may be null). count <= ws.capacity.
template <typename T>
void network_eval(double* p, double* P, const T* theta, const double* xt, std::int64_t count, const StepConfig& cfg,
                  StepWorkspace<T>& ws);

}  // namespace hinf::kern
