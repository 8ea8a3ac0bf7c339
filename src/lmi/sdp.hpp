// A block-diagonal semidefinite program in one standard form, and the call that solves it.
// Not the LMIs of any paper (see delay_lmi.hpp), and not the solver itself: SDPA sits behind sdp_solve().
#pragma once
#include <Eigen/Dense>
#include <string>
#include <utility>
#include <vector>

namespace hinf::lmi {

// Standard form (x = decision variables, m of them):
//     minimise  c' x   subject to   F0_b + sum_i x_i F_ib  >= 0   (positive semidefinite) for every block b.
// A strict LMI M(x) < 0 is posed as  -M(x) - eps I >= 0 by the caller (see delay_lmi.cpp).
struct SdpBlock {
    std::string name;                                // for messages and verification reports
    Eigen::MatrixXd constant;                        // F0_b (symmetric)
    std::vector<std::pair<int, Eigen::MatrixXd>> terms;  // (i, F_ib), symmetric, only non-zero ones
};

struct SdpProblem {
    int num_vars = 0;
    std::vector<double> cost;  // c, length num_vars
    std::vector<SdpBlock> blocks;
};

enum SdpStatus {
    SDP_STATUS_OPTIMAL = 0,          // primal and dual feasible, duality gap closed
    SDP_STATUS_INFEASIBLE = 1,       // the LMIs have no solution (a dual certificate was found)
    SDP_STATUS_UNBOUNDED = 2,        // the objective is unbounded below
    SDP_STATUS_NOT_CONVERGED = 3,    // iteration limit or stalled: feasible point maybe, optimality not shown
    SDP_STATUS_NUMERICAL_TROUBLE = 4,  // the solver could not decide
};
const char* sdp_status_name(SdpStatus s);

struct SdpOptions {
    int max_iterations = 200;
    double epsilon = 1e-6;              // relative duality gap at which the solver may stop (SDPA epsilonStar)
    double feasibility_epsilon = 1e-8;  // primal/dual infeasibility tolerance (SDPA epsilonDash)
    bool verbose = false;
};

struct SdpResult {
    SdpStatus status = SDP_STATUS_NUMERICAL_TROUBLE;
    std::string solver_phase;  // the solver's own word for it (SDPA: pdOPT, pINF_dFEAS, ...)
    std::string solver_remarks;  // anything the solver wrote to stdout while solving
    int iterations = 0;
    double primal_objective = 0;  // c' x at the returned x
    double dual_objective = 0;
    std::vector<double> x;
};

/// Solves the SDP with SDPA (single-threaded: safe inside OpenMP regions). Never throws on numerical
/// failure: the status says what happened. Throws hinf::Error only on malformed input (shapes).
SdpResult sdp_solve(const SdpProblem& problem, const SdpOptions& options = {});

/// F0_b + sum_i x_i F_ib for one block (used to verify a returned point independently of the solver).
Eigen::MatrixXd sdp_block_value(const SdpBlock& block, const std::vector<double>& x);

}  // namespace hinf::lmi
