// The worst-case search (issue 13 parts 2-3): on linear systems with a fixed-gain filter the exact worst-case
// ratio over the horizon is the largest singular value of the error system's input-output map (computed here
// by power iteration, independently of the search); the search must reach 90 % of it and may never exceed it.
// Budget: LN_SBPLX, 3 starts of 500 (scalar) / 400 (oscillator) evaluations; measured 96.9 % and 95.1 % of the exact
// value (SBPLX at 300 evaluations: 92 %, 93 %; LN_BOBYQA reached 97 % on the scalar but 54 % on the oscillator).
// Also: the ratio the search reports is the engine's, bit for bit, and does not depend on the thread count.
#include <algorithm>
#include <catch2/catch.hpp>
#include <cmath>
#include <omp.h>

#include "eval/engine.hpp"
#include "eval/worst.hpp"
#include "filters/ekf.hpp"
#include "filters/gain_law.hpp"
#include "filters/pf.hpp"
#include "filters/ukf.hpp"
#include "helpers.hpp"
#include "hinf/h5.hpp"
#include "random.hpp"

using namespace hinf;
using hinf::test::TempDir;

namespace {

// x^_{k+1} = x^_k + dt (A(x^_k) + L (y_k - C(x^_k))): a Luenberger filter with one constant gain L [n x m].
class FixedGainFilter final : public OnlineFilter {
public:
    FixedGainFilter(const FilterModel& model, std::vector<double> L) : model_(model), L_(std::move(L)) {}
    std::string name() const override { return "fixed_gain"; }
    void reset(const FilterStart& s) override { xhat_ = s.xhat0; }
    FilterStatus step(const FilterInput& in) override {
        const System& sys = *model_.system;
        const int n = sys.state_dim(), m = sys.output_dim();
        std::vector<double> a(n), c(m), e(m);
        sys.drift(a.data(), xhat_.data(), in.t, 1);
        sys.measurement(c.data(), xhat_.data(), in.t, 1);
        for (int j = 0; j < m; ++j) e[j] = in.y[j] - c[j];
        luenberger_advance(xhat_.data(), xhat_.data(), a.data(), L_.data(), e.data(), n, m, model_.dt);
        return FILTER_OK;
    }
    const double* estimate() const override { return xhat_.data(); }
    std::unique_ptr<OnlineFilter> clone() const override { return std::make_unique<FixedGainFilter>(*this); }

private:
    FilterModel model_;
    std::vector<double> L_, xhat_;
};

// The error system of that filter on x_{k+1} = x_k + dt (A x_k + B v_k), y_k = C x_k + n_k:
// e_{k+1} = Phi e_k + Gam w_k, Phi = I + dt (A - L C), Gam = [dt B, -dt L], e_0 = 0, scored e_0 ... e_{K-1}.
// Returns max over w of sum e'Qe / sum w'w (dt cancels) by power iteration on G'QG.
double exact_finite_horizon_gain(const std::vector<double>& Phi, const std::vector<double>& Gam,
                                 const std::vector<double>& Q, int n, int p, std::int64_t K) {
    std::vector<double> w(K * p), e(K * n), g(n), gn(n), Qe(n);
    for (std::int64_t i = 0; i < K * p; ++i) w[i] = 1.0 + 0.001 * double(i % 7);  // not orthogonal to the top one
    double lambda = 0;
    for (int it = 0; it < 3000; ++it) {
        // e = G w
        std::vector<double> x(n, 0.0), xn(n);
        for (std::int64_t k = 0; k < K; ++k) {
            for (int i = 0; i < n; ++i) e[k * n + i] = x[i];
            for (int i = 0; i < n; ++i) {
                double s = 0;
                for (int j = 0; j < n; ++j) s += Phi[i * n + j] * x[j];
                for (int j = 0; j < p; ++j) s += Gam[i * p + j] * w[k * p + j];
                xn[i] = s;
            }
            x = xn;
        }
        // w' = G' Q e: adjoint g_k = sum_{j > k} Phi^{j-k-1}' Q e_j, backwards; w'_k = Gam' g_k
        std::fill(g.begin(), g.end(), 0.0);
        double ww = 0, eqe = 0;
        for (std::int64_t k = K - 1; k >= 0; --k) {
            std::vector<double> wk(p, 0.0);
            for (int j = 0; j < p; ++j)
                for (int i = 0; i < n; ++i) wk[j] += Gam[i * p + j] * g[i];
            // g_{k-1} = Q e_k + Phi' g_k
            for (int i = 0; i < n; ++i) {
                double s = 0;
                for (int j = 0; j < n; ++j) s += Q[i * n + j] * e[k * n + j] + Phi[j * n + i] * g[j];
                gn[i] = s;
            }
            for (int j = 0; j < p; ++j) ww += w[k * p + j] * w[k * p + j];
            eqe += quadratic_form(Q.data(), e.data() + k * n, n);
            for (int j = 0; j < p; ++j) w[k * p + j] = wk[j];
            g = gn;
        }
        lambda = eqe / ww;  // Rayleigh quotient of the previous iterate
        double norm = 0;
        for (double v : w) norm += v * v;
        norm = std::sqrt(norm);
        for (double& v : w) v /= norm;
    }
    return lambda;
}

RunConfig linear_config(const std::string& system, const std::string& n_keys, double t_final) {
    return load_run_config(ConfigDoc::from_text(system + "[filter]\n" + n_keys + "dt = 0.01\nt_final = " +
                                                    std::to_string(t_final) +
                                                    "\n[online]\ndisturbance_std = 1.0\nnoise_std = 1.0\n",
                                                "linear.toml"));
}

}  // namespace

TEST_CASE("worst-case search reaches the exact worst-case gain of a fixed-gain filter", "[eval][worst][known]") {
    SECTION("scalar: x' = -x + v, y = x + n, L = 1 (worst at DC)") {
        RunConfig cfg = linear_config(
            "[system]\nkind = \"expr\"\nstates = [\"x\"]\nunits = [\"m\"]\ndisturbances = 1\nmeasurements = 1\n"
            "f = [\"-x\"]\ng = [[\"1\"]]\nh = [\"x\"]\n",
            "Q = [1.0]\nx0 = [0.0]\nxhat0 = [0.0]\n", 5.0);
        FixedGainFilter f(filter_model(cfg), {1.0});
        const double dt = cfg.dt, phi = 1.0 + dt * (-1.0 - 1.0);
        const std::int64_t K = cfg.steps_until();
        const double exact = exact_finite_horizon_gain({phi}, {dt, -dt}, {1.0}, 1, 2, K);
        const double hinf_norm2 = dt * dt * 2.0 / ((1 - phi) * (1 - phi));  // |G(e^{i0})|^2: the infinite horizon
        CHECK(exact <= hinf_norm2);
        CHECK(exact >= 0.9 * hinf_norm2);  // 5 s is ten time constants: the finite horizon is close to the norm
        WorstOptions opt;
        opt.random_starts = 2;
        opt.scenario_starts = {"nominal"};
        opt.evals = 500;
        opt.quiet = true;
        WorstResult r = worst_search(cfg, {&f}, {}, opt);
        const double found = r.filters[0].worst.ratio;
        const double linear = r.filters[0].linear_gain;
        INFO("exact " << exact << ", H-inf norm^2 " << hinf_norm2 << ", found " << found << ", linear " << linear);
        CHECK(found >= 0.90 * exact);
        CHECK(found <= exact * (1 + 1e-9));  // a ratio above the exact maximum would be a wrong ratio
        // the linear start: the maximum over 20 pieces a channel, so at most the exact one over every signal
        CHECK(linear <= exact * (1 + 1e-9));
        CHECK(linear >= 0.90 * exact);
    }
    SECTION("oscillator: resonance at 1 Hz, zeta = 0.05, L = [1, 0.5] (worst is a sinusoid)") {
        const double w0 = 2 * M_PI, zeta = 0.05;
        RunConfig cfg = linear_config(
            "[system]\nkind = \"expr\"\nstates = [\"p\", \"w\"]\nunits = [\"m\", \"m/s\"]\ndisturbances = 1\n"
            "measurements = 1\nparameters = { a = " + std::to_string(w0 * w0) + ", b = " +
                std::to_string(2 * zeta * w0) + " }\nf = [\"w\", \"-a*p - b*w\"]\ng = [[\"0\"], [\"1\"]]\nh = [\"p\"]\n",
            "Q = [1.0, 1.0]\nx0 = [0.0, 0.0]\nxhat0 = [0.0, 0.0]\n", 8.0);
        const double l1 = 1.0, l2 = 0.5, dt = cfg.dt, a = w0 * w0, b = 2 * zeta * w0;
        FixedGainFilter f(filter_model(cfg), {l1, l2});
        // Phi = I + dt (A - L C), A = [[0, 1], [-a, -b]], C = [1, 0]; Gam = [dt B, -dt L]
        const std::vector<double> Phi = {1 - dt * l1, dt, -dt * a - dt * l2, 1 - dt * b};
        const std::vector<double> Gam = {0.0, -dt * l1, dt, -dt * l2};
        const std::int64_t K = cfg.steps_until();
        const double exact = exact_finite_horizon_gain(Phi, Gam, {1, 0, 0, 1}, 2, 2, K);
        WorstOptions opt;
        opt.random_starts = 3;
        opt.scenario_starts = {"nominal"};
        opt.evals = 400;
        opt.quiet = true;
        WorstResult r = worst_search(cfg, {&f}, {}, opt);
        const double found = r.filters[0].worst.ratio, linear = r.filters[0].linear_gain;
        INFO("exact " << exact << ", found " << found << ", linear " << linear);
        CHECK(found >= 0.90 * exact);
        CHECK(found <= exact * (1 + 1e-9));
        CHECK(linear <= exact * (1 + 1e-9));
    }
}

TEST_CASE("the linear start: on a linear system no signal of its pieces scores above its gain and its own reaches it",
          "[eval][worst]") {
    // the oscillator above with a fixed gain: the error is linear in the signals, so the ratio does not depend on
    // the energy and the small-signal figure is the maximum over every piecewise-constant signal of those pieces
    const double w0 = 2 * M_PI, zeta = 0.05;
    const RunConfig cfg = linear_config(
        "[system]\nkind = \"expr\"\nstates = [\"p\", \"w\"]\nunits = [\"m\", \"m/s\"]\ndisturbances = 1\n"
        "measurements = 1\nparameters = { a = " + std::to_string(w0 * w0) + ", b = " + std::to_string(2 * zeta * w0) +
            " }\nf = [\"w\", \"-a*p - b*w\"]\ng = [[\"0\"], [\"1\"]]\nh = [\"p\"]\n",
        "Q = [1.0, 1.0]\nx0 = [0.0, 0.0]\nxhat0 = [0.0, 0.0]\n", 4.0);
    FixedGainFilter f(filter_model(cfg), {1.0, 0.5});
    WorstOptions opt;
    opt.linear_pieces = 8;
    opt.quiet = true;
    omp_set_num_threads(1);
    const double g1 = worst_small_signal(cfg, f, opt);
    omp_set_num_threads(2);
    const double gain = worst_small_signal(cfg, f, opt);
    CHECK(g1 == gain);  // each basis run a pure function of its index: any thread count, the same bits
    REQUIRE(gain > 0);
    const RunConfig c = worst_config(cfg, opt);
    const std::int64_t K = c.steps_until();
    // random signals constant on the same 8 pieces of each channel
    std::vector<double> u(2 * 8);
    double best = 0;
    for (std::uint64_t draw = 0; draw < 12; ++draw) {
        kern::rng_uniform(u.data(), int(u.size()), 5, 0, draw, 0);
        Signals s{std::vector<double>(K), std::vector<double>(K)};
        for (std::int64_t k = 0; k < K; ++k) {
            s.v[k] = u[k * 8 / K] - 0.5;
            s.n[k] = u[8 + k * 8 / K] - 0.5;
        }
        const double r = worst_ratio(c, f, s, K);
        CHECK(r <= gain * (1 + 1e-9));
        best = std::max(best, r);
    }
    CHECK(best < gain);  // random draws fall short of the maximum
    // its own signal (the search's "linear" start, at the budget) reaches the gain: the start's ratio
    opt.random_starts = 0;
    opt.scenario_starts = {};
    opt.evals = 1;
    opt.cross_starts = false;
    const WorstResult r = worst_search(cfg, {&f}, {}, opt);
    REQUIRE(r.filters[0].restarts.size() == 1u);
    CHECK(r.filters[0].restarts[0].start == "linear");
    CHECK(r.filters[0].restarts[0].start_ratio == Approx(gain).epsilon(1e-9));
    CHECK(r.filters[0].linear_gain == gain);
    // 0 pieces: no linear start and no figure
    opt.linear_pieces = 0;
    CHECK(std::isnan(worst_small_signal(cfg, f, opt)));
    // a particle filter's resampling does not respond linearly to small signals: its eigenvector's own difference
    // misses the eigenvalue, and it gets no figure, where a smooth filter on the same system gets one
    const RunConfig vdp = load_run_config(ConfigDoc::from_file(hinf::test::source_path("runs/vanderpol.toml")));
    WorstOptions vo;
    vo.until = 1.0;
    vo.linear_pieces = 4;
    vo.quiet = true;
    CHECK(std::isnan(worst_small_signal(vdp, *make_particle_filter(filter_model(vdp), 50), vo)));
    CHECK(worst_small_signal(vdp, *make_ekf(filter_model(vdp)), vo) > 0);
}

TEST_CASE("worst-case search: the engine replays the same ratio, any thread count, budget kept", "[eval][worst]") {
    ConfigDoc doc = ConfigDoc::from_file(hinf::test::source_path("runs/vanderpol.toml"));
    RunConfig cfg = load_run_config(std::move(doc));
    auto ekf = make_ekf(filter_model(cfg));
    WorstOptions opt;
    opt.until = 2.0;
    opt.random_starts = 2;
    opt.scenario_starts = {"energy_pulse"};
    opt.evals = 30;
    opt.quiet = true;
    opt.linear_steps = 0;  // the first level only: its bits on 1 and 2 threads, not the doubling's cost
    omp_set_num_threads(1);
    WorstResult r1 = worst_search(cfg, {ekf.get()}, {}, opt);
    omp_set_num_threads(2);
    WorstResult r2 = worst_search(cfg, {ekf.get()}, {}, opt);
    REQUIRE(r1.filters[0].restarts.size() == 4);  // 2 random, the pulse, the linear start
    CHECK(r1.filters[0].restarts[3].start == "linear");
    for (std::size_t i = 0; i < 4; ++i) CHECK(r1.filters[0].restarts[i].ratio == r2.filters[0].restarts[i].ratio);
    CHECK(r1.filters[0].linear_gain == r2.filters[0].linear_gain);
    CHECK(r1.filters[0].worst.signals.v == r2.filters[0].worst.signals.v);
    // the replay through the engine (eval/engine.cpp) gives the search's ratio bit for bit
    CHECK(r1.cross.ratio[0] == r1.filters[0].worst.ratio);
    // every candidate carries exactly the budget
    CHECK(r1.cross.signal_energy[0] == Approx(r1.energy).epsilon(1e-12));
    // the search improved on its starts
    for (const auto& rs : r1.filters[0].restarts) CHECK(rs.ratio >= rs.start_ratio);

    // the file round-trips; a file for another system is refused with a line naming the difference
    TempDir d("worst");
    worst_write(d / "worst.h5", worst_config(cfg, opt), opt, r1);
    std::int64_t steps = 0;
    bool keep = true;
    std::vector<WorstSignals> sets = worst_read(d / "worst.h5", cfg, &steps, &keep);
    CHECK(steps == r1.steps);
    CHECK_FALSE(keep);
    REQUIRE(sets.size() == 1);
    CHECK(sets[0].signals.n == r1.filters[0].worst.signals.n);
    RunConfig missile = load_run_config(ConfigDoc::from_file(hinf::test::source_path("runs/missile_hinf.toml")));
    CHECK_THROWS_WITH(worst_read(d / "worst.h5", missile, &steps, &keep), Catch::Contains("its signals are for system"));
}

TEST_CASE("worst-case search: a filter that diverges is frozen as the engine freezes it, so the replay gives its ratio",
          "[eval][worst]") {
    // x' = -x + v, y = x + n with L = -4: x^' = 3 x^ - 4 y, an error that grows as e^{3t}, past the engine's plausible
    // range (1000 times the truth's scale) within the 5 s under any signal. The engine freezes the estimate there; a
    // search that did not scored the runaway (a compressor model's EKF: 3.0e26 searched, 3.9e9 replayed).
    RunConfig cfg = linear_config(
        "[system]\nkind = \"expr\"\nstates = [\"x\"]\nunits = [\"m\"]\ndisturbances = 1\nmeasurements = 1\n"
        "f = [\"-x\"]\ng = [[\"1\"]]\nh = [\"x\"]\n",
        "Q = [1.0]\nx0 = [0.0]\nxhat0 = [0.0]\n", 5.0);
    FixedGainFilter f(filter_model(cfg), {-4.0});
    WorstOptions opt;
    opt.random_starts = 1;
    opt.scenario_starts = {"nominal"};
    opt.evals = 20;
    opt.linear_steps = 0;
    opt.quiet = true;
    WorstResult r = worst_search(cfg, {&f}, {}, opt);
    REQUIRE(r.cross.diverged_at.size() == 1);
    CHECK(r.cross.diverged_at[0] > 0);  // the replay froze it
    CHECK(std::isfinite(r.filters[0].worst.ratio));
    CHECK(r.cross.ratio[0] == r.filters[0].worst.ratio);  // bit for bit
    for (const auto& rs : r.filters[0].restarts) CHECK(rs.ratio <= r.filters[0].worst.ratio);
}

TEST_CASE("worst-case search starts the filters compare runs at the truth: their P0 stays", "[eval][worst]") {
    const RunConfig cfg = load_run_config(ConfigDoc::from_file(hinf::test::source_path("runs/vanderpol.toml")));
    WorstOptions opt;
    const RunConfig c = worst_config(cfg, opt);
    CHECK(c.xhat0 == cfg.x0);
    // EKF/UKF/PF keep compare's P0 = diag((x0 - x^0)^2), not one for the moved start (0) or a floor
    const std::vector<double> P0 = baseline_initial_covariance(cfg), Pw = engine_filter_start(c, 0).P0;
    REQUIRE(Pw.size() == P0.size());
    CHECK(Pw == P0);  // bit for bit
    CHECK(P0[0] == Approx(2.25).epsilon(1e-15));  // x0 - x^0 = (1.5, -1)
    // a P0 the config names is kept as it is; --keep-initial-error changes nothing
    RunConfig named = cfg;
    named.initial_std = {0.1, 0.2};
    CHECK(worst_config(named, opt).initial_std == named.initial_std);
    opt.keep_initial_error = true;
    const RunConfig k = worst_config(cfg, opt);
    CHECK(k.xhat0 == cfg.xhat0);
    CHECK(k.initial_std.empty());
}

namespace {

// Van der Pol over 3 s with two random starts and short local searches: the cross-start tests' search
WorstOptions short_cross_search() {
    WorstOptions opt;
    opt.until = 3.0;
    opt.random_starts = 2;
    opt.scenario_starts = {};
    opt.evals = 16;
    opt.quiet = true;
    return opt;
}

}  // namespace

TEST_CASE("worst-case search: a filter whose worst set is its linear start also offers its searched set",
          "[eval][worst]") {
    // The linear start can make a filter's worst set its small-signal direction; the set its other starts found may
    // still be what breaks another filter, and adding the linear start must not take that cross start away.
    const RunConfig cfg = load_run_config(ConfigDoc::from_file(hinf::test::source_path("runs/vanderpol.toml")));
    auto ekf = make_ekf(filter_model(cfg));
    auto ukf = make_ukf(filter_model(cfg));
    FixedGainFilter fixed(filter_model(cfg), {2.0, 1.0});
    // a filter with no linear start (a particle filter's resampling is not differentiable): its own best is what its
    // random restarts found, and the UKF's searched set beats it here (0.311 against 0.291)
    auto pf = make_particle_filter(filter_model(cfg), 100);
    const std::vector<const OnlineFilter*> filters = {ekf.get(), ukf.get(), &fixed, pf.get()};
    const int F = 4;
    WorstOptions opt = short_cross_search();
    opt.until = 2.0;
    opt.energy = 30;
    opt.linear_pieces = 20;
    const WorstResult on = worst_search(cfg, filters, {}, opt);
    // the same restarts without the linear start: their worst sets are the searched sets (restarts are pure
    // functions of their inputs), replayed here against every filter
    opt.linear_pieces = 0;
    opt.cross_starts = false;
    const WorstResult searched = worst_search(cfg, filters, {}, opt);
    const WorstReplay& by = searched.cross;
    int offered = 0;
    for (int i = 0; i < F; ++i) {
        const auto& rs = on.filters[i].restarts;
        std::size_t first = 0;  // the first round: the restarts that are not cross starts
        while (first < rs.size() && rs[first].start.rfind("cross:", 0) != 0) ++first;
        double own = 0;
        for (std::size_t j = 0; j < first; ++j) own = std::max(own, rs[j].ratio);
        const bool has_linear = std::any_of(rs.begin(), rs.begin() + first, [](const auto& r) { return r.start == "linear"; });
        REQUIRE(first == searched.filters[i].restarts.size() + (has_linear ? 1 : 0));  // + its linear start, if any
        for (int d = 0; d < F; ++d) {
            if (d == i) continue;
            const auto& rd = on.filters[d].restarts;
            double best_other = -1;
            bool linear_best = false;
            for (const auto& r : rd) {
                if (r.start.rfind("cross:", 0) == 0) break;
                if (r.ratio > best_other) {
                    best_other = r.ratio;
                    linear_best = r.start == "linear";
                }
            }
            const std::string label = "cross:" + on.filters[d].name + ":searched";
            const double r = by.ratio[std::size_t(d) * F + i];
            bool found = false;  // its first offer is in the second round, where that set beat this filter's own
            for (std::size_t j = first; j < rs.size() && !found; ++j)
                if (rs[j].start == label) {
                    found = true;
                    CHECK(rs[j].start_ratio == Approx(r).epsilon(1e-9));  // diverged or not: frozen alike
                    CHECK(rs[j].ratio >= rs[j].start_ratio);
                }
            if (linear_best && r > own) CHECK(found);
            if (!linear_best) CHECK_FALSE(found);
            if (found) {
                ++offered;
                CHECK(on.filters[i].worst.ratio >= r);
            }
        }
    }
    CHECK(offered >= 1);  // this setting exercises it
}

TEST_CASE("worst-case search searches on from another filter's worst signals where they beat a filter's own",
          "[eval][worst]") {
    const RunConfig cfg = load_run_config(ConfigDoc::from_file(hinf::test::source_path("runs/vanderpol.toml")));
    auto ekf = make_ekf(filter_model(cfg));
    auto ukf = make_ukf(filter_model(cfg));
    FixedGainFilter fixed(filter_model(cfg), {2.0, 1.0});
    const std::vector<const OnlineFilter*> filters = {ekf.get(), ukf.get(), &fixed};
    const int F = 3;
    WorstOptions opt = short_cross_search();  // here the fixed gain's worst set beats the EKF's and the UKF's own
    opt.cross_starts = false;
    opt.linear_pieces = 0;  // (a linear start finds each filter's own worst well enough to leave nothing to cross)
    const WorstResult off = worst_search(cfg, filters, {}, opt);
    opt.cross_starts = true;
    omp_set_num_threads(1);
    const WorstResult on1 = worst_search(cfg, filters, {}, opt);
    omp_set_num_threads(2);
    const WorstResult on = worst_search(cfg, filters, {}, opt);
    int cross_restarts = 0;
    for (int i = 0; i < F; ++i) {
        const auto& a = off.filters[i].restarts;
        const auto& b = on.filters[i].restarts;
        REQUIRE(b.size() >= a.size());
        // the first round is the search without cross starts, bit for bit
        for (std::size_t j = 0; j < a.size(); ++j) CHECK(b[j].ratio == a[j].ratio);
        for (const auto& rs : a) CHECK(rs.start.rfind("cross:", 0) == std::string::npos);
        double column = 0;  // the largest ratio any first-round worst set gives filter i
        for (int d = 0; d < F; ++d) column = std::max(column, off.cross.ratio[std::size_t(d) * F + i]);
        CHECK(on.filters[i].worst.ratio >= column);
        // the second round: one start per first-round set that beat this filter's own best, in set order; each
        // begins where that set left this filter, its cross-table entry (up to the rounding of scaling the set to
        // the budget once more). Later rounds start from the sets the second round found.
        std::size_t j = a.size();
        for (int d = 0; d < F; ++d) {
            if (d == i || !(off.cross.ratio[std::size_t(d) * F + i] > off.filters[i].worst.ratio)) continue;
            REQUIRE(j < b.size());
            CHECK(b[j].start == "cross:" + off.filters[d].name);
            CHECK(b[j].start_ratio == Approx(off.cross.ratio[std::size_t(d) * F + i]).epsilon(1e-9));
            ++j;
        }
        for (j = a.size(); j < b.size(); ++j) {
            ++cross_restarts;
            CHECK(b[j].start.rfind("cross:", 0) == 0);
            CHECK(b[j].start != "cross:" + off.filters[i].name);
            CHECK(b[j].ratio >= b[j].start_ratio);
        }
        CHECK(on.cross.ratio[std::size_t(i) * F + i] == on.filters[i].worst.ratio);  // the replay, bit for bit
        REQUIRE(on1.filters[i].restarts.size() == b.size());  // any thread count: the same restarts, the same bits
        for (std::size_t j = 0; j < b.size(); ++j) CHECK(on1.filters[i].restarts[j].ratio == b[j].ratio);
    }
    CHECK(cross_restarts >= 2);  // this setting exercises the cross starts (the EKF and the UKF)
}
