// Expression systems ([system] kind = "expr"): seed 000's missile written as expressions
// (runs/missile_expr.toml) against the built-in one, exact Jacobians against central differences, the
// one-line errors at config read, concurrent use, and compare/operate on an expression system.
#include <omp.h>

#include <catch2/catch.hpp>
#include <cmath>
#include <cstdio>
#include <random>

#include "helpers.hpp"
#include "hinf/config.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"
#include "models/expr_system.hpp"
#include "models/missile.hpp"
#include "train/trainer.hpp"

using namespace hinf;
using hinf::test::TempDir;

namespace {

// Round-off tolerance of one evaluation: GiNaC reorders sums and products and folds constants
// (2*0.5 -> 1.0), so a value may differ from the hand-written C++ by a few ulps of its largest term.
// 1e-13 relative (about 450 ulps) with the floor 1 (the missile's gravity term) is round-off, and a
// parameter changed by 1e-8 relative is well outside it (the test below checks that).
constexpr double kEvalTol = 1e-13;

double worst_rel(const std::vector<double>& a, const std::vector<double>& b) {
    double worst = 0;
    for (std::size_t i = 0; i < a.size(); ++i)
        worst = std::max(worst, std::fabs(a[i] - b[i]) / std::max({std::fabs(a[i]), std::fabs(b[i]), 1.0}));
    return worst;
}

std::unique_ptr<System> expr_missile(const std::vector<std::string>& sets = {}) {
    ConfigDoc doc = ConfigDoc::from_file(test::source_path("runs/missile_expr.toml"));
    for (const auto& s : sets) doc.set(s);
    return make_system(doc);
}

// random missile states: positions up to 200 km, altitudes on both sides of the 9144 m switch (and on it),
// velocities up to 4 km/s per axis
std::vector<double> missile_states(std::int64_t count, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> pos(-2e5, 2e5), alt(0.0, 2e4), high(0.0, 2e5), vel(-4000, 4000);
    std::vector<double> x(count * 6);
    for (std::int64_t s = 0; s < count; ++s) {
        double* X = &x[s * 6];
        X[0] = pos(rng);
        X[1] = pos(rng);
        X[2] = s % 2 ? alt(rng) : high(rng);
        X[3] = vel(rng);
        X[4] = vel(rng);
        X[5] = vel(rng);
    }
    x[2] = 9144.0;                       // on the switch: the upper layer (z >= 9144)
    x[8] = std::nextafter(9144.0, 0.0);  // just below it
    return x;
}

struct MissileDiff {
    double f = 0, g = 0, h = 0, df = 0, dh = 0;
};

MissileDiff missile_diff(const System& ex, const MissileSystem& ref, const std::vector<double>& x, double t) {
    const std::int64_t N = std::int64_t(x.size() / 6);
    std::vector<double> a(N * 6), b(N * 6), ga(N * 6), gb(N * 6), ca(N * 6), cb(N * 6);
    ex.drift(a.data(), x.data(), t, N);
    ref.drift(b.data(), x.data(), t, N);
    ex.disturbance_gain(ga.data(), x.data(), t, N);
    ref.disturbance_gain(gb.data(), x.data(), t, N);
    ex.measurement(ca.data(), x.data(), t, N);
    ref.measurement(cb.data(), x.data(), t, N);
    MissileDiff d;
    d.f = worst_rel(a, b);
    d.g = worst_rel(ga, gb);
    d.h = worst_rel(ca, cb);
    std::vector<double> Ja(36), Jb(36), Ha(36), Hb(36);
    for (std::int64_t s = 0; s < N; s += 7) {
        ex.drift_jacobian(Ja.data(), &x[s * 6], t);
        ref.drift_jacobian(Jb.data(), &x[s * 6], t);
        ex.measurement_jacobian(Ha.data(), &x[s * 6], t);
        ref.measurement_jacobian(Hb.data(), &x[s * 6], t);
        d.df = std::max(d.df, worst_rel(Ja, Jb));
        d.dh = std::max(d.dh, worst_rel(Ha, Hb));
    }
    return d;
}

std::string vdp_config(const std::string& system_extra = "", const std::string& filter_extra = "") {
    return "[system]\nkind = \"expr\"\nstates = [\"p\", \"w\"]\ndisturbances = 1\nmeasurements = 1\n"
           "parameters = { mu = 1.0, c = 0.3 }\nf = [\"w\", \"mu*(1 - p^2)*w - p\"]\ng = [[\"0\"], [\"1\"]]\n"
           "h = [\"p + c*p^3\"]\n" +
           system_extra + "[filter]\nrho = 0.5\nQ = [1.0, 1.0]\n" + filter_extra +
           "dt = 0.01\nt_final = 0.1\n[network]\nhidden = [8]\n[training]\nsamples = 50\nbatch = 20\nadam_steps = 2\n"
           "[sampling]\nerror_floor = [0.2, 0.2]\n[online]\ndisturbance_std = 0.5\nnoise_std = 0.1\n";
}

const char* kStart = "x0 = [2.0, 0.0]\nxhat0 = [0.5, 1.0]\n";

// Van der Pol with many terms and products (and the (a - b)^-1 that GiNaC signs by its hash order): GiNaC's
// own print ordered these differently in each process, and 8 runs of `hinf filter` gave 8 different EKF outputs
std::string rich_vdp_config() {
    return "[system]\nkind = \"expr\"\nstates = [\"p\", \"w\"]\ndisturbances = 1\nmeasurements = 2\n"
           "parameters = { mu = 1.0, c = 0.3, q = 0.7 }\ndefinitions = [\"r = sqrt(1 + p^2 + w^2)\"]\n"
           "f = [\"w + 0.1*sin(p)*w - 0.02*p*w^2\", \"mu*(1 - p^2)*w - p + 0.3*q*p*w*c - 0.05*w^3/(1 + p^2) + "
           "0.01*exp(-p*w)*r + c*q/(p - w - 7)\"]\ng = [[\"0\"], [\"1 + 0.1*p*w*q\"]]\n"
           "h = [\"p + c*p^3 + 0.2*q*p*w + 0.1*sin(w)*cos(p)\", \"r + 0.3*w*p^2*q - c/(w - p + 9)\"]\n"
           "[filter]\nrho = 0.5\nQ = [1.0, 1.0]\nx0 = [2.0, 0.0]\nxhat0 = [0.5, 1.0]\ndt = 0.01\nt_final = 1.0\n"
           "[network]\nhidden = [8]\n[sampling]\nerror_floor = [0.2, 0.2]\n[online]\ndisturbance_std = 0.5\nnoise_std = 0.1\n";
}

std::vector<std::string> all_programs(const System& sys) {
    const auto* es = dynamic_cast<const ExprSystem*>(&sys);
    REQUIRE(es);
    std::vector<std::string> out;
    for (const char* which : {"f", "g", "h", "df", "dh"})
        for (const auto& text : es->compiled(which)) out.push_back(std::string(which) + ": " + text);
    return out;
}

}  // namespace

TEST_CASE("expression missile equals the built-in missile: f, g, h and Jacobians to round-off", "[model][expr]") {
    const std::uint64_t seed = 20261122;
    INFO("random states from std::mt19937_64 seed " << seed);
    std::unique_ptr<System> ex = expr_missile();
    MissileSystem ref{MissileParams{}};
    REQUIRE(ex->state_dim() == 6);
    REQUIRE(ex->disturbance_dim() == 1);
    REQUIRE(ex->output_dim() == 6);
    CHECK(ex->state_names() == ref.state_names());
    CHECK(ex->state_units() == ref.state_units());
    std::vector<double> x = missile_states(5000, seed);
    MissileDiff d = missile_diff(*ex, ref, x, 1.25);
    INFO("largest relative differences: f " << d.f << ", g " << d.g << ", h " << d.h << ", dA/dx " << d.df << ", dC/dx "
                                            << d.dh);
    CHECK(d.f <= kEvalTol);
    CHECK(d.g == 0.0);
    CHECK(d.h == 0.0);
    CHECK(d.df <= kEvalTol);
    CHECK(d.dh == 0.0);
    // the step's derivative is gone from the Jacobian's expressions (zero, docs/method.md §12), the step stays
    const auto* es = dynamic_cast<const ExprSystem*>(ex.get());
    REQUIRE(es);
    bool step_kept = false;
    for (const auto& text : es->compiled("df")) {
        INFO(text);
        CHECK(text.find("D_0_step") == std::string::npos);
        step_kept = step_kept || text.find("step(") != std::string::npos;
    }
    CHECK(step_kept);
    // one state at a time (the path EKF/UKF/PF take) gives the same values as the batch
    std::vector<double> batch(6 * 5000), one(6);
    ex->drift(batch.data(), x.data(), 0.0, 5000);
    for (std::int64_t s : {0, 1, 2, 4999}) {
        ex->drift(one.data(), &x[s * 6], 0.0, 1);
        CHECK(std::vector<double>(batch.begin() + s * 6, batch.begin() + s * 6 + 6) == one);
    }
}

TEST_CASE("a parameter changed by 1e-8 relative is outside the round-off tolerance", "[model][expr]") {
    MissileSystem ref{MissileParams{}};
    std::vector<double> x = missile_states(500, 7);
    MissileDiff d = missile_diff(*expr_missile({"system.parameters.gravity=9.8100001"}), ref, x, 0.0);
    INFO("gravity changed: f " << d.f);
    CHECK(d.f > kEvalTol);
    MissileDiff e = missile_diff(*expr_missile({"system.parameters.decay_low=1.0930001e-4"}), ref, x, 0.0);
    INFO("decay_low changed: f " << e.f << ", dA/dx " << e.df);
    CHECK(e.f > kEvalTol);
    CHECK(e.df > kEvalTol);
}

TEST_CASE("expression Jacobians are exact: central differences agree to truncation error", "[model][expr]") {
    // every function the grammar offers, a parameter, t, a definition and a switch
    ConfigDoc doc = ConfigDoc::from_text(
        "[system]\nkind = \"expr\"\nstates = [\"a\", \"b\", \"c\"]\ndisturbances = 2\nmeasurements = 2\n"
        "parameters = { k = 0.7 }\ndefinitions = [\"r = sqrt(a^2 + b^2 + 1)\"]\n"
        "f = [\"sin(a)*cos(b) + tan(0.3*c) + k*t\", \"exp(-a*b)/r + atan2(b, 2 + c^2) + abs(c)\", "
        "\"sinh(0.2*a) + cosh(0.1*b) + tanh(c) + log(1 + a^2) + pow(r, 1.5) + step(a - 0.1)*b\"]\n"
        "g = [[\"1\", \"a\"], [\"0\", \"b*c\"], [\"t\", \"0\"]]\n"
        "h = [\"asin(0.2*a) + acos(0.1*b) + atan(c)\", \"asinh(a) + acosh(2 + b^2) + atanh(0.1*c) + pi\"]\n",
        "exact.toml");
    std::unique_ptr<System> sys = make_system(doc);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> u(-1.5, 1.5);
    for (int trial = 0; trial < 20; ++trial) {
        double x[3] = {u(rng), u(rng), u(rng)}, t = 0.3 * trial;
        if (std::fabs(x[0] - 0.1) < 1e-3 || std::fabs(x[2]) < 1e-3) continue;  // away from the kinks
        double J[9], H[6], ap[3], am[3], cp[2], cm[2];
        sys->drift_jacobian(J, x, t);
        sys->measurement_jacobian(H, x, t);
        for (int j = 0; j < 3; ++j) {
            const double eps = 1e-6;
            double xp[3] = {x[0], x[1], x[2]}, xm[3] = {x[0], x[1], x[2]};
            xp[j] += eps;
            xm[j] -= eps;
            sys->drift(ap, xp, t, 1);
            sys->drift(am, xm, t, 1);
            sys->measurement(cp, xp, t, 1);
            sys->measurement(cm, xm, t, 1);
            for (int i = 0; i < 3; ++i) CHECK(J[i * 3 + j] == Approx((ap[i] - am[i]) / (2 * eps)).margin(1e-7));
            for (int i = 0; i < 2; ++i) CHECK(H[i * 3 + j] == Approx((cp[i] - cm[i]) / (2 * eps)).margin(1e-7));
        }
    }
}

TEST_CASE("min and max evaluate as muParser's and differentiate as the argument they take", "[model][expr]") {
    // a saturated sensor and a clipped drift: min(x, 1.2), max of three (folded from the left), nested
    ConfigDoc doc = ConfigDoc::from_text(
        "[system]\nkind = \"expr\"\nstates = [\"a\", \"b\"]\ndisturbances = 1\nmeasurements = 2\n"
        "f = [\"max(-a, b^2, -0.5) \", \"min(a*b, max(b, 0.2))\"]\ng = [[\"0\"], [\"1\"]]\n"
        "h = [\"min(a, 1.2)\", \"max(2*b, sin(a))\"]\n",
        "clip.toml");
    std::unique_ptr<System> sys = make_system(doc);
    std::mt19937_64 rng(9);
    std::uniform_real_distribution<double> u(-2.0, 2.0);
    int kinks_seen = 0;
    for (int trial = 0; trial < 200; ++trial) {
        const double a = u(rng), b = u(rng), x[2] = {a, b};
        double f[2], h[2], J[4], H[4];
        sys->drift(f, x, 0.0, 1);
        sys->measurement(h, x, 0.0, 1);
        CHECK(f[0] == Approx(std::max({-a, b * b, -0.5})).margin(1e-14));
        CHECK(f[1] == Approx(std::min(a * b, std::max(b, 0.2))).margin(1e-14));
        CHECK(h[0] == Approx(std::min(a, 1.2)).margin(1e-14));
        CHECK(h[1] == Approx(std::max(2 * b, std::sin(a))).margin(1e-14));
        sys->drift_jacobian(J, x, 0.0);
        sys->measurement_jacobian(H, x, 0.0);
        // the derivative of the argument taken (away from the ties)
        const double m0 = std::max({-a, b * b, -0.5});
        if (std::fabs(-a - b * b) < 1e-6 || std::fabs(-a + 0.5) < 1e-6 || std::fabs(b * b + 0.5) < 1e-6 ||
            std::fabs(a * b - std::max(b, 0.2)) < 1e-6 || std::fabs(b - 0.2) < 1e-6 || std::fabs(a - 1.2) < 1e-6 ||
            std::fabs(2 * b - std::sin(a)) < 1e-6)
            continue;
        ++kinks_seen;
        CHECK(J[0] == (m0 == -a ? -1.0 : 0.0));
        CHECK(J[1] == Approx(m0 == b * b ? 2 * b : 0.0).margin(1e-14));
        const bool prod = a * b < std::max(b, 0.2);
        CHECK(J[2] == Approx(prod ? b : 0.0).margin(1e-14));
        CHECK(J[3] == Approx(prod ? a : b > 0.2 ? 1.0 : 0.0).margin(1e-14));
        CHECK(H[0] == (a < 1.2 ? 1.0 : 0.0));
        CHECK(H[1] == 0.0);
        CHECK(H[2] == Approx(2 * b > std::sin(a) ? 0.0 : std::cos(a)).margin(1e-14));
        CHECK(H[3] == (2 * b > std::sin(a) ? 2.0 : 0.0));
    }
    CHECK(kinks_seen > 150);
}

TEST_CASE("expression systems evaluate alike from several threads at once", "[model][expr]") {
    std::unique_ptr<System> ex = expr_missile();
    const std::int64_t chunks = 32, per = 100;
    std::vector<double> x = missile_states(chunks * per, 11), serial(x.size()), parallel(x.size());
    for (std::int64_t c = 0; c < chunks; ++c) ex->drift(&serial[c * per * 6], &x[c * per * 6], 0.0, c % 2 ? per : 1);
#pragma omp parallel for num_threads(4) schedule(dynamic)
    for (std::int64_t c = 0; c < chunks; ++c) ex->drift(&parallel[c * per * 6], &x[c * per * 6], 0.0, c % 2 ? per : 1);
    CHECK(test::bitwise_equal(serial, parallel));
}

TEST_CASE("a large batch split over threads equals one state at a time, for any thread count", "[model][expr]") {
    // outside a parallel region a batch of >= 256 states is cut into contiguous blocks, one per thread; an uneven
    // count (1001 = 3 * 333 + 2 = 4 * 250 + 1) and several thread counts check the blocks cover every state once
    std::unique_ptr<System> ex = expr_missile();
    const std::int64_t count = 1001;
    const std::vector<double> x = missile_states(count, 5);
    std::vector<double> one(x.size());
    for (std::int64_t s = 0; s < count; ++s) ex->drift(&one[s * 6], &x[s * 6], 0.5, 1);
    const int before = omp_get_max_threads();
    for (int threads : {1, 2, 3, 4}) {  // not more: clang's libomp leaks its team bookkeeping (LSan) when a team grows past 4
        INFO(threads << " threads");
        omp_set_num_threads(threads);
        std::vector<double> batch(x.size(), NAN);
        ex->drift(batch.data(), x.data(), 0.5, count);
        CHECK(test::bitwise_equal(one, batch));
    }
    omp_set_num_threads(before);
}

TEST_CASE("a thread's cached workspace serves only its own system, also after another system is gone",
          "[model][expr]") {
    auto make = [](double a) {  // f = a*p: the value tells the systems apart
        ConfigDoc doc = ConfigDoc::from_text("[system]\nkind = \"expr\"\nstates = [\"p\", \"w\"]\ndisturbances = 1\n"
                                             "measurements = 1\nparameters = { a = " + std::to_string(a) + " }\n"
                                             "f = [\"a*p\", \"w*p\"]\ng = [[\"0\"], [\"1\"]]\nh = [\"p + a\"]\n",
                                             "cache.toml");
        return make_system(doc);
    };
    const double x[2] = {1.5, 2.0};
    auto f0 = [&x](const System& s) {
        double a[2];
        s.drift(a, x, 0.0, 1);
        return a[0];
    };
    std::unique_ptr<System> A = make(2), B = make(3);
    CHECK(f0(*A) == 3.0);
    CHECK(f0(*B) == 4.5);
    A.reset();  // its workspace stays in this thread's cache, marked expired
    std::unique_ptr<System> C = make(5), D = make(7);  // more systems than a thread caches
    for (int round = 0; round < 3; ++round) {
        CHECK(f0(*C) == 7.5);
        CHECK(f0(*B) == 4.5);
        CHECK(f0(*D) == 10.5);
    }
    std::vector<double> got(300);
#pragma omp parallel for num_threads(3) schedule(dynamic)
    for (int i = 0; i < 300; ++i) got[std::size_t(i)] = f0(i % 3 == 0 ? *B : i % 3 == 1 ? *C : *D);
    for (int i = 0; i < 300; ++i) CHECK(got[std::size_t(i)] == (i % 3 == 0 ? 4.5 : i % 3 == 1 ? 7.5 : 10.5));
}

TEST_CASE("expression missile trains like the built-in missile for 20 time steps, to float round-off",
          "[train][expr]") {
    // Tolerance: the two systems differ by a few double ulps (test above); the network computes in float, so
    // after 20 time steps of 30 Adam steps the estimates may differ by float round-off carried through the gain:
    // weights to 1e-5 of the layer's largest weight (about 80 float ulps), x^ to 1e-9 relative (the gain's
    // float error times dt), loss to 1e-5. A ballistic coefficient changed by 1e-3 must exceed it.
    // N = 500, M = 250 instead of the configs' 2000 and 800: the systems are compared through the same code path,
    // and a quarter of the samples keeps this test from being the sanitizer run's longest (160 s there).
    auto run = [](const std::string& config, std::vector<std::string> sets, const std::string& dir) {
        ConfigDoc doc = ConfigDoc::from_file(test::source_path(config));
        sets.insert(sets.begin(), {"training.samples=500", "training.batch=250"});
        for (const auto& s : sets) doc.set(s);
        TrainOptions opt;
        opt.out_dir = dir;
        opt.until = 0.2;  // 20 time steps of 0.01 s
        opt.quiet = true;
        TrainSummary s = train_start(load_run_config(doc), opt);
        REQUIRE(s.status == 0);
        REQUIRE(s.last_step == 20);
    };
    struct Gap {
        double weights = 0, xhat = 0, loss = 0;
    };
    auto gap = [](const std::string& a, const std::string& b) {
        Gap g;
        Checkpoint<float> A = ckpt_read<float>(a + "/checkpoint.h5"), B = ckpt_read<float>(b + "/checkpoint.h5");
        double big = 0;
        for (float w : B.net.theta) big = std::max(big, double(std::fabs(w)));
        for (std::size_t i = 0; i < A.net.theta.size(); ++i)
            g.weights = std::max(g.weights, std::fabs(double(A.net.theta[i]) - double(B.net.theta[i])) / big);
        h5::Handle fa = h5::open_file(a + "/trajectory.h5", false), fb = h5::open_file(b + "/trajectory.h5", false);
        g.xhat = test::max_rel_diff(h5::read_doubles(fa.get(), "xhat"), h5::read_doubles(fb.get(), "xhat"));
        g.loss = test::max_rel_diff(h5::read_doubles(fa.get(), "loss"), h5::read_doubles(fb.get(), "loss"));
        return g;
    };
    TempDir dir("expr-train");
    run("runs/missile_hinf.toml", {}, dir / "builtin");
    run("runs/missile_expr.toml", {}, dir / "expr");
    Gap same = gap(dir / "expr", dir / "builtin");
    INFO("weights " << same.weights << " xhat " << same.xhat << " loss " << same.loss);
    CHECK(same.weights <= 1e-5);
    CHECK(same.xhat <= 1e-9);
    CHECK(same.loss <= 1e-5);
    run("runs/missile_expr.toml", {"system.parameters.ballistic_coefficient=40040.0"}, dir / "perturbed");
    Gap off = gap(dir / "perturbed", dir / "builtin");
    INFO("perturbed: weights " << off.weights << " xhat " << off.xhat << " loss " << off.loss);
    CHECK((off.weights > 1e-5 || off.xhat > 1e-9 || off.loss > 1e-5));
}

TEST_CASE("expression errors are one line naming the key, the expression and the position", "[cli][expr]") {
    TempDir dir("expr-errors");
    auto bad = [&](const std::string& system_extra, const std::string& fragment,
                   const std::string& filter_extra = kStart) {
        std::string text = vdp_config(system_extra, filter_extra);
        test::expect_one_line_error("train " + test::write_file(dir, "bad.toml", text) + " --out " + (dir / "out"),
                                    fragment);
    };
    auto replace = [](std::string text, const std::string& from, const std::string& to) {
        text.replace(text.find(from), from.size(), to);
        return text;
    };
    const std::string ok = vdp_config("", kStart);
    auto bad_text = [&](const std::string& text, const std::string& fragment) {
        test::expect_one_line_error("train " + test::write_file(dir, "bad.toml", text) + " --out " + (dir / "out"),
                                    fragment);
    };
    SECTION("unknown symbol, with its position") {
        bad_text(replace(ok, "mu*(1 - p^2)*w - p", "mu*(1 - p^2)*v - p"),
                 "[system] f entry 2 \"mu*(1 - p^2)*v - p\": unknown symbol 'v' at character 14 (known: p, w, c, mu, "
                 "t, pi)");
    }
    SECTION("a definition is unknown to the expressions before it (one parser checks them all, in order)") {
        bad("definitions = [\"r = s + p\", \"s = w\"]\n", "definitions entry 1 \" s + p\": unknown symbol 's' at character");
        bad("definitions = [\"r = s + p\", \"s = w\"]\n", "(known: p, w, c, mu, t, pi)");
    }
    SECTION("parse error, with its position") {
        bad_text(replace(ok, "p + c*p^3", "p + c*(p^3"), "[system] h entry 1 \"p + c*(p^3\": ");
        bad_text(replace(ok, "p + c*p^3", "p + c*(p^3"), "Missing parenthesis at character 12");
    }
    SECTION("dimension mismatch") {
        bad_text(replace(ok, "measurements = 1", "measurements = 2"),
                 "h has 1 entries, expected 2 (one per measurement)");
        bad_text(replace(ok, "f = [\"w\", ", "f = ["), "f has 1 entries, expected 2 (one per state)");
        bad_text(replace(ok, "g = [[\"0\"], [\"1\"]]", "g = [[\"0\", \"1\"], [\"1\"]]"),
                 "g row 1 has 2 entries, expected 1 (one entry per disturbance)");
    }
    SECTION("what muParser reads but GiNaC cannot differentiate") {
        bad_text(replace(ok, "p + c*p^3", "p > 0 ? p : 0"),
                 "\"p > 0 ? p : 0\": GiNaC, which differentiates it, cannot read it (expected EOF, got: \">\")");
        bad_text(replace(ok, "p + c*p^3", "sqrt(-2)*p"), "\"sqrt(-2)*p\": has the complex value");
    }
    SECTION("names") {
        bad_text(replace(ok, "[\"p\", \"w\"]", "[\"p\", \"p\"]"), "state 'p' is defined twice");
        bad_text(replace(ok, "[\"p\", \"w\"]", "[\"p\", \"t\"]"), "state 't' is reserved");
        bad_text(replace(ok, "[\"p\", \"w\"]", "[\"p\", \"I\"]"), "state 'I' is reserved (the time t, a constant");
        bad("definitions = [\"speed w\"]\n",
            "[system] definitions entry 1 \"speed w\" must read \"name = expression\"");
    }
    SECTION("required keys") {
        bad("", "[filter] x0: is required for [system] kind = \"expr\"", "");
        bad_text(replace(ok, "h = [\"p + c*p^3\"]\n", ""), "[system] h: is required for kind = \"expr\"");
        bad("radar = [1, 2, 3]\n", "unknown key 'radar'");
    }
}

TEST_CASE("train, compare (every filter) and operate run on an expression system", "[cli][expr]") {
    TempDir dir("expr-cli");
    std::string cfg = test::write_file(dir, "vdp.toml", vdp_config("", kStart));
    test::CommandResult r = test::run_hinf("train " + cfg + " --quiet --out " + (dir / "train"));
    INFO(r.output);
    REQUIRE(r.status == 0);
    const std::string ckpt = dir / "train/checkpoint.h5";
    r = test::run_hinf(
        "compare " + cfg + " --network " + ckpt +
        " --filters dnn,ekf,ukf,pf,glf,open_loop --glf-vertices 2 --particles 200 --runs 2 --quiet --out " +
        (dir / "compare"));
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK(r.output.find("ekf") != std::string::npos);
    CHECK(r.output.find("glf") != std::string::npos);
    r = test::run_hinf("operate " + cfg + " --network " + ckpt + " --runs 2 --mode measured --quiet --out " +
                       (dir / "operate"));
    INFO(r.output);
    CHECK(r.status == 0);
}

TEST_CASE("hinf bench reports the expression evaluation cost per state", "[cli][bench][expr]") {
    TempDir dir("expr-bench");
    test::CommandResult r = test::run_hinf("bench --threads 1 --precision f32 --batch 40 --repeats 3 --expr-config " +
                                           test::source_path("runs/vanderpol.toml") + " --out " + (dir / "b"));
    INFO(r.output);
    REQUIRE(r.status == 0);
    CHECK(r.output.find("f ns/state") != std::string::npos);
    h5::Handle f = h5::open_file(dir / "b/bench.h5", false);
    for (const char* key :
         {"expr_f_ns_per_state", "expr_g_ns_per_state", "expr_h_ns_per_state", "expr_drift_jacobian_us",
          "expr_measurement_jacobian_us", "expr_eval_ms_per_time_step", "expr_time_step_ms"}) {
        INFO(key);
        CHECK(h5::get_attr_double(f.get(), key) > 0);
    }
}

TEST_CASE("the example configs of expression systems load", "[model][expr]") {
    RunConfig vdp = load_run_config(ConfigDoc::from_file(test::source_path("runs/vanderpol.toml")));
    CHECK(vdp.system->name() == "expr");
    CHECK(vdp.n == 2);
    CHECK(vdp.nv == 1);
    CHECK(vdp.m == 1);
    CHECK(vdp.system->state_units() == std::vector<std::string>{"m", "m/s"});
    // Van der Pol at (p, w) = (2, 0.5): f = (w, mu (1 - p^2) w - p), h = p + c p^3, exact Jacobians
    double x[2] = {2.0, 0.5}, a[2], c[1], J[4], H[2];
    vdp.system->drift(a, x, 0.0, 1);
    vdp.system->measurement(c, x, 0.0, 1);
    vdp.system->drift_jacobian(J, x, 0.0);
    vdp.system->measurement_jacobian(H, x, 0.0);
    CHECK(a[0] == 0.5);
    CHECK(a[1] == Approx(-3.5).epsilon(1e-15));
    CHECK(c[0] == Approx(2.0 + 0.3 * 8.0).epsilon(1e-15));
    CHECK(J[0] == 0.0);
    CHECK(J[1] == 1.0);
    CHECK(J[2] == Approx(-2.0 * 2.0 * 0.5 - 1.0).epsilon(1e-15));  // -2 mu p w - 1
    CHECK(J[3] == Approx(1.0 - 4.0).epsilon(1e-15));              // mu (1 - p^2)
    CHECK(H[0] == Approx(1.0 + 0.9 * 4.0).epsilon(1e-15));        // 1 + 3 c p^2
    CHECK(H[1] == 0.0);
    RunConfig me = load_run_config(ConfigDoc::from_file(test::source_path("runs/missile_expr.toml")));
    RunConfig mb = load_run_config(ConfigDoc::from_file(test::source_path("runs/missile_hinf.toml")));
    // everything but [system] is the built-in missile's config
    CHECK(me.x0 == mb.x0);
    CHECK(me.xhat0 == mb.xhat0);
    CHECK(me.Q == mb.Q);
    CHECK(me.rho == mb.rho);
    CHECK(me.hidden == mb.hidden);
    CHECK(me.samples == mb.samples);
    CHECK(me.adam_steps == mb.adam_steps);
    CHECK(me.t_final == mb.t_final);
}

TEST_CASE("expression programs are printed in hinf's order: the same text however GiNaC orders its terms",
          "[model][expr]") {
    // GiNaC orders a sum's terms by hashes of its symbols, which change with every new symbol (and with the
    // library's load address): a second system built in the same process used to print another order
    ConfigDoc doc = ConfigDoc::from_text(rich_vdp_config(), "rich.toml");
    const std::vector<std::string> first = all_programs(*make_system(doc));
    for (int again = 0; again < 4; ++again) {
        INFO("build " << again + 2);
        CHECK(all_programs(*make_system(doc)) == first);
    }
    // the order: operands of sums and products sorted by their text, a sum's number last, x^n as x*...*x;
    // a sum's sign is ours too: 1/(a - b) and -1/(b - a) print alike
    ConfigDoc vdp = ConfigDoc::from_text(vdp_config("", kStart), "vdp.toml");
    const auto vdp_sys = make_system(vdp);  // kept alive: es points into it
    const auto* es = dynamic_cast<const ExprSystem*>(vdp_sys.get());
    REQUIRE(es);
    CHECK(es->compiled("h") == std::vector<std::string>{"(p*p*p)*c+p"});
    struct Case {
        const char *h, *text, *dh_dp;
    };
    for (const Case& c :
         {Case{"1/(p - w)", "1.0/(p-w)", "-1.0/pow(p-w,2.0)"}, Case{"-1/(w - p)", "1.0/(p-w)", "-1.0/pow(p-w,2.0)"},
          Case{"2/(w - p)", "-2.0/(p-w)", "2.0/pow(p-w,2.0)"}}) {
        INFO(c.h);
        std::string text = vdp_config("", kStart);
        text.replace(text.find("p + c*p^3"), 9, c.h);
        std::unique_ptr<System> sys = make_system(ConfigDoc::from_text(text, "vdp.toml"));
        const auto* e = dynamic_cast<const ExprSystem*>(sys.get());
        REQUIRE(e);
        CHECK(e->compiled("h") == std::vector<std::string>{c.text});
        CHECK(e->compiled("dh").at(0) == c.dh_dp);
    }
}

TEST_CASE("an expression system's EKF is the same bits in every process (address-space randomisation on)",
          "[cli][expr]") {
    // separate `hinf filter` processes on one record: GiNaC's order changed with each process's load address
    TempDir dir("expr-bits");
    const std::string cfg = test::write_file(dir, "rich.toml", rich_vdp_config());
    std::string record = "t,y1,y2\n";
    char row[128];
    for (int k = 0; k < 100; ++k) {
        const double t = 0.01 * k, p = 2 * std::cos(t), w = -2 * std::sin(t);
        std::snprintf(row, sizeof row, "%.17g,%.17g,%.17g\n", t, p + 0.3 * p * p * p + 0.05 * std::sin(37 * t),
                      std::sqrt(1 + p * p + w * w) + 0.02 * std::cos(11 * t));
        record += row;
    }
    const std::string csv = test::write_file(dir, "rec.csv", record);
    std::vector<double> first_x, first_p;
    for (int run = 0; run < 4; ++run) {
        const std::string out = dir / ("run" + std::to_string(run));
        test::CommandResult r =
            test::run_hinf("filter " + cfg + " --measurements " + csv + " --filters ekf --quiet --out " + out);
        INFO(r.output);
        REQUIRE(r.status == 0);
        h5::Handle f = h5::open_file(out + "/estimates.h5", false);
        h5::Handle g = h5::open_group(f.get(), "ekf");
        std::vector<double> x = h5::read_doubles(g.get(), "xhat"), P = h5::read_doubles(g.get(), "P");
        REQUIRE(x.size() == 200u);
        if (run == 0) {
            first_x = x;
            first_p = P;
            continue;
        }
        INFO("run " << run << ": largest relative difference to run 0 " << test::max_rel_diff(x, first_x));
        CHECK(test::bitwise_equal(x, first_x));
        CHECK(test::bitwise_equal(P, first_p));
    }
}

namespace {

// A random expression as text (for the config) and its value computed here in C++: an oracle for the printer
// that does not share its code. States p, w in [-1, 1], parameter q; divisors and pow bases kept away from 0.
struct RandomExpr {
    std::mt19937_64& rng;
    int pick(int n) { return int(rng() % std::uint64_t(n)); }
    // text and value at (p, w) with q; a copy of one generator draws the same expression at every point
    std::pair<std::string, double> node(int depth, double p, double w, double q) {
        if (depth == 0) {
            switch (pick(5)) {
                case 0:
                    return {"p", p};
                case 1:
                    return {"w", w};
                case 2:
                    return {"q", q};
                case 3:
                    return {"0.3", 0.3};
                default:
                    return {"2", 2.0};
            }
        }
        auto a = node(depth - 1, p, w, q), b = node(depth - 1, p, w, q);
        const std::string A = "(" + a.first + ")", B = "(" + b.first + ")";
        switch (pick(9)) {
            case 0:
                return {A + " + " + B, a.second + b.second};
            case 1:
                return {A + " - " + B, a.second - b.second};
            case 2:
                return {A + "*" + B, a.second * b.second};
            case 3:
                return {A + "/(3 + " + B + "^2)", a.second / (3 + b.second * b.second)};
            case 4:
                return {"1/(" + A + " - " + B + " + 40)", 1 / (a.second - b.second + 40)};  // a sum's sign
            case 5:
                return {A + "^3 - " + B + "^2", a.second * a.second * a.second - b.second * b.second};
            case 6:
                return {"sin(" + a.first + ")*cos(" + b.first + ")", std::sin(a.second) * std::cos(b.second)};
            case 7:
                return {"sqrt(1 + " + A + "^2)", std::sqrt(1 + a.second * a.second)};
            default:
                return {"atan(" + a.first + ") - 0.5*" + B, std::atan(a.second) - 0.5 * b.second};
        }
    }
};

}  // namespace

TEST_CASE("the canonical programs of random expressions equal the expressions, and Jacobians agree", "[model][expr]") {
    // 60 random expressions (depth 3): the printed programs (sorted terms, signs moved out of sums) must give
    // the values the expressions have; the exact Jacobian is checked against central differences
    const std::uint64_t seed = 20261125;
    INFO("std::mt19937_64 seed " << seed);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const double q = 0.7;
    for (int trial = 0; trial < 60; ++trial) {
        const std::uint64_t expr_seed = rng();
        auto at = [&](double p, double w) {
            std::mt19937_64 r(expr_seed);
            return RandomExpr{r}.node(3, p, w, q);
        };
        const std::string text = at(0, 0).first;
        INFO(text);
        std::string cfg = vdp_config("", kStart);
        cfg.replace(cfg.find("p + c*p^3"), 9, text);
        cfg.replace(cfg.find("c = 0.3"), 7, "c = 0.3, q = 0.7");
        std::unique_ptr<System> sys = make_system(ConfigDoc::from_text(cfg, "random.toml"));
        INFO("printed " << dynamic_cast<const ExprSystem&>(*sys).compiled("h").at(0));
        for (int point = 0; point < 5; ++point) {
            double x[2] = {u(rng), u(rng)}, c = 0, H[2];
            sys->measurement(&c, x, 0.0, 1);
            const double want = at(x[0], x[1]).second;
            CHECK(std::fabs(c - want) <= 1e-12 * std::max(1.0, std::fabs(want)));
            sys->measurement_jacobian(H, x, 0.0);
            for (int j = 0; j < 2; ++j) {
                const double eps = 1e-6;
                double xp[2] = {x[0], x[1]}, xm[2] = {x[0], x[1]};
                xp[j] += eps;
                xm[j] -= eps;
                const double fd = (at(xp[0], xp[1]).second - at(xm[0], xm[1]).second) / (2 * eps);
                // central differences: truncation ~eps^2, round-off ~1e-16 |h| / eps
                CHECK(H[j] == Approx(fd).margin(1e-6 + 1e-9 * std::fabs(want)).epsilon(1e-6));
            }
        }
    }
}
