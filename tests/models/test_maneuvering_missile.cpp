// The maneuvering missile of seed 001 eqs. (24)-(29) against values computed by hand at two times (the
// model is time-varying) and two altitudes, its 6 x 6 disturbance matrix, and its Jacobians against
// central differences at a time where the guidance term is active.
#include <catch2/catch.hpp>
#include <cmath>

#include "hinf/config.hpp"
#include "models/maneuvering_missile.hpp"

using hinf::ManeuveringMissileSystem;
using hinf::ManeuverParams;

TEST_CASE("maneuvering missile drift by hand at t = 0, high altitude", "[model][maneuver]") {
    ManeuveringMissileSystem sys{ManeuverParams{}};
    // t = 0: a(0) = 0 and e^0 sin(0) = 0. X(0): drag = rho g |v| / (2 beta) = 1.5956306453e-8 (seed 000's
    // test), 2500 drag = 3.9890766132e-5. Rows 1-3: -0.1 x1, -0.1 x2, -0.08 x3 (u's -x4 cancels x1' = x4).
    double X[6] = {150000, 210000, 120000, -2500, -2500, -2500}, A[6];
    sys.drift(A, X, 0.0, 1);
    CHECK(A[0] == -15000.0);
    CHECK(A[1] == -21000.0);
    CHECK(A[2] == -9600.0);
    CHECK(A[3] == Approx(3.9890766132e-5).epsilon(1e-9));      // no damping on row 4 at t = 0
    CHECK(A[4] == Approx(25.000039890766132).epsilon(1e-14));  // 2500 drag + 0.01 * 2500
    CHECK(A[5] == Approx(15.190039890766132).epsilon(1e-14));  // ... - g
}

TEST_CASE("maneuvering missile drift by hand at t = 1.3, low altitude", "[model][maneuver]") {
    ManeuveringMissileSystem sys{ManeuverParams{}};
    // t = 1.3: a(t) = 15000 e^{-0.13} (4/pi) sin(1.3) = 16159.244052359338,
    // e^{-0.13} sin(13) = 0.3689467552609046. z = 5000: 100 drag = 1.996003509048338 (seed 000's test).
    double X[6] = {1000, -500, 5000, -100, 50, -200}, A[6], C[6];
    sys.drift(A, X, 1.3, 1);
    CHECK(sys.wave(1.3) == Approx(16159.244052359338).epsilon(1e-14));
    CHECK(A[0] == Approx(-100.0 + 16159.244052359338).epsilon(1e-14));
    CHECK(A[1] == 50.0);
    CHECK(A[2] == -400.0);
    CHECK(A[3] == Approx(1.996003509048338 + 100 * 0.3689467552609046).epsilon(1e-13));  // -drag x4 - e sin x4
    CHECK(A[4] == Approx(-1.498001754524169).epsilon(1e-13));
    CHECK(A[5] == Approx(-3.8179929819033243).epsilon(1e-13));
    // the same state at t = 0 differs only in rows 1 and 4
    double A0[6];
    sys.drift(A0, X, 0.0, 1);
    CHECK(A0[0] == -100.0);
    CHECK(A0[3] == Approx(1.996003509048338).epsilon(1e-13));
    CHECK((A0[1] == A[1] && A0[2] == A[2] && A0[4] == A[4] && A0[5] == A[5]));
    sys.measurement(C, X, 1.3, 1);
    CHECK(C[0] == 700.0);   // x - 300
    CHECK(C[1] == -800.0);  // y - 300 (radar at (300, 300, 0))
    CHECK(C[2] == 5000.0);
    CHECK(C[3] == -100.0);
    double G[36];
    sys.disturbance_gain(G, X, 1.3, 1);
    REQUIRE(sys.disturbance_dim() == 6);
    for (int i = 0; i < 6; ++i)
        for (int j = 0; j < 6; ++j) CHECK(G[i * 6 + j] == ((i == j && i >= 3) ? 1.0 : 0.0));
}

TEST_CASE("maneuvering missile Jacobian matches central differences", "[model][maneuver]") {
    ManeuveringMissileSystem sys{ManeuverParams{}};
    for (double t : {0.0, 1.3}) {
        for (double z : {5000.0, 20000.0}) {
            double X[6] = {1000, -500, z, -900, 350, -1200}, J[36];
            sys.drift_jacobian(J, X, t);
            for (int j = 0; j < 6; ++j) {
                double h = 1e-6 * std::max(1.0, std::fabs(X[j]));
                double Xp[6], Xm[6], Ap[6], Am[6];
                for (int k = 0; k < 6; ++k) Xp[k] = Xm[k] = X[k];
                Xp[j] += h;
                Xm[j] -= h;
                sys.drift(Ap, Xp, t, 1);
                sys.drift(Am, Xm, t, 1);
                for (int i = 0; i < 6; ++i)
                    CHECK(J[i * 6 + j] == Approx((Ap[i] - Am[i]) / (2 * h)).epsilon(1e-6).margin(1e-9));
            }
        }
    }
}

TEST_CASE("[system] kind = maneuvering_missile is built from the config", "[model][maneuver][config]") {
    auto doc =
        hinf::ConfigDoc::from_text("[system]\nkind = \"maneuvering_missile\"\nmaneuver_amplitude = 0.0\n", "m.toml");
    std::unique_ptr<hinf::System> sys = hinf::make_system(doc);
    CHECK(sys->name() == "maneuvering_missile");
    CHECK(sys->disturbance_dim() == 6);
    double X[6] = {1000, -500, 5000, -100, 50, -200}, A[6];
    sys->drift(A, X, 1.3, 1);
    CHECK(A[0] == -100.0);  // amplitude 0: no wave
    // the key belongs to the maneuvering kind only
    auto bad = hinf::ConfigDoc::from_text("[system]\nkind = \"missile\"\nmaneuver_amplitude = 1.0\n", "m.toml");
    CHECK_THROWS(hinf::make_system(bad));
}
