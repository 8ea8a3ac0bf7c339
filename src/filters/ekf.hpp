// The extended Kalman filter on the discrete model of filter.hpp (the step the truth is simulated with), told
// the noise statistics in FilterModel. Not the UKF (ukf.hpp) nor the particle filter (pf.hpp).
#pragma once
#include <functional>
#include <memory>

#include <Eigen/Dense>

#include "filters/filter.hpp"

namespace hinf {

/// Extended Kalman filter (Jazwinski 1970; discrete-time form, Simon, Optimal State Estimation, 13.2), with the
/// system's exact Jacobians and the Joseph-form covariance update.
std::unique_ptr<OnlineFilter> make_ekf(const FilterModel& model);

/// ekf_predict's matrices, kept by its caller between steps (sized at the first): the Jacobians, F P+, F P+ F'
/// (row-major: the type Eigen gave that product's temporary when it was one expression, so the same bits) and the
/// symmetrisation's sum.
struct EkfPredictScratch {
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> F, Gr, FPFt;
    Eigen::MatrixXd Phi, G, FP, sym;
};

/// The EKF's prediction from the corrected x^+ [n] and P+ [n x n], shared with the extended H-infinity filter
/// (ehf.hpp): x_next = step(x^+), P_next = F P+ F' + process(G) symmetrised, F and G the step's Jacobians at x^+
/// (models/system.hpp). false where x_next or P_next is not finite.
bool ekf_predict(const FilterModel& model, double t, const Eigen::VectorXd& xu, const Eigen::MatrixXd& Pu,
                 const std::function<Eigen::MatrixXd(const Eigen::MatrixXd&)>& process, Eigen::VectorXd* xn,
                 Eigen::MatrixXd* Pn, EkfPredictScratch* scratch);

}  // namespace hinf
