// Example (47), the Jacobian vertex builder against Appendix A, and the Step (e) interpolation weights.
#include <catch2/catch.hpp>

#include <random>

#include "lmi/delay_system.hpp"

using namespace hinf::lmi;
using Eigen::MatrixXd;

TEST_CASE("delay system: Jacobian vertices of (47) reproduce Appendix A", "[lmi]") {
    const DelaySystem sys = delay_example47();
    const auto v = delay_vertices_from_jacobians(sys, {{-0.5, 0, 0, 0}, {-0.1, 0, 0, 0}, {1.5, 0, 0, 0}});
    REQUIRE(v.size() == 3);
    // Appendix A, typed from the paper (B is printed to 4 decimals)
    const double A0_11[3] = {-5.5, -4.06, -17.5}, C0_11[3] = {-0.1, -0.02, 0.3}, Q0_1[3] = {10, 9.2, 6};
    const double J0_1[3] = {-0.1, -0.02, 0.3}, K[3] = {-6, -1.2, 18};
    const double B1[3] = {-0.4388, -0.4975, -0.0353}, B2[3] = {0.4794, 0.0998, -0.9975};
    for (int i = 0; i < 3; ++i) {
        INFO("vertex " << i + 1);
        MatrixXd A0(2, 2), C0(2, 2), Q0(1, 2), J0(1, 2);
        A0 << A0_11[i], 5, -4, -10;
        C0 << C0_11[i], 0, 0, 0.1;
        Q0 << Q0_1[i], -9;
        J0 << J0_1[i], 0.1;
        CHECK((v[i].A0 - A0).cwiseAbs().maxCoeff() < 1e-6);
        CHECK((v[i].A1 - 0.1 * MatrixXd::Identity(2, 2)).cwiseAbs().maxCoeff() < 1e-6);
        CHECK((v[i].C0 - C0).cwiseAbs().maxCoeff() < 1e-6);
        CHECK((v[i].C1 - 0.1 * MatrixXd::Identity(2, 2)).cwiseAbs().maxCoeff() < 1e-6);
        CHECK((v[i].Q0 - Q0).cwiseAbs().maxCoeff() < 1e-6);
        CHECK((v[i].Q1 - MatrixXd::Constant(1, 2, 0.1)).cwiseAbs().maxCoeff() < 1e-6);
        CHECK((v[i].J0 - J0).cwiseAbs().maxCoeff() < 1e-6);
        CHECK((v[i].J1 - MatrixXd::Constant(1, 2, 0.1)).cwiseAbs().maxCoeff() < 1e-6);
        CHECK(v[i].B(0, 0) == Approx(B1[i]).margin(1e-4));
        CHECK(v[i].B(1, 0) == Approx(B2[i]).margin(1e-4));
        CHECK(v[i].K(0, 0) == Approx(K[i]).margin(1e-9));
    }
}

TEST_CASE("delay system: interpolation weights sum to 1 and lie in [0, 1]", "[lmi]") {
    const std::vector<std::vector<double>> pts = {{-0.5, 0, 0, 0}, {-0.1, 0, 0, 0}, {1.5, 0, 0, 0}};
    const unsigned seed = 42;
    INFO("random seed " << seed);
    std::mt19937 g(seed);
    std::normal_distribution<double> N(0, 2);
    double w[3];
    for (int t = 0; t < 10000; ++t) {
        const double x[2] = {N(g), N(g)};
        delay_interp_weights(x, pts, {0}, w);
        double s = 0;
        for (double wi : w) {
            CHECK(wi >= 0.0);
            CHECK(wi <= 1.0);
            s += wi;
        }
        CHECK(s == Approx(1.0).epsilon(1e-14));
    }
    // at a vertex, and within 1e-200 of one (1/d^2 overflows): that vertex alone
    for (double x1 : {-0.1, -0.1 + 1e-200}) {
        const double x[2] = {x1, 3.0};
        delay_interp_weights(x, pts, {0}, w);
        CHECK(w[0] == 0.0);
        CHECK(w[1] == 1.0);
        CHECK(w[2] == 0.0);
    }
    // by hand at x1 = 0.5: d^2 = 1, 0.36, 1 -> weights proportional to 1, 1/0.36, 1
    const double x[2] = {0.5, 0};
    delay_interp_weights(x, pts, {0}, w);
    const double s = 2 + 1 / 0.36;
    CHECK(w[0] == Approx(1 / s));
    CHECK(w[1] == Approx(1 / 0.36 / s));
    CHECK(w[2] == Approx(1 / s));
}
