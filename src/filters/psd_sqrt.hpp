// A square root L L^T = P of a covariance that may be singular (a known initial state, P0 = 0): Cholesky when P is
// positive definite, else the symmetric eigen-decomposition with eigenvalues clipped at 0. Not a general solver.
#pragma once
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace hinf {

/// false when P is not symmetric positive semidefinite (an eigenvalue below -1e-12 max |eigenvalue|) or not finite.
inline bool psd_sqrt(const Eigen::MatrixXd& P, Eigen::MatrixXd* L) {
    Eigen::LLT<Eigen::MatrixXd> llt(P);
    if (llt.info() == Eigen::Success) {
        *L = llt.matrixL();
        return true;
    }
    if (!P.allFinite()) return false;
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(P);
    if (eig.info() != Eigen::Success) return false;
    const Eigen::VectorXd ev = eig.eigenvalues();
    const double scale = std::max(ev.cwiseAbs().maxCoeff(), 1e-300);
    if (ev.minCoeff() < -1e-12 * scale) return false;
    *L = eig.eigenvectors() * ev.cwiseMax(0.0).cwiseSqrt().asDiagonal();
    return true;
}

}  // namespace hinf
