// The missile model of seed 000 eqs. (21)-(25) against values computed by hand at two states (one
// above, one below the 9144 m density switch), and its Jacobians against central differences.
#include <catch2/catch.hpp>
#include <cmath>

#include "models/missile.hpp"

using hinf::MissileParams;
using hinf::MissileSystem;

TEST_CASE("missile drift by hand, high altitude", "[model][missile]") {
    MissileSystem sys{MissileParams{}};
    // X(0) of seed 000: rho = 1.75 e^{-1.49e-4 * 120000} = 3.005056987e-8, |v| = 2500 sqrt(3),
    // drag = rho g |v| / (2 beta) = 1.5956306453e-8; A4 = 2500 drag + 25, A6 = A4 - 9.81
    double X[6] = {150000, 210000, 120000, -2500, -2500, -2500}, A[6];
    sys.drift(A, X, 0.0, 1);
    CHECK(sys.density(120000) == Approx(3.005056987061705e-08).epsilon(1e-13));
    CHECK(A[0] == -15000.0);
    CHECK(A[1] == -21000.0);
    CHECK(A[2] == -9600.0);
    CHECK(A[3] == Approx(25.000039890766132).epsilon(1e-14));
    CHECK(A[4] == Approx(25.000039890766132).epsilon(1e-14));
    CHECK(A[5] == Approx(15.190039890766132).epsilon(1e-14));
}

TEST_CASE("missile drift and measurement by hand, low altitude", "[model][missile]") {
    MissileSystem sys{MissileParams{}};
    // z = 5000 < 9144: rho = 1.227 e^{-1.093e-4 * 5000} = 0.7103994693548067; |v| = sqrt(100^2+50^2+200^2)
    double X[6] = {1000, -500, 5000, -100, 50, -200}, A[6], C[6];
    sys.drift(A, X, 0.0, 1);
    CHECK(A[0] == -100.0);
    CHECK(A[1] == 50.0);
    CHECK(A[2] == -400.0);
    CHECK(A[3] == Approx(2.996003509048338).epsilon(1e-13));
    CHECK(A[4] == Approx(-1.498001754524169).epsilon(1e-13));
    CHECK(A[5] == Approx(-3.8179929819033243).epsilon(1e-13));
    sys.measurement(C, X, 0.0, 1);
    CHECK(C[0] == 700.0);   // x - 300
    CHECK(C[1] == -700.0);  // y - 200
    CHECK(C[2] == 5000.0);
    CHECK(C[5] == -200.0);
    double B[6];
    sys.disturbance_gain(B, X, 0.0, 1);
    CHECK((B[0] == 0 && B[1] == 0 && B[2] == 0 && B[3] == 1 && B[4] == 1 && B[5] == 1));
}

TEST_CASE("missile Jacobian matches central differences", "[model][missile]") {
    MissileSystem sys{MissileParams{}};
    for (double z : {5000.0, 20000.0}) {
        double X[6] = {1000, -500, z, -900, 350, -1200}, J[36];
        sys.drift_jacobian(J, X, 0.0);
        for (int j = 0; j < 6; ++j) {
            double h = 1e-6 * std::max(1.0, std::fabs(X[j]));
            double Xp[6], Xm[6], Ap[6], Am[6];
            for (int k = 0; k < 6; ++k) Xp[k] = Xm[k] = X[k];
            Xp[j] += h;
            Xm[j] -= h;
            sys.drift(Ap, Xp, 0.0, 1);
            sys.drift(Am, Xm, 0.0, 1);
            for (int i = 0; i < 6; ++i) CHECK(J[i * 6 + j] == Approx((Ap[i] - Am[i]) / (2 * h)).epsilon(1e-6).margin(1e-9));
        }
    }
}

TEST_CASE("batched evaluation equals one-at-a-time", "[model][missile]") {
    MissileSystem sys{MissileParams{}};
    double X[12] = {1000, -500, 5000, -100, 50, -200, 150000, 210000, 120000, -2500, -2500, -2500};
    double A2[12], A1[6];
    sys.drift(A2, X, 0.0, 2);
    sys.drift(A1, X + 6, 0.0, 1);
    for (int i = 0; i < 6; ++i) CHECK(A2[6 + i] == A1[i]);
}
