// See gain_law.hpp: the HJIE at one point, evaluated through the kernels' term function.
#include "filters/gain_law.hpp"

#include "gain.hpp"
#include "hjie.hpp"
#include "net/network.hpp"

namespace hinf {

void hjie_point_terms(double* terms, const double* p, const System& sys, const double* x, const double* xhat,
                      double t, const double* Q, double rho) {
    const int n = sys.state_dim(), nv = sys.disturbance_dim(), m = sys.output_dim();
    std::vector<double> xt(n), a_x(n), a_h(n), dA(n), B(static_cast<std::size_t>(n) * nv), c_x(m), c_h(m), dc(m);
    for (int i = 0; i < n; ++i) xt[i] = x[i] - xhat[i];
    sys.drift(a_x.data(), x, t, 1);
    sys.drift(a_h.data(), xhat, t, 1);
    sys.disturbance_gain(B.data(), x, t, 1);
    sys.measurement(c_x.data(), x, t, 1);
    sys.measurement(c_h.data(), xhat, t, 1);
    for (int i = 0; i < n; ++i) dA[i] = a_x[i] - a_h[i];
    for (int j = 0; j < m; ++j) dc[j] = c_x[j] - c_h[j];
    const double q = quadratic_form(Q, xt.data(), n);
    kern::HjieSystemView view{n, nv, m, xt.data(), dA.data(), B.data(), dc.data(), &q};
    kern::hjie_terms(terms, p, view, 0, rho);
}

double gain_point_residual(double* abs_sum, double* v, FrozenNetwork& net, const System& sys, const double* x,
                           const double* xhat, double t, const double* Q, double rho) {
    const int n = sys.state_dim(), nv = sys.disturbance_dim(), m = sys.output_dim();
    std::vector<double> xt(n), a_x(n), a_h(n), dA(n), B(static_cast<std::size_t>(n) * nv), c_x(m), c_h(m), dc(m),
        K(static_cast<std::size_t>(n) * m), S(static_cast<std::size_t>(n) * n);
    for (int i = 0; i < n; ++i) xt[i] = x[i] - xhat[i];
    net.gain(K.data(), S.data(), xhat, 1);
    sys.drift(a_x.data(), x, t, 1);
    sys.drift(a_h.data(), xhat, t, 1);
    sys.disturbance_gain(B.data(), x, t, 1);
    sys.measurement(c_x.data(), x, t, 1);
    sys.measurement(c_h.data(), xhat, t, 1);
    for (int i = 0; i < n; ++i) dA[i] = a_x[i] - a_h[i];
    for (int j = 0; j < m; ++j) dc[j] = c_x[j] - c_h[j];
    const double q = quadratic_form(Q, xt.data(), n);
    kern::HjieSystemView view{n, nv, m, xt.data(), dA.data(), B.data(), dc.data(), &q};
    kern::GainLossParams lp;
    lp.rho = rho;
    kern::GainSampleValue val = kern::gain_sample_forward(K.data(), S.data(), view, 0, lp);
    if (abs_sum != nullptr) *abs_sum = val.abs_sum;
    if (v != nullptr) *v = quadratic_form(S.data(), xt.data(), n);
    return val.residual;
}

}  // namespace hinf
