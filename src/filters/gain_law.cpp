// See gain_law.hpp: the HJIE at one point, evaluated through the kernels' term function.
#include "filters/gain_law.hpp"

#include <Eigen/Dense>
#include <algorithm>

#include "gain.hpp"
#include "hjie.hpp"
#include "net/network.hpp"

namespace hinf {

namespace {

// The per-point constants of the HJIE at (x, x^) (seed 000 eq. (16)): x~ = x - x^, dA = A(x) - A(x^), B(x),
// dC = C(x) - C(x^), q = x~'Q x~; the one place both point residuals below take them from.
struct PointTerms {
    std::vector<double> xt, dA, B, dc;
    double q = 0;
    kern::HjieSystemView view(int n, int nv, int m) const {
        return kern::HjieSystemView{n, nv, m, xt.data(), dA.data(), B.data(), dc.data(), &q};
    }
};

PointTerms point_terms(const System& sys, const double* x, const double* xhat, double t, const double* Q) {
    const int n = sys.state_dim(), nv = sys.disturbance_dim(), m = sys.output_dim();
    PointTerms p;
    std::vector<double> a_x(n), a_h(n), c_x(m), c_h(m);
    p.xt.resize(n);
    p.dA.resize(n);
    p.B.resize(static_cast<std::size_t>(n) * nv);
    p.dc.resize(m);
    sys.state_difference(p.xt.data(), x, xhat);  // an angle state's wrapped
    sys.drift(a_x.data(), x, t, 1);
    sys.drift(a_h.data(), xhat, t, 1);
    sys.disturbance_gain(p.B.data(), x, t, 1);
    sys.measurement(c_x.data(), x, t, 1);
    sys.measurement(c_h.data(), xhat, t, 1);
    for (int i = 0; i < n; ++i) p.dA[i] = a_x[i] - a_h[i];
    sys.output_difference(p.dc.data(), c_x.data(), c_h.data());
    p.q = quadratic_form(Q, p.xt.data(), n);
    return p;
}

}  // namespace

void hjie_point_terms(double* terms, const double* p, const System& sys, const double* x, const double* xhat,
                      double t, const double* Q, double rho) {
    const PointTerms pt = point_terms(sys, x, xhat, t, Q);
    kern::hjie_terms(terms, p, pt.view(sys.state_dim(), sys.disturbance_dim(), sys.output_dim()), 0, rho);
}

void gain_filter_correct(double* xhat_filtered, const System& sys, const double* xhat, double t, const double* k,
                         const double* e, double dt) {
    const int n = sys.state_dim(), m = sys.output_dim();
    if (!sys.discrete_time()) return luenberger_correct(xhat_filtered, xhat, k, e, n, m, dt);
    Eigen::VectorXd ke = Eigen::VectorXd::Zero(n);
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < m; ++j) ke[i] += k[i * m + j] * e[j];
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> F(n, n);
    sys.drift_jacobian(F.data(), xhat, t);  // a discrete system's drift is its map f
    const Eigen::VectorXd dx = F.completeOrthogonalDecomposition().solve(ke);
    for (int i = 0; i < n; ++i) xhat_filtered[i] = xhat[i] + dx[i];
}

double gain_point_residual(double* abs_sum, double* v, FrozenNetwork& net, const System& sys, const double* x,
                           const double* xhat, double t, const double* Q, double rho, const double* K_given) {
    const int n = sys.state_dim(), nv = sys.disturbance_dim(), m = sys.output_dim();
    std::vector<double> K(static_cast<std::size_t>(n) * m), S(static_cast<std::size_t>(n) * n), Sd(S.size());
    net.gain(K.data(), S.data(), Sd.data(), xhat, t, sys, 1);
    if (K_given != nullptr) std::copy(K_given, K_given + K.size(), K.begin());
    const PointTerms pt = point_terms(sys, x, xhat, t, Q);
    const kern::HjieSystemView view = pt.view(n, nv, m);
    kern::GainLossParams lp;
    lp.rho = rho;
    lp.discrete = sys.discrete_time();
    kern::GainSampleValue val = kern::gain_sample_forward(K.data(), S.data(), view, 0, lp, Sd.data());
    if (abs_sum != nullptr) *abs_sum = val.abs_sum;
    if (v != nullptr) *v = quadratic_form(S.data(), pt.xt.data(), n);
    return val.residual;
}

}  // namespace hinf
