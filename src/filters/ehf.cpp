// See ehf.hpp.
#include "filters/ehf.hpp"

#include <Eigen/Dense>
#include <cmath>

#include "filters/ekf.hpp"
#include "filters/psd_sqrt.hpp"
#include "hinf/error.hpp"

namespace hinf {

namespace {

using Mat = Eigen::MatrixXd;
using Vec = Eigen::VectorXd;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

class ExtendedHinfFilter final : public OnlineFilter {
public:
    ExtendedHinfFilter(const FilterModel& model, const std::vector<double>& Q, double rho)
        : model_(model), rho_(rho) {
        const int n = model_.system->state_dim();
        Q_ = Eigen::Map<const RowMat>(Q.data(), n, n);
        tau_ = model_.system->discrete_time() ? 1.0 : model_.dt;
    }
    std::string name() const override { return "ehf"; }
    void reset(const FilterStart& start) override {
        const int n = model_.system->state_dim();
        x_ = Eigen::Map<const Vec>(start.xhat0.data(), n);
        // the EKF's P0 as it is, though the game's weights are the unit statistics over tau (R = I / tau, process
        // G G' / tau): at rho -> infinity this is the EKF started from tau P0 (tested). P0 / tau, the consistent
        // scale, was measured and not kept: the level then fails along the first steps wherever x^0 is uncertain,
        // and the near-singular corrections there threw the estimate off (docs/compare.md)
        P_ = Eigen::Map<const RowMat>(start.P0.data(), n, n);
        held_ = 0;
    }
    FilterStatus step(const FilterInput& in) override {
        const System& sys = *model_.system;
        const int n = sys.state_dim(), m = sys.output_dim();
        Vec xu = x_;
        Mat Pu = P_;
        if (in.y != nullptr) {  // a missing measurement: the prediction alone
            RowMat H(m, n);
            sys.measurement_jacobian(H.data(), x_.data(), in.t);
            Vec c(m), e(m);
            sys.measurement(c.data(), x_.data(), in.t, 1);
            sys.output_difference(e.data(), in.y, c.data());  // an angle output's wrapped
            // L L' = P (P may be singular: a start told it is exact); P+ = P (I + tau (H'H - Q/rho) P)^-1
            // = L (I + tau L'(H'H - Q/rho) L)^-1 L'
            Mat L;
            if (!psd_sqrt(P_, &L)) return FILTER_DIVERGED;
            const Mat HtH = Mat(H.transpose()) * H;
            Mat M = Mat::Identity(n, n) + tau_ * L.transpose() * (HtH - Q_ / rho_) * L;
            M = 0.5 * (M + M.transpose()).eval();
            Eigen::LLT<Mat> llt(M);
            if (llt.info() != Eigen::Success) {  // the level fails here: a Kalman step with the game's weights
                ++held_;
                M = Mat::Identity(n, n) + tau_ * L.transpose() * HtH * L;
                M = 0.5 * (M + M.transpose()).eval();
                llt.compute(M);
                if (llt.info() != Eigen::Success) return FILTER_DIVERGED;
            }
            Pu = L * llt.solve(Mat(L.transpose()));
            Pu = 0.5 * (Pu + Pu.transpose()).eval();
            xu += tau_ * Pu * H.transpose() * e;
        }
        Vec xn;
        Mat Pn;  // the game's process weight G G' / tau
        if (!ekf_predict(model_, in.t, xu, Pu, [&](const Mat& G) { return Mat(G * G.transpose() / tau_); }, &xn, &Pn,
                         &predict_))
            return FILTER_DIVERGED;
        x_ = xn;
        P_ = Pn;
        xf_ = xu;
        return FILTER_OK;
    }
    const double* estimate() const override { return x_.data(); }
    const double* filtered() const override { return xf_.data(); }
    const double* covariance() const override { return P_.data(); }  // symmetric: layout does not matter
    bool covariance_is_statistical() const override { return false; }  // the game's P, in its own weights
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<ExtendedHinfFilter>(*this); }
    std::int64_t level_steps_held() const { return held_; }
    std::vector<double> run_report() const override { return {double(held_)}; }

private:
    FilterModel model_;
    Mat Q_;
    double rho_, tau_ = 0;
    Vec x_, xf_;  // x^_{k+1}, x^_{k} corrected by y_k
    Mat P_;
    std::int64_t held_ = 0;
    EkfPredictScratch predict_;  // the prediction's matrices between steps
};

}  // namespace

std::unique_ptr<OnlineFilter> make_ehf(const FilterModel& model, const std::vector<double>& Q, double rho) {
    const int n = model.system->state_dim();
    HINF_CHECK(rho > 0 && std::isfinite(rho), "the extended H-infinity filter (ehf) needs a level [filter] rho > 0");
    HINF_CHECK(Q.size() == std::size_t(n) * n, "the extended H-infinity filter (ehf) needs Q [n x n]");
    return std::make_unique<ExtendedHinfFilter>(model, Q, rho);
}

std::int64_t ehf_level_steps_held(const OnlineFilter& f) {
    const auto* e = dynamic_cast<const ExtendedHinfFilter*>(&f);
    return e == nullptr ? -1 : e->level_steps_held();
}

}  // namespace hinf
