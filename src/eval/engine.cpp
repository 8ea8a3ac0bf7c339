// The Monte Carlo engine (see engine.hpp): truth per run from sim/truth, every filter stepped over the same
// measurements through filter_stream, error sums per (filter, run), observers per step.
#include "eval/engine.hpp"

#include <algorithm>
#include <cmath>
#include <omp.h>

#include "filters/gain_law.hpp"
#include "hinf/error.hpp"
#include "io/progress.hpp"

namespace hinf {

std::uint64_t hash_bytes(std::uint64_t h, const void* data, std::size_t bytes) {
    const unsigned char* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) {
        h ^= p[i];
        h *= 1099511628211ull;
    }
    return h;
}

FilterStart engine_filter_start(const RunConfig& cfg, std::uint64_t run) {
    const int n = cfg.n;
    FilterStart start;
    start.xhat0 = cfg.xhat0;
    start.P0.assign(std::size_t(n) * n, 0.0);
    for (int i = 0; i < n; ++i) {
        // the initial estimate's error variance: the actual squared initial error (floor 1), the same for all
        const double d = cfg.x0[i] - cfg.xhat0[i];
        start.P0[i * n + i] = std::max(d * d, 1.0);
    }
    start.seed = cfg.online_seed;
    start.run = run;
    return start;
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
    f.reset(engine_filter_start(cfg, run));
    if (obs != nullptr) obs->begin(index, run);
    StreamResult sr = filter_stream(f, tr.y.data(), m, t.data(), K, tr.x.data(), n,
                                    [&](std::int64_t k, const double* xh, bool) {
        const double* x = tr.x.data() + k * n;
        if (obs != nullptr) obs->observe(k, t[k], x, xh);
        for (int i = 0; i < n; ++i) e[i] = x[i] - xh[i];
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
            r.settled_steps += 1;
            r.sq_pos_settled += pp;
            r.sq_vel_settled += vv;
            for (int i = 0; i < n; ++i) {
                r.err_sum_settled[i] += e[i];
                r.err_sq_settled[i] += e[i] * e[i];
            }
        }
        r.stream_hash = hash_bytes(r.stream_hash, tr.y.data() + k * m, sizeof(double) * m);
    });
    r.diverged_at = sr.diverged_at;
    r.seconds = sr.seconds;
    if (obs != nullptr) r.observed = obs->end();
    return r;
}

}  // namespace

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
    res.t.resize(K);
    for (std::int64_t k = 0; k < K; ++k) res.t[k] = cfg.time_of(k);
    Progress progress(opt.label, 0, R, opt.quiet);
    std::int64_t done = 0;
#pragma omp parallel
    {
        std::vector<std::unique_ptr<OnlineFilter>> local;
        for (const OnlineFilter* f : filters) local.push_back(f->clone());
        std::unique_ptr<StepObserver> obs = observer != nullptr ? observer->clone() : nullptr;
#pragma omp for schedule(dynamic)
        for (std::int64_t r = 0; r < R; ++r) {
            TruthRun tr = truth_simulate(cfg, opt.scenario, std::uint64_t(r), K,
                                         opt.signals != nullptr ? &(*opt.signals)[r] : nullptr);
            res.truth_hash[r] = hash_bytes(hash_start, tr.y.data(), sizeof(double) * tr.y.size());
            for (int k = 0; k < F; ++k)
                res.runs[k][r] = run_one_filter(cfg, *local[k], tr, res.t, std::uint64_t(r), opt, obs.get(), k);
            if (r == 0) res.truth0 = std::move(tr);
#pragma omp critical
            progress.update(++done, "runs |");
        }
    }
    return res;
}

}  // namespace hinf
