// Example (47) of seed 002, Jacobian-based vertices (19), and the interpolation weights of Step (e).
// Not the LMIs (delay_lmi.cpp) nor the time stepping (delay_sim.cpp).
#include "lmi/delay_system.hpp"

#include <cmath>

#include "hinf/error.hpp"

namespace hinf::lmi {

DelaySystem delay_example47() {
    DelaySystem s;
    s.n = 2;
    s.l = 1;
    s.nv = 1;
    // seed 002 eq. (47)
    s.f = [](const double* x, const double* xd, double* o) {
        o[0] = -4 * x[0] - 2 * x[0] * x[0] * x[0] + 5 * x[1] + 0.1 * xd[0];
        o[1] = -4 * x[0] - 10 * x[1] + 0.1 * xd[1];
    };
    s.g = [](const double* x, const double*, double* o) {
        o[0] = -0.5 * std::cos(x[0]);
        o[1] = -std::sin(x[0]);
    };
    s.h = [](const double* x, const double* xd, double* o) {
        o[0] = 0.1 * x[0] * x[0] + 0.1 * xd[0];
        o[1] = 0.1 * x[1] + 0.1 * xd[1];
    };
    s.q = [](const double* x, const double* xd, double* o) {
        o[0] = 9 * x[0] - x[0] * x[0] - 9 * x[1] + 0.1 * xd[0] + 0.1 * xd[1];
    };
    s.k = [](const double* x, const double*, double* o) { o[0] = 12 * x[0]; };
    s.j = [](const double* x, const double* xd, double* o) {
        o[0] = 0.1 * x[0] * x[0] + 0.1 * x[1] + 0.1 * xd[0] + 0.1 * xd[1];
    };
    return s;
}

namespace {

// d fn / d z, z = (x, xd) of length 2n: returns rows x 2n (left half d/dx, right half d/dxd).
Eigen::MatrixXd jacobian(const DelaySystem::Fn& fn, int rows, int n, const std::vector<double>& z, double step) {
    Eigen::MatrixXd J(rows, 2 * n);
    std::vector<double> zp = z, zm = z, op(rows), om(rows);
    for (int c = 0; c < 2 * n; ++c) {
        const double hstep = step * std::max(1.0, std::fabs(z[c]));
        zp[c] = z[c] + hstep;
        zm[c] = z[c] - hstep;
        fn(zp.data(), zp.data() + n, op.data());
        fn(zm.data(), zm.data() + n, om.data());
        for (int r = 0; r < rows; ++r) J(r, c) = (op[r] - om[r]) / (2 * hstep);
        zp[c] = zm[c] = z[c];
    }
    return J;
}

}  // namespace

std::vector<DelayVertex> delay_vertices_from_jacobians(const DelaySystem& sys,
                                                       const std::vector<std::vector<double>>& points,
                                                       double step) {
    HINF_CHECK(sys.f && sys.g && sys.h && sys.q && sys.k && sys.j, "delay system is missing a function");
    HINF_CHECK(!points.empty(), "no operating points given for the Jacobian vertices");
    const int n = sys.n, l = sys.l, nv = sys.nv;
    std::vector<DelayVertex> out;
    for (std::size_t i = 0; i < points.size(); ++i) {
        HINF_CHECK(static_cast<int>(points[i].size()) == 2 * n,
                   "operating point " + std::to_string(i + 1) + " needs " + std::to_string(2 * n) +
                       " numbers (x then x(t - tau))");
        const auto& z = points[i];
        DelayVertex v;
        const Eigen::MatrixXd Jf = jacobian(sys.f, n, n, z, step), Jh = jacobian(sys.h, n, n, z, step);
        const Eigen::MatrixXd Jq = jacobian(sys.q, l, n, z, step), Jj = jacobian(sys.j, l, n, z, step);
        v.A0 = Jf.leftCols(n);
        v.A1 = Jf.rightCols(n);
        v.C0 = Jh.leftCols(n);
        v.C1 = Jh.rightCols(n);
        v.Q0 = Jq.leftCols(n);
        v.Q1 = Jq.rightCols(n);
        v.J0 = Jj.leftCols(n);
        v.J1 = Jj.rightCols(n);
        std::vector<double> gb(static_cast<std::size_t>(n) * nv), kb(static_cast<std::size_t>(l) * nv);
        sys.g(z.data(), z.data() + n, gb.data());
        sys.k(z.data(), z.data() + n, kb.data());
        v.B = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(gb.data(), n, nv);
        v.K = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(kb.data(), l, nv);
        out.push_back(v);
    }
    return out;
}

void delay_interp_weights(const double* x, const std::vector<std::vector<double>>& points,
                          const std::vector<int>& coordinates, double* w) {
    const std::size_t m = points.size();
    double sum = 0;
    for (std::size_t i = 0; i < m; ++i) {
        double d2 = 0;
        for (int c : coordinates) {
            const double d = x[c] - points[i][c];
            d2 += d * d;
        }
        if (d2 == 0.0) {  // exactly at vertex i: the limit of the weights is the unit vector
            for (std::size_t r = 0; r < m; ++r) w[r] = r == i ? 1.0 : 0.0;
            return;
        }
        w[i] = 1.0 / d2;
        sum += w[i];
    }
    if (!std::isfinite(sum)) {  // some d2 so small that 1/d2 overflows: share among those
        double cnt = 0;
        for (std::size_t i = 0; i < m; ++i) cnt += std::isinf(w[i]) ? 1 : 0;
        for (std::size_t i = 0; i < m; ++i) w[i] = std::isinf(w[i]) ? 1.0 / cnt : 0.0;
        return;
    }
    for (std::size_t i = 0; i < m; ++i) w[i] /= sum;
}

}  // namespace hinf::lmi
