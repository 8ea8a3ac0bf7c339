// `hinf export CHECKPOINT... [--ensemble] --c DIR`: a trained DNN filter (or an ensemble's mean gain) as a
// dependency-free C99 header/source pair (weights as const arrays, the network's forward pass and head, the
// system's A, B, C and dC/dx, the gain law and the measured-mode filter step of filters/dnn.cpp; continuous or
// discrete time). Not a compiler of arbitrary systems: built-in systems are written out by hand-kept C twins,
// expression systems through GiNaC's C print. docs/export.md.
#pragma once
#include <string>
#include <vector>

namespace hinf {

struct ExportOptions {
    std::string dir;              // where PREFIX.h and PREFIX.c go
    std::string prefix = "hinf_filter";  // C identifier prefix and file stem
    bool ensemble = false;        // two or more gain networks: one filter with the mean of their gains
};

struct ExportResult {
    std::vector<std::string> files;  // the paths written
    long long parameters = 0;        // network weights and biases
    long long flops_per_step = 0;    // floating-point operations of one filter step (counted, docs/export.md)
    long long weight_bytes = 0;      // const data of the weights
    std::string variant, precision, system;
    int networks = 1;                // an ensemble's member count
};

/// Writes DIR/PREFIX.h and DIR/PREFIX.c for the network of the one checkpoint, or (opt.ensemble) for the ensemble of
/// two or more gain networks trained on one model (their mean gain, as `hinf compare --ensemble`); throws
/// hinf::Error naming what cannot be exported (a variant without a C gain law, a state name that is a C keyword,
/// a bad prefix, an ensemble member of another variant or model).
ExportResult export_c(const std::vector<std::string>& checkpoints, const ExportOptions& opt);

}  // namespace hinf
