// Filters against the Kalman filter on a linear-Gaussian system: EKF and UKF equal it to round-off, the
// particle filter's mean converges to it with the particle count. Also the DNN adapter's basics.
#include <Eigen/Dense>
#include <catch2/catch.hpp>
#include <cmath>

#include "filters/dnn.hpp"
#include "filters/filter.hpp"
#include "net/network.hpp"
#include "random.hpp"
#include "filters/ekf.hpp"
#include "filters/open_loop.hpp"
#include "filters/pf.hpp"
#include "filters/ukf.hpp"

using namespace hinf;

namespace {

using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// x' = F x + G v, y = H x + n (time-invariant, n = 3, nv = 2, m = 2)
class LinearSystem final : public System {
public:
    RowMat F{3, 3}, G{3, 2}, H{2, 3};
    LinearSystem() {
        F << -0.5, 1.0, 0.0, -1.0, -0.2, 0.3, 0.1, 0.0, -0.8;
        G << 0.0, 0.0, 1.0, 0.0, 0.5, 1.0;
        H << 1.0, 0.0, 0.0, 0.0, 0.5, 1.0;
    }
    std::string name() const override { return "linear"; }
    int state_dim() const override { return 3; }
    int disturbance_dim() const override { return 2; }
    int output_dim() const override { return 2; }
    void drift(double* a, const double* x, double, std::int64_t count) const override {
        for (std::int64_t s = 0; s < count; ++s)
            Eigen::Map<Eigen::Vector3d>(a + 3 * s) = F * Eigen::Map<const Eigen::Vector3d>(x + 3 * s);
    }
    void disturbance_gain(double* B, const double*, double, std::int64_t count) const override {
        for (std::int64_t s = 0; s < count; ++s) std::copy(G.data(), G.data() + 6, B + 6 * s);
    }
    void measurement(double* c, const double* x, double, std::int64_t count) const override {
        for (std::int64_t s = 0; s < count; ++s)
            Eigen::Map<Eigen::Vector2d>(c + 2 * s) = H * Eigen::Map<const Eigen::Vector3d>(x + 3 * s);
    }
    void drift_jacobian(double* J, const double*, double) const override { std::copy(F.data(), F.data() + 9, J); }
    void measurement_jacobian(double* Hj, const double*, double) const override { std::copy(H.data(), H.data() + 6, Hj); }
    std::vector<std::string> state_names() const override { return {"a", "b", "c"}; }
    std::vector<std::string> state_units() const override { return {"1", "1", "1"}; }
};

// The textbook discrete Kalman filter (Kalman 1960) for x_{k+1} = Phi x_k + dt G v_k, written independently
// of src/filters: standard (not Joseph) covariance update.
struct KalmanReference {
    Eigen::MatrixXd Phi, Qd, H, R, P;
    Eigen::VectorXd x;
    void step(const Eigen::VectorXd& y) {
        Eigen::MatrixXd S = H * P * H.transpose() + R;
        Eigen::MatrixXd K = P * H.transpose() * S.inverse();
        x = x + K * (y - H * x);
        P = (Eigen::MatrixXd::Identity(3, 3) - K * H) * P;
        x = Phi * x;
        P = Phi * P * Phi.transpose() + Qd;
    }
};

struct Setup {
    LinearSystem sys;
    FilterModel model;
    FilterStart start;
    KalmanReference kf;
    std::vector<double> ys;  // [steps x 2]
    std::int64_t steps;
    Setup(double sv, double sn, double p0, std::int64_t steps_) : steps(steps_) {
        model = FilterModel{&sys, 0.05, sv, sn, {}, {}, {}, {}};
        start.xhat0 = {0.5, -0.3, 0.2};
        start.P0 = {p0, 0, 0, 0, p0, 0, 0, 0, p0};
        start.seed = 11;
        kf.Phi = Eigen::MatrixXd::Identity(3, 3) + model.dt * Eigen::MatrixXd(sys.F);
        kf.Qd = sv * sv * model.dt * model.dt * Eigen::MatrixXd(sys.G) * Eigen::MatrixXd(sys.G).transpose();
        kf.H = sys.H;
        kf.R = sn * sn * Eigen::MatrixXd::Identity(2, 2);
        kf.P = p0 * Eigen::MatrixXd::Identity(3, 3);
        kf.x = Eigen::Map<const Eigen::Vector3d>(start.xhat0.data());
        // a truth drawn from the same model (fixed seed 5)
        Eigen::Vector3d x(1.0, 0.0, -0.5);
        std::vector<double> z(4);
        for (std::int64_t k = 0; k < steps; ++k) {
            kern::rng_normal(z.data(), 4, 5, kern::RNG_STREAM_NOISE, 0, std::uint64_t(k));
            Eigen::Vector2d y = sys.H * x + sn * Eigen::Vector2d(z[2], z[3]);
            ys.push_back(y[0]);
            ys.push_back(y[1]);
            x = kf.Phi * x + model.dt * sys.G * (sv * Eigen::Vector2d(z[0], z[1]));
        }
    }
};

double max_rel(const Eigen::VectorXd& a, const double* b, double floor) {
    double w = 0;
    for (int i = 0; i < a.size(); ++i) w = std::max(w, std::fabs(a[i] - b[i]) / std::max(std::fabs(a[i]), floor));
    return w;
}

}  // namespace

TEST_CASE("EKF and UKF equal the Kalman filter on a linear-Gaussian system", "[filters][kalman]") {
    Setup su(2.0, 0.3, 4.0, 400);
    auto ekf = make_ekf(su.model), ukf = make_ukf(su.model);
    ekf->reset(su.start);
    ukf->reset(su.start);
    double worst_x_ekf = 0, worst_x_ukf = 0, worst_P_ekf = 0, worst_P_ukf = 0;
    for (std::int64_t k = 0; k < su.steps; ++k) {
        FilterInput in{su.ys.data() + 2 * k, k * su.model.dt, k, nullptr};
        REQUIRE(ekf->step(in) == FILTER_OK);
        REQUIRE(ukf->step(in) == FILTER_OK);
        su.kf.step(Eigen::Map<const Eigen::Vector2d>(su.ys.data() + 2 * k));
        worst_x_ekf = std::max(worst_x_ekf, max_rel(su.kf.x, ekf->estimate(), 1e-3));
        worst_x_ukf = std::max(worst_x_ukf, max_rel(su.kf.x, ukf->estimate(), 1e-3));
        Eigen::VectorXd Pk = Eigen::Map<const Eigen::VectorXd>(su.kf.P.data(), 9);
        worst_P_ekf = std::max(worst_P_ekf, max_rel(Pk, ekf->covariance(), 1e-6));
        worst_P_ukf = std::max(worst_P_ukf, max_rel(Pk, ukf->covariance(), 1e-6));
    }
    INFO("EKF x " << worst_x_ekf << " P " << worst_P_ekf << "; UKF x " << worst_x_ukf << " P " << worst_P_ukf);
    CHECK(worst_x_ekf < 1e-10);
    CHECK(worst_P_ekf < 1e-10);
    CHECK(worst_x_ukf < 1e-10);
    CHECK(worst_P_ukf < 1e-10);
}

TEST_CASE("particle filter mean converges to the Kalman mean as particles grow", "[filters][pf]") {
    // Few steps, prior not much wider than the likelihood, so the weights stay balanced (ESS ~ N/2).
    // The Monte Carlo error of a weighted mean is ~ sqrt(P_ii / ESS); with ESS >= N/4 and resampling noise
    // the bound 6 sqrt(4 P_ii / N) holds with overwhelming probability (seed 11, fixed).
    const std::int64_t steps = 4;
    // roughening (zero-mean jitter after resampling) must not bias the mean either
    for (double K : {0.0, 0.2})
    for (std::int64_t N : {400, 40000}) {
        Setup su(2.0, 0.8, 0.5, steps);
        auto pf = make_particle_filter(su.model, N, K > 0 ? 1.0 : 0.5, K);  // K > 0: resample (and roughen) every step
        CHECK(pf->name() == (K > 0 ? "pf_roughened" : "pf"));
        pf->reset(su.start);
        double worst = 0;  // in units of the tolerance
        for (std::int64_t k = 0; k < steps; ++k) {
            FilterInput in{su.ys.data() + 2 * k, k * su.model.dt, k, nullptr};
            REQUIRE(pf->step(in) == FILTER_OK);
            su.kf.step(Eigen::Map<const Eigen::Vector2d>(su.ys.data() + 2 * k));
            for (int i = 0; i < 3; ++i) {
                const double tol = 6.0 * std::sqrt(4.0 * su.kf.P(i, i) / double(N));
                worst = std::max(worst, std::fabs(pf->estimate()[i] - su.kf.x[i]) / tol);
            }
        }
        INFO("K = " << K << ", N = " << N << ": worst |PF - KF| / tolerance = " << worst);
        CHECK(worst < 1.0);  // the tolerance itself shrinks 10x from N = 400 to N = 40000
    }
}

TEST_CASE("each Bayesian filter's NIS is its innovation against the covariance it expected for it", "[filters][nis]") {
    // linear-Gaussian: the EKF's and UKF's S are H P H' + R of their own P, to round-off, and a filter told the
    // truth has a mean NIS of m (here 2 outputs, 400 steps: the sum is chi-square with 800 degrees of freedom, sd 40)
    Setup su(2.0, 0.3, 4.0, 400);
    auto ekf = make_ekf(su.model), ukf = make_ukf(su.model), ol = make_open_loop_filter(su.model);
    for (OnlineFilter* f : {ekf.get(), ukf.get()}) {
        f->reset(su.start);
        double worst = 0, sum = 0;
        for (std::int64_t k = 0; k < su.steps; ++k) {
            // by hand, from the filter's own estimate and P before the step: S = H P H' + sn^2 I
            const Eigen::Map<const Eigen::Vector2d> y(su.ys.data() + 2 * k);
            const Eigen::Vector2d nu = y - su.sys.H * Eigen::Map<const Eigen::Vector3d>(f->estimate());
            const Eigen::Matrix3d P = Eigen::Map<const Eigen::Matrix3d>(f->covariance());
            const Eigen::Matrix2d S = su.sys.H * P * su.sys.H.transpose() + 0.09 * Eigen::Matrix2d::Identity();
            const double expect = nu.dot(S.inverse() * nu);
            REQUIRE(f->step(FilterInput{su.ys.data() + 2 * k, k * su.model.dt, k, nullptr}) == FILTER_OK);
            worst = std::max(worst, std::fabs(f->nis() - expect) / expect);
            sum += f->nis();
        }
        INFO(f->name() << ": mean NIS per output " << sum / 800.0 << ", worst relative difference from H P H' + R "
                       << worst);
        CHECK(worst < 1e-9);
        CHECK(sum / 800.0 > 0.85);
        CHECK(sum / 800.0 < 1.15);
        // a missing measurement: no innovation
        REQUIRE(f->step(FilterInput{nullptr, 400 * su.model.dt, 400, nullptr}) == FILTER_OK);
        CHECK(std::isnan(f->nis()));
    }
    ol->reset(su.start);  // states no covariance, so no S
    REQUIRE(ol->step(FilterInput{su.ys.data(), 0.0, 0, nullptr}) == FILTER_OK);
    CHECK(std::isnan(ol->nis()));
    // the PF's S is its prior cloud's output covariance plus R: with 40000 particles the Kalman filter's own
    Setup pu(2.0, 0.8, 0.5, 4);
    auto pf = make_particle_filter(pu.model, 40000);
    CHECK(pf->covariance() == nullptr);  // never reset: no cloud to state
    pf->reset(pu.start);
    for (std::int64_t k = 0; k < pu.steps; ++k) {
        const Eigen::Vector2d y = Eigen::Map<const Eigen::Vector2d>(pu.ys.data() + 2 * k);
        const Eigen::Vector2d nu = y - pu.kf.H * pu.kf.x;
        const Eigen::MatrixXd S = pu.kf.H * pu.kf.P * pu.kf.H.transpose() + pu.kf.R;
        const double kalman = nu.dot(S.inverse() * nu);
        REQUIRE(pf->step(FilterInput{pu.ys.data() + 2 * k, k * pu.model.dt, k, nullptr}) == FILTER_OK);
        pu.kf.step(y);
        INFO("step " << k << ": PF " << pf->nis() << ", Kalman " << kalman);
        CHECK(std::fabs(pf->nis() - kalman) < 0.05 * (1.0 + kalman));
    }
    REQUIRE(pf->step(FilterInput{nullptr, 4 * pu.model.dt, 4, nullptr}) == FILTER_OK);
    CHECK(std::isnan(pf->nis()));
}

TEST_CASE("open-loop predictor ignores measurements and a diverging EKF is reported", "[filters]") {
    Setup su(1.0, 1.0, 1.0, 3);
    auto ol = make_open_loop_filter(su.model);
    ol->reset(su.start);
    std::vector<double> y_big = {1e6, -1e6};
    REQUIRE(ol->step(FilterInput{y_big.data(), 0.0, 0, nullptr}) == FILTER_OK);
    Eigen::Vector3d expect = su.kf.Phi * Eigen::Map<const Eigen::Vector3d>(su.start.xhat0.data());
    CHECK(max_rel(expect, ol->estimate(), 1e-12) < 1e-15);
    // an EKF told a zero-variance measurement of a non-finite value cannot stay finite
    auto ekf = make_ekf(su.model);
    ekf->reset(su.start);
    std::vector<double> y_nan = {NAN, 0.0};
    CHECK(ekf->step(FilterInput{y_nan.data(), 0.0, 0, nullptr}) == FILTER_DIVERGED);
    CHECK(filter_estimate_ok(ekf->estimate(), 3));  // left at its last finite value
}

namespace {
// p = dV/dx~ = x~ (V = |x~|^2 / 2): the gain of eq. (8) is then k = 2 rho x~ dC^T / |x~|^2.
class IdentityNetwork final : public FrozenNetwork {
public:
    kern::StepConfig cfg;
    void gradient(double* p, const double* xt, std::int64_t count) override {
        std::copy(xt, xt + 3 * count, p);
    }
    const kern::StepConfig& step_config() const override { return cfg; }
    std::unique_ptr<FrozenNetwork> clone() const override { return std::make_unique<IdentityNetwork>(*this); }
};
}  // namespace

TEST_CASE("DNN adapter: one step of eq. (19) with gain (8), oracle and measured", "[filters][dnn]") {
    Setup su(1.0, 1.0, 1.0, 1);
    IdentityNetwork net;
    const double rho = 0.5;
    const Eigen::Vector3d x(1.0, 0.0, -0.5), xh = Eigen::Map<const Eigen::Vector3d>(su.start.xhat0.data());
    const Eigen::Vector2d y(0.7, -0.9);
    const Eigen::Vector2d e = y - su.sys.H * xh;
    for (bool measured : {false, true}) {
        auto f = make_dnn_filter(su.model, net, *make_hinf_gain_law(rho), measured, "dnn");
        CHECK(f->uses_true_state() == !measured);
        f->reset(su.start);
        REQUIRE(f->step(FilterInput{y.data(), 0.0, 0, x.data()}) == FILTER_OK);
        // oracle: network input x - x^, dC = H (x - x^); measured: x~ = least-squares H^+ e, dC = e
        // (e through a Map: GCC 12 warned of an AVX-512 load beyond a Vector2d copied into a VectorXd, a branch that
        // never runs for two entries)
        const Eigen::Map<const Eigen::VectorXd> e_dyn(e.data(), 2);
        Eigen::Vector3d xt =
            measured ? Eigen::Vector3d(Eigen::MatrixXd(su.sys.H).completeOrthogonalDecomposition().solve(e_dyn))
                     : Eigen::Vector3d(x - xh);
        Eigen::Vector2d dc = measured ? e : Eigen::Vector2d(su.sys.H * (x - xh));
        Eigen::Matrix<double, 3, 2> k = 2.0 * rho * xt * dc.transpose() / xt.squaredNorm();
        Eigen::Vector3d expect = xh + su.model.dt * (su.sys.F * xh + k * e);
        INFO("measured = " << measured);
        CHECK(max_rel(expect, f->estimate(), 1e-12) < 1e-13);
        // its filtered-estimate equivalent (docs/compare.md): the correction of the step alone, x^ + dt k e
        Eigen::Vector3d corrected = xh + su.model.dt * k * e;
        CHECK(max_rel(corrected, f->filtered(), 1e-12) < 1e-13);
    }
}
