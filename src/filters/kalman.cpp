// Extended and unscented Kalman filters and the open-loop predictor on the discrete model of filter.hpp
// (the Euler step the truth is simulated with), given the noise statistics in FilterModel.
// Not the particle filter (pf.cpp) nor the DNN filters (dnn.cpp).
#include <Eigen/Dense>
#include <cmath>

#include "filters/filter.hpp"
#include "hinf/error.hpp"

namespace hinf {

namespace {

using Mat = Eigen::MatrixXd;
using Vec = Eigen::VectorXd;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

class OpenLoopFilter final : public OnlineFilter {
public:
    explicit OpenLoopFilter(const FilterModel& model) : model_(model), a_(model.system->state_dim()) {}
    std::string name() const override { return "open_loop"; }
    void reset(const FilterStart& start) override { xhat_ = start.xhat0; }
    FilterStatus step(const FilterInput& in) override {
        const int n = model_.system->state_dim();
        model_.system->drift(a_.data(), xhat_.data(), in.t, 1);
        std::vector<double> next(xhat_);
        for (int i = 0; i < n; ++i) next[i] += model_.dt * a_[i];
        if (!filter_estimate_ok(next.data(), n)) return FILTER_DIVERGED;
        xhat_ = next;
        return FILTER_OK;
    }
    const double* estimate() const override { return xhat_.data(); }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<OpenLoopFilter>(*this); }

private:
    FilterModel model_;
    std::vector<double> xhat_, a_;
};

// Extended Kalman filter (Jazwinski 1970; the discrete-time form, e.g. Simon, Optimal State Estimation, 13.2).
class ExtendedKalmanFilter final : public OnlineFilter {
public:
    explicit ExtendedKalmanFilter(const FilterModel& model) : model_(model) {}
    std::string name() const override { return "ekf"; }
    void reset(const FilterStart& start) override {
        const int n = model_.system->state_dim();
        x_ = Eigen::Map<const Vec>(start.xhat0.data(), n);
        P_ = Eigen::Map<const RowMat>(start.P0.data(), n, n);
    }
    FilterStatus step(const FilterInput& in) override {
        const System& sys = *model_.system;
        const int n = sys.state_dim(), nv = sys.disturbance_dim(), m = sys.output_dim();
        // measurement update with y(t_k)
        RowMat H(m, n);
        sys.measurement_jacobian(H.data(), x_.data(), in.t);
        Vec c(m);
        sys.measurement(c.data(), x_.data(), in.t, 1);
        const double r = model_.noise_std * model_.noise_std;
        Mat S = H * P_ * H.transpose();
        S.diagonal().array() += r;
        Eigen::LLT<Mat> llt(S);
        if (llt.info() != Eigen::Success) return FILTER_DIVERGED;
        Mat K = llt.solve(H * P_).transpose();  // P H^T S^-1 (S, P symmetric)
        Vec xu = x_ + K * (Eigen::Map<const Vec>(in.y, m) - c);
        Mat IKH = Mat::Identity(n, n) - K * H;
        Mat Pu = IKH * P_ * IKH.transpose() + r * K * K.transpose();  // Joseph form: stays symmetric PSD
        // predict to t_{k+1}: Phi = I + dt dA/dx, G = dt B
        RowMat J(n, n), B(n, nv);
        sys.drift_jacobian(J.data(), xu.data(), in.t);
        sys.disturbance_gain(B.data(), xu.data(), in.t, 1);
        Vec a(n);
        sys.drift(a.data(), xu.data(), in.t, 1);
        Mat Phi = Mat::Identity(n, n) + model_.dt * Mat(J);
        Mat G = model_.dt * Mat(B);
        Vec xn = xu + model_.dt * a;
        Mat Pn = Phi * Pu * Phi.transpose() +
                 model_.disturbance_std * model_.disturbance_std * G * G.transpose();
        Pn = 0.5 * (Pn + Pn.transpose()).eval();
        if (!filter_estimate_ok(xn.data(), n) || !Pn.allFinite()) return FILTER_DIVERGED;
        x_ = xn;
        P_ = Pn;
        return FILTER_OK;
    }
    const double* estimate() const override { return x_.data(); }
    const double* covariance() const override { return P_.data(); }  // symmetric: layout does not matter
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<ExtendedKalmanFilter>(*this); }

private:
    FilterModel model_;
    Vec x_;
    Mat P_;
};

// Unscented Kalman filter, additive noise (Julier & Uhlmann 1997; Wan & van der Merwe 2000), scaled
// sigma points with alpha = 1, beta = 2, kappa = 0 (lambda = 0: no negative weights).
class UnscentedKalmanFilter final : public OnlineFilter {
public:
    explicit UnscentedKalmanFilter(const FilterModel& model) : model_(model) {
        const int n = model.system->state_dim();
        const double alpha = 1.0, beta = 2.0, kappa = 0.0;
        lambda_ = alpha * alpha * (n + kappa) - n;
        wm_.assign(2 * n + 1, 1.0 / (2.0 * (n + lambda_)));
        wc_ = wm_;
        wm_[0] = lambda_ / (n + lambda_);
        wc_[0] = wm_[0] + (1.0 - alpha * alpha + beta);
    }
    std::string name() const override { return "ukf"; }
    void reset(const FilterStart& start) override {
        const int n = model_.system->state_dim();
        x_ = Eigen::Map<const Vec>(start.xhat0.data(), n);
        P_ = Eigen::Map<const RowMat>(start.P0.data(), n, n);
    }
    FilterStatus step(const FilterInput& in) override {
        const System& sys = *model_.system;
        const int n = sys.state_dim(), nv = sys.disturbance_dim(), m = sys.output_dim(), ns = 2 * n + 1;
        // measurement update: sigma points of (x^-, P^-) through C
        RowMat X(ns, n), Z(ns, m);
        if (!sigma_points(&X, x_, P_)) return FILTER_DIVERGED;
        sys.measurement(Z.data(), X.data(), in.t, ns);
        Vec zbar = Vec::Zero(m);
        for (int s = 0; s < ns; ++s) zbar += wm_[s] * Z.row(s).transpose();
        Mat S = Mat::Zero(m, m), Pxz = Mat::Zero(n, m);
        for (int s = 0; s < ns; ++s) {
            Vec dz = Z.row(s).transpose() - zbar;
            S += wc_[s] * dz * dz.transpose();
            Pxz += wc_[s] * (X.row(s).transpose() - x_) * dz.transpose();
        }
        S.diagonal().array() += model_.noise_std * model_.noise_std;
        Eigen::LLT<Mat> llt(S);
        if (llt.info() != Eigen::Success) return FILTER_DIVERGED;
        Mat K = llt.solve(Pxz.transpose()).transpose();
        Vec xu = x_ + K * (Eigen::Map<const Vec>(in.y, m) - zbar);
        Mat Pu = P_ - K * S * K.transpose();
        Pu = 0.5 * (Pu + Pu.transpose()).eval();
        // predict: sigma points of (x^+, P^+) through the Euler step; additive process noise dt B v
        if (!sigma_points(&X, xu, Pu)) return FILTER_DIVERGED;
        RowMat A(ns, n), B(n, nv);
        sys.drift(A.data(), X.data(), in.t, ns);
        RowMat Xn = X + model_.dt * A;
        Vec xn = Vec::Zero(n);
        for (int s = 0; s < ns; ++s) xn += wm_[s] * Xn.row(s).transpose();
        Mat Pn = Mat::Zero(n, n);
        for (int s = 0; s < ns; ++s) {
            Vec dx = Xn.row(s).transpose() - xn;
            Pn += wc_[s] * dx * dx.transpose();
        }
        sys.disturbance_gain(B.data(), xu.data(), in.t, 1);
        Mat G = model_.dt * Mat(B);
        Pn += model_.disturbance_std * model_.disturbance_std * G * G.transpose();
        Pn = 0.5 * (Pn + Pn.transpose()).eval();
        if (!filter_estimate_ok(xn.data(), n) || !Pn.allFinite()) return FILTER_DIVERGED;
        x_ = xn;
        P_ = Pn;
        return FILTER_OK;
    }
    const double* estimate() const override { return x_.data(); }
    const double* covariance() const override { return P_.data(); }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<UnscentedKalmanFilter>(*this); }

private:
    // rows of X: x, x + sqrt(n + lambda) L_j, x - sqrt(n + lambda) L_j with L L^T = P
    bool sigma_points(RowMat* X, const Vec& x, const Mat& P) const {
        const int n = static_cast<int>(x.size());
        Eigen::LLT<Mat> llt(P);
        if (llt.info() != Eigen::Success) return false;
        Mat L = std::sqrt(n + lambda_) * Mat(llt.matrixL());
        X->row(0) = x.transpose();
        for (int j = 0; j < n; ++j) {
            X->row(1 + j) = (x + L.col(j)).transpose();
            X->row(1 + n + j) = (x - L.col(j)).transpose();
        }
        return true;
    }

    FilterModel model_;
    double lambda_ = 0;
    std::vector<double> wm_, wc_;
    Vec x_;
    Mat P_;
};

}  // namespace

std::unique_ptr<OnlineFilter> make_open_loop_filter(const FilterModel& model) {
    return std::make_unique<OpenLoopFilter>(model);
}
std::unique_ptr<OnlineFilter> make_ekf(const FilterModel& model) { return std::make_unique<ExtendedKalmanFilter>(model); }
std::unique_ptr<OnlineFilter> make_ukf(const FilterModel& model) {
    return std::make_unique<UnscentedKalmanFilter>(model);
}

}  // namespace hinf
