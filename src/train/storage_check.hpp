// Can a constant storage V = x~'Sx~ keep the one-step inequality of a discrete-time `gain` filter at all?
// (docs/method.md section 16.8, "Errors the outputs do not see".) For an error in the null space of the output
// Jacobian H(x^) no gain acts within the step, so to first order the inequality asks
//     Z'(F'SF - S + Q)Z <= 0,   Z a basis of ker H(x^),  F = df/dx(x^),
// at every estimate the filter meets, for one S >= 0, whatever the level rho and the gain. This is a semidefinite
// program in S; SDPA answers it over estimates along the training's truth runs. Not the training (trainer.cpp) and
// not the level rho* (config/game_level.hpp).
#pragma once
#include <Eigen/Dense>
#include <cstdint>
#include <string>

#include "config/run_config.hpp"
#include "train/gain_samples.hpp"

namespace hinf {

struct StorageCheck {
    bool ran = false;            // a discrete-time system with an error direction some output Jacobian misses
    std::int64_t estimates = 0;  // estimates (truth states of the pool's runs) where ker H(x^) was not empty
    int kernel_dim = 0;          // the largest dim ker H(x^) among them
    // max over those estimates of lambda_max(Z'(F'SF - S + Q)Z) at the S SDPA returned (verified by eigenvalues),
    // in the error scales dx (x~ = D u, D = diag(dx); per unit u'u), clipped below at -q_scale; and a lower bound on its
    // minimum over every S >= 0 (SDPA's dual bound): > 0, no constant storage exists
    double mu = 0, mu_lower = 0;
    double q_scale = 0;  // max over the estimates of lambda_max(Z'DQDZ): the size of the Q term mu is measured against
    Eigen::MatrixXd S;                             // the best S found, in the error scales (D S D in state units)
    std::int64_t worst_run = -1, worst_step = -1;  // where it leaves its largest violation
    std::string solver_phase;                      // SDPA's word for the solve (pdOPT, ...)
    bool solved = false;                           // SDPA returned an optimal point, verified by eigenvalues
    /// No constant storage: every S leaves a violation above 10^-6 of the Q term
    bool infeasible() const { return ran && solved && mu_lower > 1e-6 * q_scale; }
};

/// At most this many estimates enter the SDP (spread evenly over the pool's runs and steps; repeated ones once)
inline constexpr std::int64_t kStorageCheckEstimates = 400;
/// ... and fewer for many states, so that the solve stays near a second: 400 up to n = 12, 16 from n = 22 on (n = 24
/// took 42 s with 400). Fewer estimates can only miss an infeasible storage, never claim one.
std::int64_t storage_check_estimates(int n);

/// The check above for cfg (variant gain, discrete time; anything else: ran = false) over `pool`'s truth states.
StorageCheck constant_storage_check(const RunConfig& cfg, const GainPool& pool);

/// max over the check's estimates of lambda_max(Z'(F'SF - S + Q)Z) for S [n x n] in the error scales (S' = D S D of
/// the storage in state units): what the check minimises, for a cross-check by other S (-inf: no estimate)
double constant_storage_violation(const RunConfig& cfg, const GainPool& pool, const Eigen::MatrixXd& S);

/// One line for a check that found no constant storage ("hinf: note: ..."); empty otherwise.
std::string constant_storage_note(const RunConfig& cfg, const StorageCheck& c);

}  // namespace hinf
