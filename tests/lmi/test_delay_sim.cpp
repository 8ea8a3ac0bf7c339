// The delay history buffer and the Euler-Maruyama step against hand-computed cases, the strong order of
// the integrator on geometric Brownian motion, the filter step by hand, and thread-count independence.
#include <catch2/catch.hpp>

#include <cmath>
#include <random>

#include "lmi/delay_sim.hpp"

using namespace hinf::lmi;
using Eigen::MatrixXd;

TEST_CASE("delay sim: history buffer interpolates linearly and clamps", "[lmi]") {
    DelayHistory h;
    h.reset(2, -1.0, 0.5);
    const double a[2] = {1, 10}, b[2] = {3, 20}, c[2] = {7, 40};
    h.push(a);  // t = -1
    h.push(b);  // t = -0.5
    h.push(c);  // t = 0
    CHECK(h.t_last() == Approx(0.0));
    double o[2];
    h.at(-0.75, o);
    CHECK(o[0] == Approx(2.0));
    CHECK(o[1] == Approx(15.0));
    h.at(-0.1, o);  // 0.8 of the way from -0.5 to 0
    CHECK(o[0] == Approx(3 + 0.8 * 4));
    CHECK(o[1] == Approx(20 + 0.8 * 20));
    h.at(-0.5, o);
    CHECK(o[0] == 3.0);
    h.at(0.0, o);
    CHECK(o[1] == 40.0);
    h.at(-5.0, o);  // before the initial function's start: clamped
    CHECK(o[0] == 1.0);
    h.at(3.0, o);
    CHECK(o[0] == 7.0);
}

TEST_CASE("delay sim: Euler-Maruyama step of (47) by hand", "[lmi]") {
    const DelaySystem sys = delay_example47();
    const double x[2] = {1.0, 2.0}, xd[2] = {0.5, -1.0}, v[1] = {2.0};
    double xn[2], dy[1];
    delay_em_step(sys, x, xd, v, 0.1, 0.01, xn, dy);
    // f = (-4 - 2 + 10 + 0.05, -4 - 20 - 0.1), g = (-0.5 cos 1, -sin 1), h = (0.1 + 0.05, 0.2 - 0.1)
    CHECK(xn[0] == Approx(1 + (4.05 - std::cos(1.0)) * 0.01 + 0.15 * 0.1).epsilon(1e-14));
    CHECK(xn[1] == Approx(2 + (-24.1 - 2 * std::sin(1.0)) * 0.01 + 0.1 * 0.1).epsilon(1e-14));
    // q = 9 - 1 - 18 + 0.05 - 0.1, k v = 24, j = 0.1 + 0.2 + 0.05 - 0.1
    CHECK(dy[0] == Approx((-10.05 + 24) * 0.01 + 0.25 * 0.1).epsilon(1e-14));
}

TEST_CASE("delay sim: Euler-Maruyama has strong order 1/2 on geometric Brownian motion", "[lmi]") {
    // dX = mu X dt + s X dW, X(T) = X0 exp((mu - s^2/2) T + s W(T)); no delay, no disturbance.
    const double mu = 1.5, s = 1.0, T = 1.0;
    DelaySystem sys;
    sys.n = 1, sys.l = 1, sys.nv = 1;
    sys.f = [mu](const double* x, const double*, double* o) { o[0] = mu * x[0]; };
    sys.h = [s](const double* x, const double*, double* o) { o[0] = s * x[0]; };
    sys.g = [](const double*, const double*, double* o) { o[0] = 0; };
    sys.q = [](const double* x, const double*, double* o) { o[0] = x[0]; };
    sys.k = [](const double*, const double*, double* o) { o[0] = 0; };
    sys.j = [](const double*, const double*, double* o) { o[0] = 0; };
    const unsigned seed = 1234;
    INFO("random seed " << seed);
    std::mt19937_64 g(seed);
    std::normal_distribution<double> N(0, 1);
    const int paths = 2000, fine = 1 << 10;
    const int levels[3] = {1 << 4, 1 << 6, 1 << 8};
    double err[3] = {0, 0, 0};
    std::vector<double> dWf(fine);
    for (int p = 0; p < paths; ++p) {
        double W = 0;
        for (auto& d : dWf) {
            d = std::sqrt(T / fine) * N(g);
            W += d;
        }
        const double exact = std::exp((mu - 0.5 * s * s) * T + s * W);
        for (int lv = 0; lv < 3; ++lv) {
            const int steps = levels[lv], per = fine / steps;
            double x = 1.0, xn, dy, v0 = 0.0;
            for (int k = 0; k < steps; ++k) {
                double dW = 0;
                for (int q = 0; q < per; ++q) dW += dWf[k * per + q];
                delay_em_step(sys, &x, &x, &v0, dW, T / steps, &xn, &dy);
                x = xn;
            }
            err[lv] += std::fabs(x - exact) / paths;
        }
    }
    // slope of log(error) against log(dt) over a factor 16 in dt
    const double slope = std::log(err[0] / err[2]) / std::log(16.0);
    INFO("strong errors " << err[0] << " " << err[1] << " " << err[2] << ", slope " << slope);
    CHECK(slope > 0.35);
    CHECK(slope < 0.75);
    CHECK(err[0] > err[1]);
    CHECK(err[1] > err[2]);
}

TEST_CASE("delay sim: filter step (21) by hand with two vertices", "[lmi]") {
    DelayFilter fl;
    DelayVertex a, b;
    a.A0 = MatrixXd::Constant(1, 1, -1.0);
    a.A1 = MatrixXd::Constant(1, 1, 0.5);
    a.Q0 = MatrixXd::Constant(1, 1, 2.0);
    a.Q1 = MatrixXd::Constant(1, 1, 0.0);
    b = a;
    b.A0(0, 0) = -3.0;
    b.Q0(0, 0) = 4.0;
    fl.vertices = {a, b};
    fl.gains = {MatrixXd::Constant(1, 1, 0.1), MatrixXd::Constant(1, 1, 0.3)};
    fl.points = {{0.0, 0.0}, {2.0, 0.0}};
    fl.coordinates = {0};
    const double xh = 0.5, xhd = 0.2, dy = 0.05, dt = 0.01;
    double xn;
    delay_filter_step(fl, &xh, &xhd, &dy, dt, &xn);
    // weights at 0.5: d^2 = 0.25, 2.25 -> 4 : 4/9 -> 0.9, 0.1
    const double w0 = 0.9, w1 = 0.1;
    const double dyhat = (w0 * 2.0 + w1 * 4.0) * xh * dt;
    const double expect = xh + w0 * ((-1.0 * xh + 0.5 * xhd) * dt + 0.1 * (dy - dyhat)) +
                          w1 * ((-3.0 * xh + 0.5 * xhd) * dt + 0.3 * (dy - dyhat));
    CHECK(xn == Approx(expect).epsilon(1e-13));
}

TEST_CASE("delay sim: Monte Carlo results do not depend on the thread count", "[lmi]") {
    const DelaySystem sys = delay_example47();
    DelayFilter fl;
    fl.points = {{-0.5, 0, 0, 0}, {-0.1, 0, 0, 0}, {1.5, 0, 0, 0}};
    fl.vertices = delay_vertices_from_jacobians(sys, fl.points);
    fl.coordinates = {0};
    for (int j = 0; j < 3; ++j) fl.gains.push_back((MatrixXd(2, 1) << -0.1, 0.1).finished());
    DelaySimSpec s;
    s.final_time = 1.0;
    s.dt = 1e-3;
    s.initial_covariance = MatrixXd::Identity(2, 2);
    const DelayMonteCarlo one = delay_monte_carlo(sys, fl, s, 6, 1);
    const DelayMonteCarlo two = delay_monte_carlo(sys, fl, s, 6, 2);
    REQUIRE(one.error_energy.size() == 6);
    for (int r = 0; r < 6; ++r) CHECK(one.error_energy[r] == two.error_energy[r]);
    CHECK(one.mean == two.mean);
    CHECK(one.mean_squared_error == two.mean_squared_error);
    CHECK(one.error_energy[0] != one.error_energy[1]);  // runs draw different noise
    CHECK(one.ci95_low < one.mean);
    CHECK(one.mean < one.ci95_high);
}
