// The worst-case search (see worst.hpp): a parametrised v(t), n(t) scaled to the energy budget, the truth from
// sim/truth with those signals, the filter stepped through filter_stream, NLopt maximising the ratio per
// (filter, start). Not the CLI's table (cli/worst_cmd.cpp) nor the plots (scripts/plot).
#include "eval/worst.hpp"

#include <nlopt.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <omp.h>
#include <sstream>
#include <toml++/toml.h>

#include <Eigen/Dense>

#include "eval/engine.hpp"
#include "filters/gain_law.hpp"
#include "hinf/error.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"
#include "io/atomic.hpp"
#include "io/progress.hpp"
#include "io/run_lock.hpp"
#include "models/weighted_system.hpp"
#include "par/par.hpp"
#include "random.hpp"

namespace hinf {

namespace {

constexpr double kPi = 3.14159265358979323846;

struct NamedAlgorithm {
    const char* name;
    nlopt_algorithm algorithm;
};
// local, derivative-free and free of NLopt's process-wide random generator (so restarts can run in parallel
// and give the same result on any thread count)
const NamedAlgorithm kAlgorithms[] = {
    {"LN_SBPLX", NLOPT_LN_SBPLX},
    {"LN_BOBYQA", NLOPT_LN_BOBYQA},
    {"LN_NELDERMEAD", NLOPT_LN_NELDERMEAD},
    {"LN_NEWUOA_BOUND", NLOPT_LN_NEWUOA_BOUND},
};

nlopt_algorithm algorithm_named(const std::string& name, Spelling spelling = Spelling::program) {
    for (const NamedAlgorithm& a : kAlgorithms)
        if (name == a.name) return a.algorithm;
    HINF_FAIL(option_name("--algorithm", spelling) + " '" + name + "' is not one of: " + worst_algorithms());
}

// v'v + n'n summed over steps, times dt: the energy the truth reports (sim/truth.cpp, TruthRun::energy)
double signal_energy(const Signals& s, double dt) {
    double e = 0;
    for (double v : s.v) e += v * v;
    for (double v : s.n) e += v * v;
    return e * dt;
}

// Scales s to the budget; false (s untouched) when it carries no energy.
bool scale_to_budget(Signals& s, double energy, double dt) {
    const double e = signal_energy(s, dt);
    if (!(e > 0) || !std::isfinite(e)) return false;
    const double c = std::sqrt(energy / e);
    for (double& v : s.v) v *= c;
    for (double& v : s.n) v *= c;
    return true;
}

// The parametrisation of one start: w_c(t) = alpha base_c(t) + a_p sum_j theta_cj 1[piece j] +
// a_s sum_s (theta_cs sin(2 pi f_s t) + theta'_cs cos(2 pi f_s t)), then scaled to the budget.
// theta = [alpha (with a base)] [S log-frequencies in [0, 1]] [per channel: P pieces, S sin, S cos]; amplitudes in
// [-1, 1]: a piece of value 1 over the whole horizon, or a sinusoid of amplitude 1, carries the whole budget.
struct Parametrisation {
    int nv = 0, m = 0, P = 0, S = 0;
    std::int64_t K = 0;
    double dt = 0, energy = 0, amp_piece = 0, amp_sine = 0, logf_lo = 0, logf_hi = 0;
    const Signals* base = nullptr;  // energy-normalised, or nullptr
    const double* t = nullptr;      // [K] t_k (RunConfig::time_of)

    int channels() const { return nv + m; }
    int offset() const { return base != nullptr ? 1 : 0; }
    int dims() const { return offset() + S + channels() * (P + 2 * S); }
    double frequency(double u) const { return std::exp(logf_lo + u * (logf_hi - logf_lo)); }

    // s must be sized [K x nv], [K x m]; returns false when the signal has no energy
    bool signals(Signals& s, const double* theta) const {
        const int C = channels(), o = offset();
        std::vector<double> sn(S), cs(S);
        for (std::int64_t k = 0; k < K; ++k) {
            const double tk = t[k];
            for (int q = 0; q < S; ++q) {
                const double w = 2.0 * kPi * frequency(theta[o + q]) * tk;
                sn[q] = std::sin(w);
                cs[q] = std::cos(w);
            }
            const int piece = int(k * P / K);
            for (int c = 0; c < C; ++c) {
                const double* th = theta + o + S + c * (P + 2 * S);
                double w = P > 0 ? amp_piece * th[piece] : 0.0;
                for (int q = 0; q < S; ++q) w += amp_sine * (th[P + q] * sn[q] + th[P + S + q] * cs[q]);
                if (base != nullptr) w += theta[0] * (c < nv ? base->v[k * nv + c] : base->n[k * m + (c - nv)]);
                if (c < nv) s.v[k * nv + c] = w;
                else s.n[k * m + (c - nv)] = w;
            }
        }
        return scale_to_budget(s, energy, dt);
    }
};

// The filter (an already-cloned one, reset here) run under s: visit(k, e_k, energy_k) with e_k = x_k - x^_k [n] (an
// angle state's wrapped) and the step's v'v + n'n; false (nothing visited) where the truth runs away (escape:
// truth_escape_bound; docs/compare.md "A truth that escapes"). freeze: a filter that diverges is frozen as the engine
// freezes it (plausible_bound of this truth, docs/compare.md "Divergence"), so that a ratio is the one its replay
// gives: without it an EKF that ran away scored 3.0e26 in the search and 3.9e9 in the replay of the same signals (a
// compressor model, 2026-12-05). Not for the linear start's differences: their signals are a millionth of the budget,
// and a truth that barely moves (noise only, x0 = 0) puts that bound below any estimate.
template <class Visit>
bool run_errors(const RunConfig& cfg, OnlineFilter& f, const Signals& s, std::int64_t K, const std::vector<double>& t,
                const std::vector<double>& escape, bool freeze, Visit&& visit) {
    std::int64_t escaped_at = -1;
    TruthRun tr = truth_simulate_checked(cfg, Scenario{}, 0, K, escape.data(), &escaped_at, &s);
    const int n = cfg.n;
    if (escaped_at >= 0) return false;
    std::vector<double> e(n);
    const FilterStart start = engine_filter_start(cfg, 0);
    f.reset(start);
    const std::vector<double> bound = freeze ? plausible_bound(cfg, start, tr.x.data(), nullptr, K) : std::vector<double>{};
    filter_stream(f, tr.y.data(), cfg.m, t.data(), K, tr.x.data(), n, freeze ? bound.data() : nullptr, nullptr,
                  [&](std::int64_t k, const double* xh, bool) {
        cfg.system->state_difference(e.data(), tr.x.data() + k * n, xh);
        visit(k, e.data(), tr.energy[k]);
    });
    return true;
}

// The ratio of an already-cloned filter (reset here) under s: the sums of eval/engine.cpp run_one_filter, in its
// order, so that a replay through the engine gives the same bits. NaN where the truth runs away.
double ratio_of(const RunConfig& cfg, OnlineFilter& f, const Signals& s, std::int64_t K, const std::vector<double>& t,
                const std::vector<double>& escape) {
    double error_energy = 0, energy = 0;
    const bool stayed = run_errors(cfg, f, s, K, t, escape, true, [&](std::int64_t, const double* e, double ek) {
        error_energy += cfg.dt * quadratic_form(cfg.Q.data(), e, cfg.n);
        energy += cfg.dt * ek;
    });
    return stayed ? error_energy / energy : NAN;
}

std::vector<double> times(const RunConfig& cfg, std::int64_t K) {
    std::vector<double> t(K);
    for (std::int64_t k = 0; k < K; ++k) t[k] = cfg.time_of(k);
    return t;
}

// The game's worst case along the filter's own trajectory (seed 000 eqs. (6)-(7)): v*_k = B(x_k)'p_k / (2 rho),
// n*_k = -(C(x_k) - C(x^_k)), p_k = dV/dx~ at x_k - x^_k; iterated from the nominal draws (with x~0 = 0 and
// no signal, p = 0 and v* = 0), each pass scaled to the budget.
Signals game_signals(const RunConfig& cfg, const OnlineFilter& proto, const WorstGame& game, std::int64_t K,
                     double energy, const std::vector<double>& t) {
    const System& sys = *cfg.system;
    const int n = cfg.n, nv = cfg.nv, m = cfg.m;
    TruthRun nominal = truth_simulate(cfg, Scenario{}, 0, K);
    Signals s{nominal.v, nominal.n};
    scale_to_budget(s, energy, cfg.dt);
    std::unique_ptr<OnlineFilter> f = proto.clone();
    std::unique_ptr<FrozenNetwork> net = game.network->clone();
    std::vector<double> xt(n), p(n), B(std::size_t(n) * nv), cx(m), ch(m);
    for (int pass = 0; pass < 3; ++pass) {
        TruthRun tr = truth_simulate(cfg, Scenario{}, 0, K, &s);
        Signals g{std::vector<double>(K * nv), std::vector<double>(K * m)};
        f->reset(engine_filter_start(cfg, 0));
        filter_stream(*f, tr.y.data(), m, t.data(), K, tr.x.data(), n, nullptr, nullptr, [&](std::int64_t k, const double* xh, bool) {
            const double* x = tr.x.data() + k * n;
            sys.state_difference(xt.data(), x, xh);
            net->gradient(p.data(), xt.data(), 1);
            sys.disturbance_gain(B.data(), x, t[k], 1);
            sys.measurement(cx.data(), x, t[k], 1);
            sys.measurement(ch.data(), xh, t[k], 1);
            for (int j = 0; j < nv; ++j) {
                double bp = 0;
                for (int i = 0; i < n; ++i) bp += B[i * nv + j] * p[i];
                g.v[k * nv + j] = bp / (2.0 * game.rho);
            }
            sys.output_difference(cx.data(), cx.data(), ch.data());  // an angle output's wrapped
            for (int j = 0; j < m; ++j) g.n[k * m + j] = -cx[j];
        });
        bool finite = true;
        for (double v : g.v) finite = finite && std::isfinite(v);
        for (double v : g.n) finite = finite && std::isfinite(v);
        if (!finite || !scale_to_budget(g, energy, cfg.dt)) break;  // keep the last usable pass
        s = std::move(g);
    }
    return s;
}

// The small-signal worst case of one filter over piecewise-constant signals, P pieces a channel (docs/compare.md,
// "The linear start"). For signals small enough that the truth and the filter respond linearly, the error sequence
// is e = L s about the zero signal's, and the ratio |e|_Q^2 / |s|^2 is at most the largest eigenvalue of the error
// energy's Gram matrix G = dt D'(I (x) Q)D over the signals' M = diag(piece lengths dt), where column j of D is the
// error sequence's central difference along basis signal j (one piece of one channel). That eigenvalue is the gain;
// its eigenvector, scaled to the budget, is the signal that reaches it, the search's "linear" start. Each difference
// runs the filter twice at +-a_j, the amplitude that carries kLinearShare of the budget: small against the noise the
// filter was built for, large against the round-off of a float network. Columns run in parallel, each a pure
// function of its index, so the result does not depend on the thread count. gain NaN: a basis run escaped or gave a
// non-finite error, D would not fit in kLinearBytes, or the filter is not linear at that scale (the eigenvector's own
// central difference does not reach its eigenvalue within kLinearAgreement: a particle filter).
constexpr double kLinearShare = 1e-6;
constexpr double kLinearBytes = 512.0 * 1024.0 * 1024.0;  // D, and as much again for (I (x) Q) D
constexpr double kLinearAgreement = 0.01;  // the eigenvector's own difference within 1 % of its eigenvalue

struct LinearWorst {
    double gain = NAN;
    Signals s;       // [K x nv], [K x m], scaled to the budget (empty where gain is NaN)
    int pieces = 0;  // the pieces a channel it was found with
    bool converged = false;  // the last doubling moved it by less than kLinearConverged
};

LinearWorst linear_worst(const RunConfig& cfg, const OnlineFilter& proto, std::int64_t K, int pieces, double energy,
                         const std::vector<double>& t, const std::vector<double>& escape, bool quiet) {
    const int P = int(std::min<std::int64_t>(pieces, K));  // a short horizon: a piece a step
    const int n = cfg.n, nv = cfg.nv, m = cfg.m, C = nv + m, B = C * P;
    LinearWorst out;
    if (P <= 0 || double(K) * n * B * sizeof(double) > kLinearBytes) return out;
    auto first = [K, P](int p) { return std::int64_t(p) * K / P; };  // piece p: steps [first(p), first(p + 1))
    std::vector<double> D(std::size_t(K) * n * B, 0.0), M(B);
    std::vector<unsigned char> ok(B, 0);
    Progress progress("worst linear start " + proto.name(), 0, B, quiet);
    std::int64_t finished = 0;
#pragma omp parallel for schedule(dynamic, 1)
    for (int j = 0; j < B; ++j) {
        const int c = j / P, p = j % P;
        const std::int64_t k0 = first(p), k1 = first(p + 1);
        M[j] = double(k1 - k0) * cfg.dt;
        const double a = std::sqrt(kLinearShare * energy / M[j]);
        std::unique_ptr<OnlineFilter> f = proto.clone();
        double* col = D.data() + std::size_t(j) * K * n;
        bool good = k1 > k0;
        for (int sign = 1; good && sign >= -1; sign -= 2) {
            Signals s{std::vector<double>(std::size_t(K) * nv, 0.0), std::vector<double>(std::size_t(K) * m, 0.0)};
            for (std::int64_t k = k0; k < k1; ++k) (c < nv ? s.v[k * nv + c] : s.n[k * m + (c - nv)]) = sign * a;
            good = run_errors(cfg, *f, s, K, t, escape, false, [&](std::int64_t k, const double* e, double) {
                for (int i = 0; i < n; ++i) col[k * n + i] += sign * e[i] / (2 * a);
            });
        }
        for (std::size_t i = 0; good && i < std::size_t(K) * n; ++i) good = std::isfinite(col[i]);
        ok[j] = good;
#pragma omp critical
        progress.update(++finished, "basis signals |");
    }
    for (unsigned char g : ok)
        if (!g) return out;
    // G = dt D' (I (x) Q) D: each column [K x n] seen as n x K (column-major), Q symmetric
    const Eigen::Map<const Eigen::MatrixXd> Dm(D.data(), std::int64_t(K) * n, B);
    const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> Q(cfg.Q.data(), n, n);
    Eigen::MatrixXd QD(std::int64_t(K) * n, B);
    for (int j = 0; j < B; ++j)
        Eigen::Map<Eigen::MatrixXd>(QD.col(j).data(), n, K).noalias() =
            Q * Eigen::Map<const Eigen::MatrixXd>(D.data() + std::size_t(j) * K * n, n, K);
    Eigen::MatrixXd A = cfg.dt * (Dm.transpose() * QD);
    for (int i = 0; i < B; ++i)
        for (int j = 0; j < B; ++j) A(i, j) /= std::sqrt(M[i] * M[j]);
    A = 0.5 * (A + A.transpose());
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(A);
    if (es.info() != Eigen::Success) return out;
    Eigen::VectorXd u = es.eigenvectors().col(B - 1);
    Eigen::Index big = 0;
    u.cwiseAbs().maxCoeff(&big);
    if (u[big] < 0) u = -u;  // one sign whatever the solver's
    Signals s{std::vector<double>(std::size_t(K) * nv, 0.0), std::vector<double>(std::size_t(K) * m, 0.0)};
    for (int j = 0; j < B; ++j) {
        const int c = j / P, p = j % P;
        const double w = u[j] / std::sqrt(M[j]);
        for (std::int64_t k = first(p); k < first(p + 1); ++k) (c < nv ? s.v[k * nv + c] : s.n[k * m + (c - nv)]) = w;
    }
    if (!scale_to_budget(s, energy, cfg.dt)) return out;
    // the check that the filter is linear at that scale: the central difference along the eigenvector itself must
    // give its eigenvalue. A smooth filter gives it to the differences' rounding; one that is not differentiable
    // there (a particle filter's resampling) does not, and its figure would be the differences' noise
    const double lambda = std::max(0.0, es.eigenvalues()[B - 1]), c = std::sqrt(kLinearShare);
    Signals half{s.v, s.n};
    for (double& v : half.v) v *= c;
    for (double& v : half.n) v *= c;
    std::vector<double> diff(std::size_t(K) * n, 0.0);
    std::unique_ptr<OnlineFilter> f = proto.clone();
    for (int sign = 1; sign >= -1; sign -= 2) {
        if (sign < 0) {
            for (double& v : half.v) v = -v;
            for (double& v : half.n) v = -v;
        }
        if (!run_errors(cfg, *f, half, K, t, escape, false, [&](std::int64_t k, const double* e, double) {
                for (int i = 0; i < n; ++i) diff[k * n + i] += sign * e[i] / 2;
            }))
            return out;
    }
    double along = 0;
    for (std::int64_t k = 0; k < K; ++k) along += cfg.dt * quadratic_form(cfg.Q.data(), diff.data() + k * n, n);
    along /= kLinearShare * energy;
    if (!(std::fabs(along - lambda) <= kLinearAgreement * lambda)) return out;
    out.gain = lambda;
    out.s = std::move(s);
    out.pieces = P;
    return out;
}

// The pieces doubled from `pieces` until the figure moves by less than kLinearConverged (each level's pieces split
// the last's in two, so its maximum is over a larger family and can only grow, up to the differences' rounding), the
// pieces reach the horizon's steps, or the next level would simulate more than max_steps steps in all (the first
// level runs whatever it costs). 20 pieces over a 20 s horizon cannot hold a cart's pendulum swinging at 0.5 Hz: its
// DNN filter reached 0.38 with them and 5.8 / 6.3 with 100 / 400 (docs/compare.md "The linear start").
constexpr double kLinearConverged = 0.05;

LinearWorst linear_worst_refined(const RunConfig& cfg, const OnlineFilter& proto, std::int64_t K, int pieces,
                                 double max_steps, double energy, const std::vector<double>& t,
                                 const std::vector<double>& escape, bool quiet) {
    const double per_piece = 2.0 * (cfg.nv + cfg.m) * double(K);  // steps simulated per piece a channel
    LinearWorst best = linear_worst(cfg, proto, K, pieces, energy, t, escape, quiet);
    double spent = per_piece * best.pieces;
    while (std::isfinite(best.gain) && best.pieces < K && spent + per_piece * 2.0 * best.pieces <= max_steps) {
        LinearWorst finer = linear_worst(cfg, proto, K, 2 * best.pieces, energy, t, escape, quiet);
        spent += per_piece * 2.0 * best.pieces;
        if (!std::isfinite(finer.gain)) break;  // keep the figure that checked itself
        const bool moved = finer.gain > best.gain * (1 + kLinearConverged);
        best = std::move(finer);
        if (!moved) {
            best.converged = true;
            break;
        }
    }
    if (std::isfinite(best.gain) && best.pieces >= K) best.converged = true;  // a piece a step: every signal, exact
    return best;
}

struct Task {
    int filter = 0;
    std::string start;
    const Signals* base = nullptr;  // scenario or game start
    std::uint64_t random_index = 0;
};

struct TaskResult {
    WorstRestart restart;
    Signals best;
};

struct Objective {
    const RunConfig* cfg = nullptr;
    OnlineFilter* filter = nullptr;
    const Parametrisation* par = nullptr;
    const std::vector<double>* t = nullptr;
    Signals s;
    std::vector<double> escape;  // truth_escape_bound over the horizon
    double best = -1;
    Signals best_signals;
    int evals = 0;
};

// NLopt's callback: the ratio under theta (0 for a signal with no energy or a truth that runs away)
double objective(unsigned, const double* theta, double*, void* data) {
    Objective& o = *static_cast<Objective*>(data);
    ++o.evals;
    if (!o.par->signals(o.s, theta)) return 0.0;
    double r = ratio_of(*o.cfg, *o.filter, o.s, o.par->K, *o.t, o.escape);
    if (!std::isfinite(r)) return 0.0;
    if (r > o.best) {
        o.best = r;
        o.best_signals = o.s;
    }
    return r;
}

TaskResult run_task(const RunConfig& cfg, const OnlineFilter& proto, Parametrisation par, const Task& task,
                    const WorstOptions& opt, const std::vector<double>& t) {
    par.base = task.base;
    const int d = par.dims();
    std::vector<double> lo(d, -1.0), hi(d, 1.0), x(d, 0.0), step(d, 0.25);
    const int o = par.offset();
    for (int q = 0; q < par.S; ++q) {
        lo[o + q] = 0.0;
        x[o + q] = 0.5;
        step[o + q] = 0.15;
    }
    if (task.base != nullptr) x[0] = 1.0;
    else {
        // a random start: uniform over the box, the same draws for every filter
        std::vector<double> u(d);
        kern::rng_uniform(u.data(), d, cfg.online_seed, kern::RNG_STREAM_WORST, task.random_index, 0);
        for (int i = 0; i < d; ++i) x[i] = lo[i] + (hi[i] - lo[i]) * u[i];
    }
    std::unique_ptr<OnlineFilter> f = proto.clone();
    Objective obj;
    obj.cfg = &cfg;
    obj.filter = f.get();
    obj.par = &par;
    obj.t = &t;
    obj.escape = truth_escape_bound(cfg, par.K);
    obj.s = Signals{std::vector<double>(par.K * par.nv), std::vector<double>(par.K * par.m)};
    TaskResult res;
    res.restart.start = task.start;
    res.restart.start_ratio = objective(d, x.data(), nullptr, &obj);
    nlopt_opt nl = nlopt_create(algorithm_named(opt.algorithm), unsigned(d));
    HINF_CHECK(nl != nullptr, "worst: NLopt could not create " + opt.algorithm + " in " + std::to_string(d) + " dimensions");
    nlopt_set_lower_bounds(nl, lo.data());
    nlopt_set_upper_bounds(nl, hi.data());
    nlopt_set_max_objective(nl, objective, &obj);
    nlopt_set_maxeval(nl, std::max(1, opt.evals - 1));
    nlopt_set_initial_step(nl, step.data());
    double fval = 0;
    nlopt_result rc = nlopt_optimize(nl, x.data(), &fval);
    nlopt_destroy(nl);
    res.restart.ratio = std::max(obj.best, 0.0);
    res.restart.evals = obj.evals;
    res.restart.nlopt_result = nlopt_result_to_string(rc);
    res.best = obj.best >= 0 ? std::move(obj.best_signals) : obj.s;
    return res;
}

// Every task (one restart of one filter's search), OpenMP over the tasks; under mpirun the tasks are dealt out
// over the processes (worst_rank_of: every filter's restarts spread over all of them, so a slow filter's restarts
// do not pile up on one) and every process ends with all results in task order. Each task is a pure function of
// its inputs, so who computes it does not change a bit of it.
std::vector<TaskResult> run_tasks(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                                  const Parametrisation& par, const std::vector<Task>& tasks, const WorstOptions& opt,
                                  const std::vector<double>& t, const char* label) {
    const std::int64_t N = std::int64_t(tasks.size());
    const int rank = par_rank(), ranks = par_size();
    std::vector<std::int64_t> mine;
    for (std::int64_t j = 0; j < N; ++j)
        if (worst_rank_of(j, ranks) == rank) mine.push_back(j);
    const std::int64_t L = std::int64_t(mine.size());
    std::vector<TaskResult> done(N);
    Progress progress(label, 0, L, opt.quiet);
    std::int64_t finished = 0;
#pragma omp parallel for schedule(dynamic, 1)
    for (std::int64_t i = 0; i < L; ++i) {
        const std::int64_t j = mine[i];
        done[j] = run_task(cfg, *filters[tasks[j].filter], par, tasks[j], opt, t);
        char detail[200];
        std::snprintf(detail, sizeof detail, "restarts%s | %s %s: ratio %.4g (start %.4g) |",
                      ranks > 1 ? " of rank 0" : "", filters[tasks[j].filter]->name().c_str(), tasks[j].start.c_str(),
                      done[j].restart.ratio, done[j].restart.start_ratio);
#pragma omp critical
        progress.update(++finished, detail);
    }
    if (ranks > 1) {
        // every process's restarts to every process, placed in task order
        ParBytesOut w;
        for (std::int64_t j : mine) {
            const TaskResult& d = done[j];
            w.put(d.restart.start);
            w.put(d.restart.nlopt_result);
            w.put(d.restart.start_ratio);
            w.put(d.restart.ratio);
            w.put(std::uint64_t(d.restart.evals));
            w.put(d.best.v);
            w.put(d.best.n);
        }
        const std::vector<std::vector<char>> all = par_allgather(w.bytes);
        for (int q = 0; q < ranks; ++q) {
            ParBytesIn rd(all[q]);
            for (std::int64_t j = 0; j < N; ++j) {
                if (worst_rank_of(j, ranks) != q) continue;
                TaskResult& d = done[j];
                d.restart.start = rd.get_string();
                d.restart.nlopt_result = rd.get_string();
                d.restart.start_ratio = rd.get_double();
                d.restart.ratio = rd.get_double();
                d.restart.evals = int(rd.get_u64());
                d.best.v = rd.get_vector();
                d.best.n = rd.get_vector();
            }
            HINF_CHECK(rd.at_end(), "worst: a process sent more than its restarts (bug)");
        }
    }

    return done;
}

}  // namespace

std::string worst_algorithms() {
    std::string all;
    for (const NamedAlgorithm& a : kAlgorithms) all += std::string(all.empty() ? "" : ", ") + a.name;
    return all;
}

RunConfig worst_config(const RunConfig& cfg, const WorstOptions& opt) {
    RunConfig c = cfg;
    if (opt.keep_initial_error) return c;
    // The same filters as compare's, started at the truth: the energy gain from x~0 = 0, what the H-infinity norm
    // measures, of the filters a user runs. EKF/UKF/PF keep the initial covariance compare tells them (it is their
    // tuning, as the trained gain is the DNN filter's), not one for the moved start.
    if (c.initial_std.empty()) {  // |d| squared is d^2 bit for bit: baseline_initial_covariance's P0
        c.initial_std.resize(c.n);
        for (int i = 0; i < c.n; ++i) c.initial_std[i] = std::fabs(c.x0[i] - c.xhat0[i]);
    }
    c.xhat0 = c.x0;
    return c;
}

double worst_energy(const RunConfig& cfg, const WorstOptions& opt, std::int64_t steps) {
    const std::string energy = option_name("--energy", opt.spelling);
    if (opt.energy != -1)
        HINF_CHECK(std::isfinite(opt.energy) && opt.energy > 0,
                   energy + " must be a finite number > 0 (got " + std::to_string(opt.energy) + ")");
    const double T = cfg.time_of(steps);
    const double e = opt.energy > 0 ? opt.energy
                                    : (cfg.disturbance_std * cfg.disturbance_std * cfg.nv +
                                       cfg.noise_std * cfg.noise_std * cfg.m) * T;
    HINF_CHECK(std::isfinite(e) && e > 0, "worst: the energy budget is " + std::to_string(e) +
                                              " ([online] disturbance_std and noise_std are 0?): pass " + energy + " E > 0");
    return e;
}

double worst_ratio(const RunConfig& cfg, const OnlineFilter& f, const Signals& s, std::int64_t steps) {
    std::unique_ptr<OnlineFilter> c = f.clone();
    return ratio_of(cfg, *c, s, steps, times(cfg, steps), truth_escape_bound(cfg, steps));
}

double worst_small_signal(const RunConfig& cfg_in, const OnlineFilter& f, const WorstOptions& opt) {
    const RunConfig cfg = worst_config(cfg_in, opt);
    const std::int64_t K = cfg.steps_until(opt.until);
    if (opt.linear_pieces <= 0 || K < 2) return NAN;
    return linear_worst_refined(cfg, f, K, opt.linear_pieces, opt.linear_steps, worst_energy(cfg, opt, K), times(cfg, K),
                                truth_escape_bound(cfg, K), opt.quiet)
        .gain;
}

WorstNetworks worst_networks(const std::vector<const OnlineFilter*>& filters, const std::vector<std::string>& paths) {
    WorstNetworks w;
    for (const std::string& path : paths) {
        RunConfig ncfg;
        w.nets.push_back(ckpt_frozen_network(path, &ncfg));
        w.prefixes.push_back("dnn_" + ncfg.variant + "_");
        w.rhos.push_back(ncfg.rho);
    }
    w.games.resize(filters.size());
    for (std::size_t i = 0; i < filters.size(); ++i)
        for (std::size_t j = 0; j < w.nets.size(); ++j)
            if (filters[i]->name().rfind(w.prefixes[j], 0) == 0 && !w.nets[j]->step_config().gain.enabled)
                w.games[i] = WorstGame{w.nets[j].get(), w.rhos[j]};
    return w;
}

WorstResult worst_search(const RunConfig& cfg_in, const std::vector<const OnlineFilter*>& filters,
                         const std::vector<WorstGame>& games, const WorstOptions& opt) {
    const auto wall0 = std::chrono::steady_clock::now();
    const auto o = [&](const char* flag) { return option_name(flag, opt.spelling); };
    HINF_CHECK(!filters.empty(), "worst: no filters to search (name at least one with " + o("--filters") + ")");
    HINF_CHECK(games.empty() || games.size() == filters.size(), "worst: one game per filter (or none)");
    HINF_CHECK(opt.pieces >= 0 && opt.sines >= 0 && opt.pieces + opt.sines >= 1,
               o("--pieces") + " and " + o("--sines") + " must be >= 0, and not both 0 (got " +
                   std::to_string(opt.pieces) + ", " + std::to_string(opt.sines) + ")");
    HINF_CHECK(opt.pieces <= 1000 && opt.sines <= 100, o("--pieces") + " <= 1000 and " + o("--sines") + " <= 100");
    HINF_CHECK(opt.evals >= 1, o("--evals") + " must be >= 1 (got " + std::to_string(opt.evals) + ")");
    HINF_CHECK(opt.random_starts >= 0, o("--random-starts") + " must be >= 0");
    HINF_CHECK(opt.linear_pieces >= 0 && opt.linear_pieces <= 1000,
               o("--linear-pieces") + " must be in [0, 1000] (0: no linear start; got " +
                   std::to_string(opt.linear_pieces) + ")");
    algorithm_named(opt.algorithm, opt.spelling);
    const RunConfig cfg = worst_config(cfg_in, opt);
    const std::int64_t K = cfg.steps_until(opt.until);
    HINF_CHECK(K >= 2, "worst: the horizon is shorter than two time steps (dt = " + std::to_string(cfg.dt) +
                           " s): pass a later " + o("--until"));
    HINF_CHECK(opt.pieces <= K, o("--pieces") + " " + std::to_string(opt.pieces) + " is more than the " + std::to_string(K) +
                                    " steps of the horizon");
    const double E = worst_energy(cfg, opt, K);
    const std::vector<double> t = times(cfg, K);
    const int F = int(filters.size());

    Parametrisation par;
    par.nv = cfg.nv;
    par.m = cfg.m;
    par.P = opt.pieces;
    par.S = opt.sines;
    par.K = K;
    par.dt = cfg.dt;
    par.t = t.data();
    par.energy = E;
    const double T = cfg.time_of(K);
    par.amp_piece = std::sqrt(E / T);        // a constant of this amplitude over [0, T) carries the budget
    par.amp_sine = std::sqrt(2.0 * E / T);   // ... and a sinusoid of this amplitude
    par.logf_lo = std::log(1.0 / T);          // one period over the horizon
    par.logf_hi = std::log(0.25 / cfg.dt);    // half the Nyquist frequency of the sampled filters

    // the starts: the compare scenarios' signals (run 0) and, per DNN filter, the game's worst case
    std::vector<Signals> scenario_base;
    for (const std::string& name : opt.scenario_starts) {
        TruthRun tr = truth_simulate(cfg, scenario_named(name), 0, K);
        Signals s{tr.v, tr.n};
        HINF_CHECK(scale_to_budget(s, E, cfg.dt), "worst: scenario start '" + name + "' carries no energy");
        scenario_base.push_back(std::move(s));
    }
    std::vector<Signals> game_base(F), linear_base(F);
    std::vector<double> linear_gain(F, NAN);
    std::vector<int> linear_pieces(F, 0);
    std::vector<char> linear_converged(F, 0);
    std::vector<Task> tasks;
    const std::vector<double> escape = opt.linear_pieces > 0 ? truth_escape_bound(cfg, K) : std::vector<double>{};
    for (int i = 0; i < F; ++i) {
        for (int j = 0; j < opt.random_starts; ++j)
            tasks.push_back(Task{i, "random:" + std::to_string(j), nullptr, std::uint64_t(j)});
        for (std::size_t j = 0; j < scenario_base.size(); ++j)
            tasks.push_back(Task{i, "scenario:" + opt.scenario_starts[j], &scenario_base[j], 0});
        if (opt.game_start && !games.empty() && games[i].network != nullptr) {
            game_base[i] = game_signals(cfg, *filters[i], games[i], K, E, t);
            tasks.push_back(Task{i, "game", &game_base[i], 0});
        }
        if (opt.linear_pieces > 0) {  // every process computes it: the same bits, no exchange
            LinearWorst lw = linear_worst_refined(cfg, *filters[i], K, opt.linear_pieces, opt.linear_steps, E, t, escape,
                                                  opt.quiet || par_rank() != 0);
            linear_gain[i] = lw.gain;
            linear_pieces[i] = lw.pieces;
            linear_converged[i] = lw.converged;
            if (std::isfinite(lw.gain)) {
                linear_base[i] = std::move(lw.s);
                tasks.push_back(Task{i, "linear", &linear_base[i], 0});
            }
        }
    }
    HINF_CHECK(!tasks.empty(), "worst: no starts (" + o("--random-starts") + " 0 and no " + o("--scenario-starts") + ")");
    for (int i = 0; i < F; ++i) {  // a filter whose only start was its linear one, which found no linear regime
        bool started = false;
        for (const Task& task : tasks) started = started || task.filter == i;
        HINF_CHECK(started, "worst: no start for " + filters[i]->name() + ": its linear start found no linear regime (" +
                                "a small signal's run ran away, or it does not respond linearly) and there are no "
                                "other starts; add " + o("--random-starts") + " or " + o("--scenario-starts"));
    }
    const std::int64_t N = std::int64_t(tasks.size());
    const int ranks = par_size();
    HINF_CHECK(ranks <= N, std::to_string(ranks) + " MPI processes for " + std::to_string(N) +
                               " restart(s): start at most as many processes as restarts (mpirun -np), or add "
                               "restarts (" + o("--random-starts") + ")");

    WorstResult res;
    res.energy = E;
    res.steps = K;
    res.parameters = par.dims();
    res.filters.resize(F);
    for (int i = 0; i < F; ++i) {
        res.filters[i].name = filters[i]->name();
        res.filters[i].linear_gain = linear_gain[i];
        res.filters[i].linear_pieces = linear_pieces[i];
        res.filters[i].linear_converged = linear_converged[i] != 0;
    }
    // restarts in task order into each filter's list; its worst set is its largest ratio (the first on a tie), and
    // `searched` its largest apart from the linear start (kept where the linear start gave the worst set: below)
    std::vector<WorstSignals> searched(F);
    std::vector<char> has_searched(F, 0);
    auto merge = [&res, &searched, &has_searched](const std::vector<Task>& ts, std::vector<TaskResult>& done) {
        for (std::size_t j = 0; j < ts.size(); ++j) {
            WorstFilterResult& fr = res.filters[ts[j].filter];
            const int f = ts[j].filter;
            if (ts[j].start != "linear" && (!has_searched[f] || done[j].restart.ratio > searched[f].ratio)) {
                searched[f] = WorstSignals{fr.name, done[j].restart.ratio, done[j].best};
                has_searched[f] = 1;
            }
            fr.restarts.push_back(done[j].restart);
            const int r = int(fr.restarts.size()) - 1;
            if (r == 0 || done[j].restart.ratio > fr.restarts[fr.best].ratio) {
                fr.best = r;
                fr.worst = WorstSignals{fr.name, done[j].restart.ratio, std::move(done[j].best)};
            }
        }
    };
    auto worst_sets = [&res] {
        std::vector<WorstSignals> sets;
        for (const auto& fr : res.filters) sets.push_back(fr.worst);
        return sets;
    };
    std::vector<TaskResult> done = run_tasks(cfg, filters, par, tasks, opt, t, "worst");
    merge(tasks, done);
    std::vector<WorstSignals> sets = worst_sets();
    res.cross = worst_replay(cfg, filters, sets, K, opt.quiet);

    // Cross starts: a local search finds a lower bound, and another filter's worst signals can beat a filter's own
    // best (on Van der Pol the UKF's gave a DNN filter 1.62 where its own seven restarts found 1.20). Each such set
    // becomes one more start for that filter, searched on from there, and the table is replayed with the new worst
    // sets; again while a set beats a filter's best, at most kCrossRounds rounds. When the rounds end on their own,
    // every filter's worst ratio is the largest entry of its column. Tasks in (filter, set) order; the table is the
    // same on every process.
    // A filter whose worst set came from its linear start also offers its best searched set ("cross:<name>:searched"):
    // the linear start raises a filter's worst set to its small-signal direction, which may serve another filter
    // less than the set its search found (Van der Pol, 40 knots at rho = 2: the UKF's searched set gave the DNN filter
    // 1.583, its linear set 1.283), and a start added to the search must not lower what the others find.
    constexpr int kCrossRounds = 3;
    for (int round = 0; opt.cross_starts && round < kCrossRounds; ++round) {
        std::vector<WorstSignals> alt;
        std::vector<int> alt_of;
        for (int d = 0; d < F; ++d) {
            const WorstFilterResult& fr = res.filters[d];
            if (fr.restarts[fr.best].start == "linear" && has_searched[d]) {
                alt.push_back(searched[d]);
                alt_of.push_back(d);
            }
        }
        const WorstReplay alt_cross = alt.empty() ? WorstReplay{} : worst_replay(cfg, filters, alt, K, true);
        std::vector<Task> more;
        for (int i = 0; i < F; ++i) {
            for (int d = 0; d < F; ++d)
                if (d != i && res.cross.ratio[std::size_t(d) * F + i] > res.filters[i].worst.ratio)
                    more.push_back(Task{i, "cross:" + sets[d].source, &sets[d].signals, 0});
            for (std::size_t a = 0; a < alt.size(); ++a)
                if (alt_of[a] != i && alt_cross.ratio[a * F + i] > res.filters[i].worst.ratio)
                    more.push_back(Task{i, "cross:" + alt[a].source + ":searched", &alt[a].signals, 0});
        }
        if (more.empty()) break;
        std::vector<TaskResult> again = run_tasks(cfg, filters, par, more, opt, t, "worst cross starts");
        merge(more, again);
        sets = worst_sets();
        res.cross = worst_replay(cfg, filters, sets, K, opt.quiet);
    }
    res.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    return res;
}

WorstReplay worst_replay(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                         const std::vector<WorstSignals>& sets, std::int64_t steps, bool quiet) {
    WorstReplay r;
    const int F = int(filters.size()), D = int(sets.size());
    for (const auto& s : sets) r.sets.push_back(s.source);
    for (const OnlineFilter* f : filters) r.filters.push_back(f->name());
    r.ratio.assign(std::size_t(D) * F, 0.0);
    r.diverged_at.assign(std::size_t(D) * F, -1.0);
    r.signal_energy.assign(D, 0.0);
    r.stride = std::max<std::int64_t>(1, steps / 2000);
    r.err.resize(std::size_t(D) * F);
    r.note.assign(std::size_t(D) * F, "");
    // under mpirun the sets are dealt out over the processes (set d to worst_rank_of(d)); a process may have none
    const int rank = par_rank(), ranks = par_size();
    for (int d = 0; d < D; ++d) {
        if (worst_rank_of(d, ranks) != rank) continue;
        // one run per set, each with run 0's initial estimate and draws (the PF's): the search's own conditions
        std::vector<Signals> one{sets[d].signals};
        EngineOptions eo;
        eo.runs = 1;
        eo.steps = steps;
        eo.stride = r.stride;
        eo.signals = &one;
        eo.label = "replay " + sets[d].source;
        eo.quiet = quiet;
        eo.split = false;
        EngineResult er = engine_run(cfg, filters, eo);
        const bool escaped = er.truth_escaped_at[0] >= 0;  // a set found before the search looked for escapes
        for (int f = 0; f < F; ++f) {
            FilterRunStats& st = er.runs[f][0];
            r.ratio[d * F + f] = escaped ? NAN : st.error_energy / st.signal_energy;
            r.diverged_at[d * F + f] = escaped ? NAN : st.diverged_at;
            r.signal_energy[d] = st.signal_energy;
            r.err[d * F + f] = std::move(st.err_sub);
            r.note[d * F + f] = st.note;
        }
    }
    if (ranks > 1) {
        ParBytesOut w;
        for (int d = 0; d < D; ++d) {
            if (worst_rank_of(d, ranks) != rank) continue;
            w.put(r.signal_energy[d]);
            for (int f = 0; f < F; ++f) {
                w.put(r.ratio[d * F + f]);
                w.put(r.diverged_at[d * F + f]);
                w.put(r.err[d * F + f]);
                w.put(r.note[d * F + f]);
            }
        }
        const std::vector<std::vector<char>> all = par_allgather(w.bytes);
        for (int q = 0; q < ranks; ++q) {
            ParBytesIn rd(all[q]);
            for (int d = 0; d < D; ++d) {
                if (worst_rank_of(d, ranks) != q) continue;
                r.signal_energy[d] = rd.get_double();
                for (int f = 0; f < F; ++f) {
                    r.ratio[d * F + f] = rd.get_double();
                    r.diverged_at[d * F + f] = rd.get_double();
                    r.err[d * F + f] = rd.get_vector();
                    r.note[d * F + f] = rd.get_string();
                }
            }
            HINF_CHECK(rd.at_end(), "worst: a process sent more than its replays (bug)");
        }
    }
    return r;
}

std::int64_t worst_rank_of(std::int64_t task, int ranks) { return task % ranks; }

namespace {

std::string join(const std::vector<std::string>& v) {
    std::string s;
    for (const auto& x : v) s += (s.empty() ? "" : ",") + x;
    return s;
}

// The [system] table as TOML text: two expression systems share name() and may share state names
std::string system_table(const RunConfig& cfg) {
    const toml::node* n = cfg.doc.root().get("system");
    std::ostringstream ss;
    if (n != nullptr && n->is_table()) ss << *n->as_table();
    return ss.str();
}

void write_identity(hid_t root, const RunConfig& cfg, std::int64_t steps) {
    h5::set_text(root, "system_table", system_table(cfg));  // a dataset when too long for an attribute
    h5::set_attr(root, "system", cfg.system->name());
    h5::set_attr(root, "state_names", join(cfg.system->state_names()));
    h5::set_attr(root, "n", std::int64_t(cfg.n));
    h5::set_attr(root, "nv", std::int64_t(cfg.nv));
    h5::set_attr(root, "m", std::int64_t(cfg.m));
    h5::set_attr(root, "dt", cfg.dt);
    h5::set_attr(root, "system_time", std::string(system_time_name(*cfg.system)));
    h5::set_attr(root, "steps", steps);
    h5::write_string(root, "config", cfg.doc.text(), "the effective TOML config");
}

void write_sets_and_cross(hid_t root, const RunConfig& cfg, const std::vector<WorstSignals>& sets,
                          const WorstReplay& r, std::int64_t steps) {
    const hsize_t K = hsize_t(steps);
    h5::Handle sg = h5::create_group(root, "sets");
    for (std::size_t d = 0; d < sets.size(); ++d) {
        h5::Handle g = h5::create_group(sg.get(), std::to_string(d));
        h5::set_attr(g.get(), "source", sets[d].source);
        h5::set_attr(g.get(), "ratio", sets[d].ratio);
        // with [online] std lists, in the model's units (models/weighted_system.hpp): kept so, so that a replay
        // reads back the very signals
        h5::write_doubles(g.get(), "v", sets[d].signals.v.data(), {K, hsize_t(cfg.nv)},
                          cfg.disturbance_scale.empty() ? "input units" : "input units / disturbance_scale",
                          "disturbance v_k at t_k");
        h5::write_doubles(g.get(), "n", sets[d].signals.n.data(), {K, hsize_t(cfg.m)},
                          cfg.output_weight.empty() ? "output units" : "output units x output_weight",
                          "measurement noise n_k at t_k");
        // diagonal (std lists): the diagonal [m] / [nv]; correlated (noise_cov, disturbance_cov): the matrix
        const std::vector<double> w = diagonal_of(cfg.output_weight, cfg.m), u = diagonal_of(cfg.disturbance_scale, cfg.nv);
        if (!w.empty())
            h5::write_doubles(g.get(), "output_weight", w.data(), {hsize_t(cfg.m)},
                              "1", "n_j here = output_weight_j x the noise in output j's units ([online] noise_std list)");
        else if (!cfg.output_weight.empty())
            h5::write_doubles(g.get(), "output_weight", cfg.output_weight.data(), {hsize_t(cfg.m), hsize_t(cfg.m)},
                              "1", "n here = output_weight x the noise in the outputs' units, output_weight = L^-1 "
                                   "with noise_cov = L L' ([online] noise_cov)");
        if (!u.empty())
            h5::write_doubles(g.get(), "disturbance_scale", u.data(),
                              {hsize_t(cfg.nv)}, "1",
                              "v_k here = the disturbance in input k's units / disturbance_scale_k ([online] "
                              "disturbance_std list)");
        else if (!cfg.disturbance_scale.empty())
            h5::write_doubles(g.get(), "disturbance_scale", cfg.disturbance_scale.data(),
                              {hsize_t(cfg.nv), hsize_t(cfg.nv)}, "1",
                              "v here = disturbance_scale^-1 x the disturbance in the inputs' units, disturbance_scale "
                              "= L with disturbance_cov = L L' ([online] disturbance_cov)");
    }
    const hsize_t D = hsize_t(r.sets.size()), F = hsize_t(r.filters.size());
    h5::Handle cg = h5::create_group(root, "cross");
    h5::set_attr(cg.get(), "sets", join(r.sets));
    h5::set_attr(cg.get(), "filters", join(r.filters));
    h5::set_attr(cg.get(), "meaning", "ratio[d][f]: filter f's attenuation ratio under set d (the worst found for "
                                      "sets[d]); err_<d>_<f>: its error x - x^ at t_sub");
    h5::write_doubles(cg.get(), "ratio", r.ratio.data(), {D, F}, "", "int x~'Qx~ dt / int (v'v + n'n) dt");
    h5::write_doubles(cg.get(), "diverged_at", r.diverged_at.data(), {D, F}, "s", "-1: never; NaN: the truth ran away");
    h5::write_doubles(cg.get(), "signal_energy", r.signal_energy.data(), {D}, "", "int (v'v + n'n) dt per set");
    std::vector<double> tsub;
    for (std::int64_t k = 0; k < steps; k += r.stride) tsub.push_back(cfg.time_of(k));
    h5::write_doubles(cg.get(), "t_sub", tsub.data(), {hsize_t(tsub.size())}, "s", "times of err_*");
    for (hsize_t d = 0; d < D; ++d)
        for (hsize_t f = 0; f < F; ++f) {
            const auto& e = r.err[d * F + f];
            h5::write_doubles(cg.get(), "err_" + std::to_string(d) + "_" + std::to_string(f), e.data(),
                              {hsize_t(e.size()) / hsize_t(cfg.n), hsize_t(cfg.n)}, "state units", "x - x^");
        }
}

}  // namespace

void worst_write(const std::string& path, const RunConfig& cfg, const WorstOptions& opt, const WorstResult& r) {
    AtomicH5 file(path);
    const hid_t root = file.get();
    h5::set_attr(root, "format", "hinf-worst");
    write_identity(root, cfg, r.steps);
    h5::set_attr(root, "energy", r.energy);
    h5::set_attr(root, "keep_initial_error", std::int64_t(opt.keep_initial_error ? 1 : 0));
    h5::set_attr(root, "algorithm", opt.algorithm);
    h5::set_attr(root, "pieces", std::int64_t(opt.pieces));
    h5::set_attr(root, "sines", std::int64_t(opt.sines));
    h5::set_attr(root, "linear_pieces", std::int64_t(opt.linear_pieces));
    h5::set_attr(root, "evals", std::int64_t(opt.evals));
    h5::set_attr(root, "parameters", std::int64_t(r.parameters));
    h5::set_attr(root, "wall_seconds", r.wall_seconds);
    h5::set_attr(root, "meaning", "worst-case search: per filter the restarts' ratios and its worst signals (sets/), "
                                  "every worst set replayed against every filter (cross/)");
    h5::Handle fg = h5::create_group(root, "filters");
    for (const auto& fr : r.filters) {
        h5::Handle g = h5::create_group(fg.get(), fr.name);
        std::vector<double> ratio, start_ratio;
        std::vector<std::int64_t> evals;
        std::vector<std::string> starts, results;
        for (const auto& rs : fr.restarts) {
            ratio.push_back(rs.ratio);
            start_ratio.push_back(rs.start_ratio);
            evals.push_back(rs.evals);
            starts.push_back(rs.start);
            results.push_back(rs.nlopt_result);
        }
        const hsize_t R = hsize_t(ratio.size());
        h5::write_doubles(g.get(), "restart_ratio", ratio.data(), {R}, "", "best ratio per restart");
        h5::write_doubles(g.get(), "restart_start_ratio", start_ratio.data(), {R}, "", "ratio at each start point");
        h5::write_int64s(g.get(), "restart_evals", evals.data(), {R}, "objective evaluations per restart");
        h5::set_attr(g.get(), "starts", join(starts));
        h5::set_attr(g.get(), "nlopt_results", join(results));
        h5::set_attr(g.get(), "best", std::int64_t(fr.best));
        h5::set_attr(g.get(), "ratio", fr.worst.ratio);
        h5::set_attr(g.get(), "linear_gain", fr.linear_gain);
        h5::set_attr(g.get(), "linear_pieces", std::int64_t(fr.linear_pieces));
        h5::set_attr(g.get(), "linear_converged", std::int64_t(fr.linear_converged ? 1 : 0));
    }
    std::vector<WorstSignals> sets;
    for (const auto& fr : r.filters) sets.push_back(fr.worst);
    write_sets_and_cross(root, cfg, sets, r.cross, r.steps);
    file.commit();
}

void worst_write_replay(const std::string& path, const RunConfig& cfg, const std::string& source,
                        const std::vector<WorstSignals>& sets, const WorstReplay& r, std::int64_t steps,
                        bool keep_initial_error) {
    AtomicH5 file(path);
    const hid_t root = file.get();
    h5::set_attr(root, "format", "hinf-worst-replay");
    write_identity(root, cfg, steps);
    h5::set_attr(root, "replayed", source);
    h5::set_attr(root, "keep_initial_error", std::int64_t(keep_initial_error ? 1 : 0));
    write_sets_and_cross(root, cfg, sets, r, steps);
    file.commit();
}

WorstReplayRun worst_replay_file(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                                 const std::string& source, const std::string& out_dir, const WorstOptions& opt,
                                 const std::string& who) {
    WorstReplayRun run;
    run.sets = worst_read(source, cfg, &run.steps, &run.keep_initial_error, opt.spelling);
    WorstOptions ro = opt;
    ro.keep_initial_error = run.keep_initial_error;
    const RunConfig rc = worst_config(cfg, ro);
    run.table = worst_replay(rc, filters, run.sets, run.steps, opt.quiet);
    const RunDirLock lock(out_dir, who);
    run.file = out_dir + "/replay.h5";
    worst_write_replay(run.file, rc, source, run.sets, run.table, run.steps, run.keep_initial_error);
    return run;
}

std::vector<WorstSignals> worst_read(const std::string& path, const RunConfig& cfg, std::int64_t* steps_out,
                                     bool* keep_initial_error_out, Spelling spelling) {
    check_input_file(path, "worst-case signals");
    h5::Handle file = h5::open_file(path, false);
    const hid_t root = file.get();
    const std::string where = (spelling == Spelling::program ? "--replay " : "worst_file ") + path + ": ";
    HINF_CHECK(h5::has_attr(root, "format") && (h5::get_attr_string(root, "format") == "hinf-worst" ||
                                                h5::get_attr_string(root, "format") == "hinf-worst-replay"),
               where + "not a file written by `hinf worst` (no format = hinf-worst)");
    const std::string sys = h5::get_attr_string(root, "system"), names = h5::get_attr_string(root, "state_names");
    HINF_CHECK(sys == cfg.system->name() && names == join(cfg.system->state_names()),
               where + "its signals are for system '" + sys + "' (states " + names + "), the config's is '" +
                   cfg.system->name() + "' (states " + join(cfg.system->state_names()) + ")");
    HINF_CHECK(h5::get_text(root, "system_table") == system_table(cfg),
               where + "its signals are for another [system] table (" + sys + " with other keys or parameters) than "
                       "the config's");
    const std::int64_t nv = h5::get_attr_int(root, "nv"), m = h5::get_attr_int(root, "m");
    HINF_CHECK(nv == cfg.nv && m == cfg.m, where + "its signals have " + std::to_string(nv) + " disturbance and " +
                                               std::to_string(m) + " noise channels, the config's system " +
                                               std::to_string(cfg.nv) + " and " + std::to_string(cfg.m));
    const double dt = h5::get_attr_double(root, "dt");
    HINF_CHECK(dt == cfg.dt, where + "its signals are sampled at dt = " + std::to_string(dt) + " s, the config has " +
                                 std::to_string(cfg.dt) + " s");
    const std::int64_t K = h5::get_attr_int(root, "steps");
    HINF_CHECK(K >= 1 && K <= cfg.steps_until(), where + "its signals last " + std::to_string(K) +
                                                     " steps, longer than the config's horizon (" +
                                                     std::to_string(cfg.steps_until()) + " steps)");
    *steps_out = K;
    *keep_initial_error_out = h5::get_attr_int(root, "keep_initial_error") != 0;
    std::vector<WorstSignals> sets;
    h5::Handle sg = h5::open_group(root, "sets");
    for (int d = 0; h5::exists(sg.get(), std::to_string(d)); ++d) {
        h5::Handle g = h5::open_group(sg.get(), std::to_string(d));
        WorstSignals s;
        s.source = h5::get_attr_string(g.get(), "source");
        s.ratio = h5::get_attr_double(g.get(), "ratio");
        std::vector<hsize_t> dv, dn;
        s.signals.v = h5::read_doubles(g.get(), "v", &dv);
        s.signals.n = h5::read_doubles(g.get(), "n", &dn);
        HINF_CHECK(dv.size() == 2 && dn.size() == 2 && std::int64_t(dv[0]) == K && std::int64_t(dn[0]) == K &&
                       std::int64_t(dv[1]) == nv && std::int64_t(dn[1]) == m,
                   where + "set " + std::to_string(d) + " has the wrong shape (damaged file?)");
        for (double x : s.signals.v) HINF_CHECK(std::isfinite(x), where + "set " + std::to_string(d) + " holds a non-finite v");
        for (double x : s.signals.n) HINF_CHECK(std::isfinite(x), where + "set " + std::to_string(d) + " holds a non-finite n");
        sets.push_back(std::move(s));
    }
    HINF_CHECK(!sets.empty(), where + "holds no signal sets");
    return sets;
}

std::string worst_outside_training(const kern::GainSpec& g, const std::vector<std::string>& names,
                                   const std::vector<double>& x, int n, double t0, double dt) {
    if (n <= 0) return "";
    BoxExcursion far;
    far.see(g, x.data(), std::int64_t(x.size()) / n, n, t0, dt);
    return far.text(names);
}

std::string worst_truth_outside_training(const RunConfig& cfg, const kern::GainSpec& g, const Signals& s,
                                         std::int64_t steps) {
    if (g.zlo.empty()) return "";
    const TruthRun tr = truth_simulate(cfg, Scenario{}, 0, steps, &s);
    return worst_outside_training(g, cfg.system->state_names(), tr.x, cfg.n, cfg.time_of(0), cfg.dt);
}

}  // namespace hinf
