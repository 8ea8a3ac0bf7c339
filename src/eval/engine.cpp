// The Monte Carlo engine (see engine.hpp): truth per run from sim/truth, every filter stepped over the same
// measurements through filter_stream, error sums per (filter, run), observers per step.
#include "eval/engine.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <omp.h>

#include "filters/gain_law.hpp"
#include "hinf/error.hpp"
#include "io/progress.hpp"
#include "par/par.hpp"

namespace hinf {

std::uint64_t hash_bytes(std::uint64_t h, const void* data, std::size_t bytes) {
    const unsigned char* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) {
        h ^= p[i];
        h *= 1099511628211ull;
    }
    return h;
}

std::vector<double> baseline_initial_covariance(const RunConfig& cfg, const std::vector<double>& initial_std) {
    const int n = cfg.n;
    const std::vector<double>& sd = !initial_std.empty() ? initial_std : cfg.initial_std;
    HINF_CHECK(sd.empty() || int(sd.size()) == n, "initial_std has " + std::to_string(sd.size()) +
                                                      " values, the system has " + std::to_string(n) + " states");
    std::vector<double> P0(std::size_t(n) * n, 0.0);
    for (int i = 0; i < n; ++i) {
        const double d = cfg.x0[i] - cfg.xhat0[i];  // the actual initial error (0: the start is known exactly)
        const double v = sd.empty() ? d * d : sd[i] * sd[i];
        HINF_CHECK(std::isfinite(v) && v >= 0, "initial_std: value " + std::to_string(i + 1) +
                                                   " is not a finite number >= 0 (one standard deviation per state)");
        P0[std::size_t(i) * n + i] = v;
    }
    return P0;
}

std::string baseline_certain_note(const RunConfig& cfg, const std::vector<double>& P0) {
    const auto names = cfg.system->state_names();
    std::string which;
    for (int i = 0; i < cfg.n; ++i)
        if (P0[std::size_t(i) * cfg.n + i] == 0) which += (which.empty() ? "" : ", ") + names[i];
    if (which.empty()) return "";
    return "note: ekf, ukf and pf start certain of " + which + " (x0 = x^0 there in the config, so the variance they "
           "are told is 0); to give them a spread, pass --initial-std or set [baseline] initial_std (docs/compare.md)";
}

FilterStart engine_filter_start(const RunConfig& cfg, std::uint64_t run) {
    FilterStart start;
    start.xhat0 = cfg.xhat0;
    start.P0 = baseline_initial_covariance(cfg);  // the same for every filter and run
    start.seed = cfg.online_seed;
    start.run = run;
    return start;
}

std::vector<double> plausible_bound(const RunConfig& cfg, const FilterStart& start, const double* x_true,
                                    const double* y, std::int64_t K) {
    const int n = cfg.n, m = cfg.m;
    double ymax = 0;
    if (y != nullptr)
        for (std::int64_t i = 0; i < K * m; ++i)
            if (std::isfinite(y[i])) ymax = std::max(ymax, std::fabs(y[i]));
    std::vector<double> bound(n);
    for (int i = 0; i < n; ++i) {
        double s = std::max({std::fabs(cfg.x0[i]), std::fabs(start.xhat0[i]), ymax});
        if (start.P0.size() == std::size_t(n) * n) s = std::max(s, std::sqrt(std::max(0.0, start.P0[i * n + i])));
        if (x_true != nullptr)
            for (std::int64_t k = 0; k < K; ++k) s = std::max(s, std::fabs(x_true[k * n + i]));
        // a state with no scale at all (a bias or a parameter that starts at 0 and stays there in the truth) has no
        // range to leave: any estimate of it would count, the DNN gain's first nudge included (docs/compare.md)
        bound[i] = s > 0 ? kPlausibleFactor * s : std::numeric_limits<double>::infinity();
    }
    // an angle winds (a phase turns on for as long as the record runs): its value is no scale, so only a non-finite
    // estimate of it counts (|x^| <= the largest double)
    for (int i : cfg.system->angle_states()) bound[std::size_t(i)] = std::numeric_limits<double>::max();
    return bound;
}

double nees(const double* P, const double* e, int n) {
    const Eigen::Map<const Eigen::MatrixXd> Pm(P, n, n);  // symmetric: layout does not matter
    if (!Pm.allFinite()) return NAN;
    return normalised_square(Eigen::LLT<Eigen::MatrixXd>(Pm), Eigen::Map<const Eigen::VectorXd>(e, n));  // as the NIS
}

namespace {

FilterRunStats run_one_filter(const RunConfig& cfg, OnlineFilter& f, const TruthRun& tr, const std::vector<double>& t,
                              std::uint64_t run, const EngineOptions& opt, StepObserver* obs, int index) {
    const int n = cfg.n, m = cfg.m;
    const std::int64_t K = opt.steps;
    // "position" and "velocity": the states of the first and second unit (x, y, z and vx, vy, vz for the missile)
    const std::vector<int> pos = state_unit_group(*cfg.system, 0), vel = state_unit_group(*cfg.system, 1);
    FilterRunStats r;
    r.err_sum.assign(n, 0);
    r.err_sq.assign(n, 0);
    r.err_sum_settled.assign(n, 0);
    r.err_sq_settled.assign(n, 0);
    r.stream_hash = hash_start;
    std::vector<double> e(n);
    const FilterStart start = engine_filter_start(cfg, run);
    f.reset(start);
    const bool stated = f.covariance_is_statistical();
    if (obs != nullptr) obs->begin(index, run);
    const std::vector<double> bound = plausible_bound(cfg, start, tr.x.data(), nullptr, K);
    StreamResult sr = filter_stream(f, tr.y.data(), m, t.data(), K, tr.x.data(), n, bound.data(), nullptr,
                                    [&](std::int64_t k, const double* xh, bool frozen) {
        const double* x = tr.x.data() + k * n;
        if (obs != nullptr) obs->observe(k, t[k], x, xh);
        cfg.system->state_difference(e.data(), x, xh);  // an angle state's wrapped
        if (run == 0) r.xhat.insert(r.xhat.end(), xh, xh + n);
        if (k % opt.stride == 0) r.err_sub.insert(r.err_sub.end(), e.begin(), e.end());
        r.error_energy += cfg.dt * quadratic_form(cfg.Q.data(), e.data(), n);
        r.signal_energy += cfg.dt * tr.energy[k];
        double pp = 0, vv = 0;
        for (int i : pos) pp += e[i] * e[i];
        for (int i : vel) vv += e[i] * e[i];
        r.sq_pos += pp;
        r.sq_vel += vv;
        for (int i = 0; i < n; ++i) {
            r.err_sum[i] += e[i];
            r.err_sq[i] += e[i] * e[i];
        }
        if (t[k] >= cfg.settle_time) {
            if (stated && !frozen) {
                const double q = nees(f.covariance(), e.data(), n);
                if (std::isfinite(q)) {
                    r.nees_sum += q;
                    r.nees_steps += 1;
                }
            }
            r.settled_steps += 1;
            r.sq_pos_settled += pp;
            r.sq_vel_settled += vv;
            for (int i = 0; i < n; ++i) {
                r.err_sum_settled[i] += e[i];
                r.err_sq_settled[i] += e[i] * e[i];
            }
        }
        r.stream_hash = hash_bytes(r.stream_hash, tr.y.data() + k * m, sizeof(double) * m);
    }, [&](std::int64_t k, const double* xf, bool frozen) {
        if (stated && !frozen && t[k] >= cfg.settle_time) {
            const double q = f.nis();  // of y(t_k); NaN without a measurement or a positive definite S
            if (std::isfinite(q)) {
                r.nis_sum += q;
                r.nis_steps += 1;
            }
        }
        if (xf == nullptr) return;
        const double* x = tr.x.data() + k * n;
        if (r.err_sq_filtered.empty()) r.err_sq_filtered.assign(n, 0.0);
        cfg.system->state_difference(e.data(), x, xf);
        for (int i = 0; i < n; ++i) r.err_sq_filtered[i] += e[i] * e[i];
    });
    r.diverged_at = sr.diverged_at;
    r.seconds = sr.seconds;
    if (obs != nullptr) r.observed = obs->end();
    r.reported = f.run_report();
    r.note = f.run_note();
    return r;
}

void put_stats(ParBytesOut& w, const FilterRunStats& s) {
    for (double v : {s.diverged_at, s.settled_steps, s.sq_pos, s.sq_vel, s.sq_pos_settled, s.sq_vel_settled,
                     s.error_energy, s.signal_energy, s.seconds, s.nees_sum, s.nees_steps, s.nis_sum, s.nis_steps})
        w.put(v);
    w.put(s.stream_hash);
    for (const auto* v : {&s.err_sum, &s.err_sq, &s.err_sum_settled, &s.err_sq_settled, &s.err_sub, &s.xhat, &s.observed,
                          &s.err_sq_filtered, &s.reported})
        w.put(*v);
    w.put(s.note);
}

FilterRunStats get_stats(ParBytesIn& rd) {
    FilterRunStats s;
    for (double* v : {&s.diverged_at, &s.settled_steps, &s.sq_pos, &s.sq_vel, &s.sq_pos_settled, &s.sq_vel_settled,
                      &s.error_energy, &s.signal_energy, &s.seconds, &s.nees_sum, &s.nees_steps, &s.nis_sum, &s.nis_steps})
        *v = rd.get_double();
    s.stream_hash = rd.get_u64();
    for (auto* v : {&s.err_sum, &s.err_sq, &s.err_sum_settled, &s.err_sq_settled, &s.err_sub, &s.xhat, &s.observed,
                    &s.err_sq_filtered, &s.reported})
        *v = rd.get_vector();
    s.note = rd.get_string();
    return s;
}

}  // namespace

std::int64_t engine_rank_of(std::int64_t run, int ranks) { return run % ranks; }

EngineResult engine_run(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                        const EngineOptions& opt, const StepObserver* observer) {
    HINF_CHECK(!filters.empty(), "no filters to run (name at least one with --filters)");
    HINF_CHECK(opt.runs >= 1, "--runs must be >= 1 (got " + std::to_string(opt.runs) + ")");
    HINF_CHECK(opt.steps >= 1, "the horizon is shorter than one time step (dt = " + std::to_string(cfg.dt) +
                                   " s): pass a later --until or a longer [filter] t_final");
    HINF_CHECK(opt.signals == nullptr || std::int64_t(opt.signals->size()) == opt.runs,
               "engine: " + std::to_string(opt.signals ? opt.signals->size() : 0) + " signal sets for " +
                   std::to_string(opt.runs) + " runs");
    const int F = static_cast<int>(filters.size());
    const std::int64_t R = opt.runs, K = opt.steps;
    EngineResult res;
    res.runs.assign(F, std::vector<FilterRunStats>(R));
    res.truth_hash.assign(R, 0);
    res.truth_escaped_at.assign(R, -1.0);
    const std::vector<double> escape_bound = truth_escape_bound(cfg, K);
    res.t.resize(K);
    for (std::int64_t k = 0; k < K; ++k) res.t[k] = cfg.time_of(k);
    // under mpirun: run r is computed by rank r mod size (runs cost alike, and a filter's divergence makes
    // later runs cheaper at random, so dealing them out evens the load better than blocks); each run draws
    // from its own counter-based streams, so who computes it does not change a bit of it
    const int rank = opt.split ? par_rank() : 0, ranks = opt.split ? par_size() : 1;
    HINF_CHECK(ranks <= R, std::to_string(ranks) + " MPI processes for " + std::to_string(R) +
                               " run(s): start at most as many processes as runs (mpirun -np)");
    std::vector<std::int64_t> mine;
    for (std::int64_t r = 0; r < R; ++r)
        if (engine_rank_of(r, ranks) == rank) mine.push_back(r);
    const std::int64_t L = std::int64_t(mine.size());
    Progress progress(opt.label, 0, L, opt.quiet);
    std::int64_t done = 0;
    const auto c0 = std::chrono::steady_clock::now();
#pragma omp parallel
    {
        std::vector<std::unique_ptr<OnlineFilter>> local;
        for (const OnlineFilter* f : filters) local.push_back(f->clone());
        std::unique_ptr<StepObserver> obs = observer != nullptr ? observer->clone() : nullptr;
#pragma omp for schedule(dynamic)
        for (std::int64_t j = 0; j < L; ++j) {
            const std::int64_t r = mine[j];
            // a look past the horizon catches an escape still finite at its end
            std::int64_t esc = -1;
            TruthRun tr = truth_simulate_checked(cfg, opt.scenario, std::uint64_t(r), K, escape_bound.data(), &esc,
                                                 opt.signals != nullptr ? &(*opt.signals)[r] : nullptr);
            res.truth_hash[r] = hash_bytes(hash_start, tr.y.data(), sizeof(double) * tr.y.size());
            if (esc >= 0) res.truth_escaped_at[r] = cfg.time_of(esc);
            for (int k = 0; k < F; ++k)
                res.runs[k][r] = run_one_filter(cfg, *local[k], tr, res.t, std::uint64_t(r), opt, obs.get(), k);
            if (r == 0) res.truth0 = std::move(tr);
#pragma omp critical
            progress.update(++done, ranks > 1 ? "runs of rank 0 |" : "runs |");
        }
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count();
    res.rank_seconds = opt.split ? par_allgather_double(seconds) : std::vector<double>{seconds};
    if (ranks == 1) return res;
    // run 0's truth for the files, on the ranks that did not compute run 0: one more simulation, the same bits
    if (engine_rank_of(0, ranks) != rank)
        res.truth0 = truth_simulate(cfg, opt.scenario, 0, K, opt.signals != nullptr ? &(*opt.signals)[0] : nullptr);

    // every rank's runs to every rank, then placed in run order: the reductions that follow see the same
    // [F][R] table whatever the number of processes
    ParBytesOut w;
    for (std::int64_t r : mine) {
        w.put(res.truth_hash[r]);
        w.put(res.truth_escaped_at[r]);
        for (int k = 0; k < F; ++k) put_stats(w, res.runs[k][r]);
    }
    const std::vector<std::vector<char>> all = par_allgather(w.bytes);
    for (int q = 0; q < ranks; ++q) {
        ParBytesIn rd(all[q]);
        for (std::int64_t r = 0; r < R; ++r) {
            if (engine_rank_of(r, ranks) != q) continue;
            res.truth_hash[r] = rd.get_u64();
            res.truth_escaped_at[r] = rd.get_double();
            for (int k = 0; k < F; ++k) res.runs[k][r] = get_stats(rd);
        }
        HINF_CHECK(rd.at_end(), "engine: a rank sent more than its runs (bug)");
    }
    return res;
}

}  // namespace hinf
