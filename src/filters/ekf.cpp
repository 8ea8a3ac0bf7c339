// See ekf.hpp.
#include "filters/ekf.hpp"

#include <Eigen/Dense>
#include <cmath>

namespace hinf {

namespace {

using Mat = Eigen::MatrixXd;
using Vec = Eigen::VectorXd;
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Extended Kalman filter (Jazwinski 1970; the discrete-time form, e.g. Simon, Optimal State Estimation, 13.2).
class ExtendedKalmanFilter final : public OnlineFilter {
public:
    explicit ExtendedKalmanFilter(const FilterModel& model) : model_(model) {}
    std::string name() const override { return "ekf"; }
    void reset(const FilterStart& start) override {
        const int n = model_.system->state_dim();
        x_ = Eigen::Map<const Vec>(start.xhat0.data(), n);
        P_ = Eigen::Map<const RowMat>(start.P0.data(), n, n);
        nis_ = NAN;
    }
    FilterStatus step(const FilterInput& in) override {
        const System& sys = *model_.system;
        const int n = sys.state_dim(), m = sys.output_dim();
        // measurement update with y(t_k); the step's matrices live in the filter (sized once, not each step)
        RowMat& H = H_;
        H.resize(m, n);
        sys.measurement_jacobian(H.data(), x_.data(), in.t);
        c_.resize(m);
        sys.measurement(c_.data(), x_.data(), in.t, 1);
        const double r = model_.noise_std * model_.noise_std;
        rj_.resize(m);  // R = diag(rj): sn^2 per output (model_.noise_weight)
        for (int j = 0; j < m; ++j) rj_[j] = model_.noise_std_of(j) * model_.noise_std_of(j);
        Mat& S = S_;
        S.noalias() = H * P_ * H.transpose();
        const bool full = !model_.noise_chol.empty();  // correlated: R = noise_covariance (filters/filter.hpp)
        const Mat R = full ? noise_covariance(model_, m) : Mat();
        if (full) S += R;
        else S.diagonal() += rj_;
        Eigen::LLT<Mat>& llt = llt_;
        llt.compute(S);
        if (llt.info() != Eigen::Success) return FILTER_DIVERGED;
        Mat& K = K_;
        K = llt.solve(H * P_).transpose();  // P H^T S^-1 (S, P symmetric)
        Vec& xu = xu_;
        Mat& Pu = Pu_;
        xu = x_;
        Pu = P_;
        nis_ = NAN;
        if (in.y != nullptr) {  // a missing measurement: the prediction alone
            e_.resize(m);  // y - C(x^), an angle output's wrapped
            sys.output_difference(e_.data(), in.y, c_.data());
            nis_ = normalised_square(llt, e_);
            xu += K * e_;
            IKH_.noalias() = -K * H;  // I - K H (the same bits as forming it from the identity)
            IKH_.diagonal().array() += 1.0;
            // Joseph form: stays symmetric PSD
            Pu = full                         ? Mat(IKH_ * P_ * IKH_.transpose() + K * R * K.transpose())
                 : model_.noise_weight.empty() ? Mat(IKH_ * P_ * IKH_.transpose() + r * K * K.transpose())
                                               : Mat(IKH_ * P_ * IKH_.transpose() + K * rj_.asDiagonal() * K.transpose());
        }
        // predict to t_{k+1} through the shared step
        if (!ekf_predict(model_, in.t, xu, Pu, [&](const Mat& G) { return process_noise(G, model_); }, &xn_, &Pn_,
                         &predict_))
            return FILTER_DIVERGED;
        x_ = xn_;
        P_ = Pn_;
        xf_ = xu;
        return FILTER_OK;
    }
    const double* estimate() const override { return x_.data(); }
    const double* filtered() const override { return xf_.data(); }
    const double* covariance() const override { return P_.data(); }  // symmetric: layout does not matter
    double nis() const override { return nis_; }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<ExtendedKalmanFilter>(*this); }

private:
    FilterModel model_;
    Vec x_, xf_;  // x^_{k+1|k}, x^_{k|k}
    Mat P_;
    double nis_ = NAN;  // of the last step's measurement (OnlineFilter::nis)
    // step's scratch
    RowMat H_;
    Vec c_, rj_, e_, xu_, xn_;
    Mat S_, K_, Pu_, IKH_, Pn_;
    Eigen::LLT<Mat> llt_;
    EkfPredictScratch predict_;
};

}  // namespace

std::unique_ptr<OnlineFilter> make_ekf(const FilterModel& model) { return std::make_unique<ExtendedKalmanFilter>(model); }

bool ekf_predict(const FilterModel& model, double t, const Vec& xu, const Mat& Pu,
                 const std::function<Mat(const Mat&)>& process, Vec* xn, Mat* Pn, EkfPredictScratch* scratch) {
    const System& sys = *model.system;
    const int n = sys.state_dim(), nv = sys.disturbance_dim();
    EkfPredictScratch& s = *scratch;
    s.F.resize(n, n);  // Phi = d x_next / dx, G = d x_next / dv
    s.Gr.resize(n, nv);
    system_advance_jacobian(sys, s.F.data(), s.Gr.data(), xu.data(), t, model.dt);
    s.Phi = s.F;
    s.G = s.Gr;
    xn->resize(n);
    system_advance(sys, xn->data(), xu.data(), nullptr, t, model.dt);
    s.FP.noalias() = s.Phi * Pu;
    s.FPFt.noalias() = s.FP * s.Phi.transpose();
    *Pn = s.FPFt + process(s.G);
    s.sym = *Pn + Pn->transpose();
    *Pn = 0.5 * s.sym;
    return filter_estimate_ok(xn->data(), n) && Pn->allFinite();
}

}  // namespace hinf
