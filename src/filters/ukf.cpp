// See ukf.hpp.
#include "filters/ukf.hpp"
#include "filters/psd_sqrt.hpp"

#include <Eigen/Dense>
#include <cmath>

namespace hinf {

namespace {

using Mat = Eigen::MatrixXd;
using Vec = Eigen::VectorXd;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Unscented Kalman filter, additive noise (Julier & Uhlmann 1997; Wan & van der Merwe 2000), scaled
// sigma points (alpha, beta, kappa); default 1, 2, 0 (lambda = 0: no negative weights).
class UnscentedKalmanFilter final : public OnlineFilter {
public:
    UnscentedKalmanFilter(const FilterModel& model, double alpha, double beta, double kappa) : model_(model) {
        const int n = model.system->state_dim();
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
        nis_ = NAN;
    }
    FilterStatus step(const FilterInput& in) override {
        const System& sys = *model_.system;
        const int n = sys.state_dim(), nv = sys.disturbance_dim(), m = sys.output_dim(), ns = 2 * n + 1;
        // measurement update: sigma points of (x^-, P^-) through C
        RowMat &X = X_, &Z = Z_;  // the step's matrices live in the filter (sized once, not each step)
        X.resize(ns, n);
        Z.resize(ns, m);
        if (!sigma_points(&X, x_, P_)) return FILTER_DIVERGED;
        sys.measurement(Z.data(), X.data(), in.t, ns);
        // an angle output: the mean of the points' differences from the centre's
        const Vec zbar = sys.wraps_outputs() ? centred_mean(Z, [&](double* d, const double* a, const double* b) {
            sys.output_difference(d, a, b);
        }) : plain_mean(Z);
        Mat &S = S_, &Pxz = Pxz_;
        S.setZero(m, m);
        Pxz.setZero(n, m);
        dz_.resize(m);
        dx_.resize(n);
        for (int s = 0; s < ns; ++s) {
            sys.output_difference(dz_.data(), Z.row(s).data(), zbar.data());
            S += wc_[s] * dz_ * dz_.transpose();
            sys.state_difference(dx_.data(), X.row(s).data(), x_.data());  // an angle state's offset wrapped
            Pxz += wc_[s] * dx_ * dz_.transpose();
        }
        if (!model_.noise_chol.empty()) S += noise_covariance(model_, m);  // correlated
        else
            for (int j = 0; j < m; ++j) S(j, j) += model_.noise_std_of(j) * model_.noise_std_of(j);
        Eigen::LLT<Mat>& llt = llt_;
        llt.compute(S);
        if (llt.info() != Eigen::Success) return FILTER_DIVERGED;
        Mat& K = K_;
        K = llt.solve(Pxz.transpose()).transpose();
        Vec& xu = xu_;
        Mat& Pu = Pu_;
        xu = x_;
        Pu = P_;
        nis_ = NAN;
        if (in.y != nullptr) {  // a missing measurement: the prediction alone
            Vec& e = e_;  // y - zbar, an angle output's wrapped
            e.resize(m);
            sys.output_difference(e.data(), in.y, zbar.data());
            nis_ = normalised_square(llt, e);
            xu += K * e;
            Pu = P_ - K * S * K.transpose();
            Pu = 0.5 * (Pu + Pu.transpose()).eval();
        }
        // predict: sigma points of (x^+, P^+) through the Euler step; additive process noise dt B v
        if (!sigma_points(&X, xu, Pu)) return FILTER_DIVERGED;
        RowMat &Xn = Xn_, &G = G_;
        Xn.resize(ns, n);
        G.resize(n, nv);
        system_advance(sys, Xn.data(), X.data(), nullptr, in.t, model_.dt, ns);
        // an angle state: the mean of the points' offsets from the centre's
        const Vec xn = !sys.angle_states().empty() ? centred_mean(Xn, [&](double* d, const double* a, const double* b) {
            sys.state_difference(d, a, b);
        }) : plain_mean(Xn);
        Mat& Pn = Pn_;
        Pn.setZero(n, n);
        for (int s = 0; s < ns; ++s) {
            sys.state_difference(dx_.data(), Xn.row(s).data(), xn.data());
            Pn += wc_[s] * dx_ * dx_.transpose();
        }
        system_advance_jacobian(sys, nullptr, G.data(), xu.data(), in.t, model_.dt);
        Pn += process_noise(Mat(G), model_);
        Pn = 0.5 * (Pn + Pn.transpose()).eval();
        if (!filter_estimate_ok(xn.data(), n) || !Pn.allFinite()) return FILTER_DIVERGED;
        x_ = xn;
        P_ = Pn;
        xf_ = xu;
        return FILTER_OK;
    }
    const double* estimate() const override { return x_.data(); }
    const double* filtered() const override { return xf_.data(); }
    const double* covariance() const override { return P_.data(); }
    double nis() const override { return nis_; }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<UnscentedKalmanFilter>(*this); }

private:
    // the weighted mean of the rows of P (the points through a function)
    Vec plain_mean(const RowMat& P) const {
        Vec mean = Vec::Zero(P.cols());
        for (Eigen::Index s = 0; s < P.rows(); ++s) mean += wm_[s] * P.row(s).transpose();
        return mean;
    }
    // the centre row plus the weighted mean of each row's difference from it (diff(d, a, b): d = a - b wrapped where
    // a component is an angle), so points that straddle +-pi average where they are
    template <class Diff>
    Vec centred_mean(const RowMat& P, Diff diff) const {
        Vec mean = Vec::Zero(P.cols()), d(P.cols());
        for (Eigen::Index s = 0; s < P.rows(); ++s) {
            diff(d.data(), P.row(s).data(), P.row(0).data());
            mean += wm_[s] * d;
        }
        return mean + P.row(0).transpose();
    }

    // rows of X: x, x + sqrt(n + lambda) L_j, x - sqrt(n + lambda) L_j with L L^T = P
    bool sigma_points(RowMat* X, const Vec& x, const Mat& P) {
        const int n = static_cast<int>(x.size());
        Mat& L = L_;
        if (!psd_sqrt(P, &L)) return false;
        L *= std::sqrt(n + lambda_);
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
    Vec x_, xf_;  // x^_{k+1|k}, x^_{k|k}
    Mat P_;
    double nis_ = NAN;  // of the last step's measurement (OnlineFilter::nis)
    // the step's scratch (kept between steps so that a step allocates little)
    Vec dz_, dx_, xu_, e_;
    RowMat X_, Z_, Xn_, G_;
    Mat S_, Pxz_, K_, Pu_, Pn_, L_;
    Eigen::LLT<Mat> llt_;
};

}  // namespace

std::unique_ptr<OnlineFilter> make_ukf(const FilterModel& model, double alpha, double beta, double kappa) {
    return std::make_unique<UnscentedKalmanFilter>(model, alpha, beta, kappa);
}

}  // namespace hinf
