// The SDP solver binding: our SdpProblem handed to SDPA 7's callable library, and its answer mapped back.
// The only file that includes SDPA's headers (they bring `using namespace std`, MUMPS and pthread).
#include "lmi/sdp.hpp"

#include <sdpa_call.h>

#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "hinf/error.hpp"
#include "mlp.hpp"

namespace hinf::lmi {

const char* sdp_status_name(SdpStatus s) {
    switch (s) {
        case SDP_STATUS_OPTIMAL: return "optimal";
        case SDP_STATUS_INFEASIBLE: return "infeasible";
        case SDP_STATUS_UNBOUNDED: return "unbounded";
        case SDP_STATUS_NOT_CONVERGED: return "not_converged";
        case SDP_STATUS_NUMERICAL_TROUBLE: return "numerical_trouble";
    }
    return "unknown";
}

Eigen::MatrixXd sdp_block_value(const SdpBlock& block, const std::vector<double>& x) {
    Eigen::MatrixXd v = block.constant;
    for (const auto& t : block.terms) v += x[t.first] * t.second;
    return v;
}

SdpResult sdp_solve(const SdpProblem& problem, const SdpOptions& options) {
    HINF_CHECK(problem.num_vars > 0, "SDP with no decision variables (nothing to solve)");
    HINF_CHECK(static_cast<int>(problem.cost.size()) == problem.num_vars, "SDP cost vector length != number of variables");
    HINF_CHECK(!problem.blocks.empty(), "SDP with no constraint blocks");
    for (const auto& b : problem.blocks) {
        const auto n = b.constant.rows();
        HINF_CHECK(n > 0 && b.constant.cols() == n, "SDP block '" + b.name + "' is not square");
        for (const auto& t : b.terms) {
            HINF_CHECK(t.first >= 0 && t.first < problem.num_vars, "SDP block '" + b.name + "' names a variable out of range");
            HINF_CHECK(t.second.rows() == n && t.second.cols() == n, "SDP block '" + b.name + "' has a term of the wrong size");
        }
    }

    // SDPA's x-problem: minimise sum_k c_k x_k  s.t.  X = sum_k F_k x_k - F_0 >= 0. So F_0 = -(our F0).
    SDPA solver;
    solver.setParameterType(SDPA::PARAMETER_STABLE_BUT_SLOW);
    solver.setParameterMaxIteration(options.max_iterations);
    solver.setParameterEpsilonStar(options.epsilon);
    solver.setParameterEpsilonDash(options.feasibility_epsilon);
    solver.setDisplay(options.verbose ? stdout : nullptr);
    solver.setResultFile(nullptr);
    solver.setNumThreads(1);  // we may be inside an OpenMP region; results must not depend on threads

    const int m = problem.num_vars;
    const int nb = static_cast<int>(problem.blocks.size());
    solver.inputConstraintNumber(m);
    solver.inputBlockNumber(nb);
    for (int l = 0; l < nb; ++l) {
        solver.inputBlockSize(l + 1, static_cast<int>(problem.blocks[l].constant.rows()));
        solver.inputBlockType(l + 1, SDPA::SDP);
    }
    solver.initializeUpperTriangleSpace();
    for (int k = 0; k < m; ++k) solver.inputCVec(k + 1, problem.cost[k]);
    for (int l = 0; l < nb; ++l) {
        const SdpBlock& b = problem.blocks[l];
        const int n = static_cast<int>(b.constant.rows());
        for (int i = 0; i < n; ++i)
            for (int j = i; j < n; ++j)
                if (b.constant(i, j) != 0.0) solver.inputElement(0, l + 1, i + 1, j + 1, -b.constant(i, j));
        for (const auto& t : b.terms)
            for (int i = 0; i < n; ++i)
                for (int j = i; j < n; ++j)
                    if (t.second(i, j) != 0.0) solver.inputElement(t.first + 1, l + 1, i + 1, j + 1, t.second(i, j));
    }
    // SDPA writes remarks ("Strange behavior : primal < dual") to std::cout: keep them in the result instead.
    std::ostringstream remarks;
    std::streambuf* saved = std::cout.rdbuf(remarks.rdbuf());
    // SDPA's BLAS is OpenBLAS: at the process's starting thread count, so that the answer does not depend on whether
    // the MLP's OpenBLAS path (one thread, kern::gemm_prepare) ran first. Found on an AVX2 machine, where the MLP runs
    // through OpenBLAS: a GLF designed in the CLI and in the Python module differed. One thread throughout is not the
    // fix: the missile's 8-vertex GLF LMI then comes back infeasible (SDPA pdINF; tests/filters/test_glf.cpp).
    const kern::BlasThreadsAtStart blas_threads;
    solver.initializeUpperTriangle();
    solver.initializeSolve();
    solver.solve();
    std::cout.rdbuf(saved);

    SdpResult r;
    char phase[64] = {0};
    solver.getPhaseString(phase);
    r.solver_phase = phase;
    while (!r.solver_phase.empty() && r.solver_phase.back() == ' ') r.solver_phase.pop_back();
    r.solver_remarks = remarks.str();
    r.iterations = solver.getIteration();
    r.primal_objective = solver.getPrimalObj();
    r.dual_objective = solver.getDualObj();
    const double* xv = solver.getResultXVec();
    r.x.assign(xv, xv + m);
    // SDPA 7's PhaseType enum calls the problem in x the dual (its primal is  max F0.Y  s.t. F_k.Y = c_k,
    // Y >= 0), so infeasible LMIs show as dINF / pUNBD and an objective unbounded below as pINF / dUNBD.
    // Its phase *string* (solver_phase) uses the opposite naming: for infeasible LMIs the enum is pUNBD and
    // the string "dUNBD". We map from the enum; tests/lmi/test_sdp.cpp pins both cases down.
    switch (solver.getPhaseValue()) {
        case SDPA::pdOPT: r.status = SDP_STATUS_OPTIMAL; break;
        case SDPA::pFEAS_dINF:
        case SDPA::pUNBD:
        case SDPA::pdINF: r.status = SDP_STATUS_INFEASIBLE; break;
        case SDPA::pINF_dFEAS:
        case SDPA::dUNBD: r.status = SDP_STATUS_UNBOUNDED; break;
        case SDPA::pFEAS:
        case SDPA::dFEAS:
        case SDPA::pdFEAS: r.status = SDP_STATUS_NOT_CONVERGED; break;
        default: r.status = SDP_STATUS_NUMERICAL_TROUBLE; break;
    }
    for (double v : r.x)
        if (!std::isfinite(v)) r.status = SDP_STATUS_NUMERICAL_TROUBLE;
    solver.terminate();
    return r;
}

}  // namespace hinf::lmi
