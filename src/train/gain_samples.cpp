// Samples of the gain variant (see gain_samples.hpp).
#include "train/gain_samples.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "filters/gain_law.hpp"
#include "hinf/error.hpp"
#include "random.hpp"

namespace hinf {

kern::HjieSystemView GainSamples::view() const {
    return {n, nv, m, xt.data(), dA.data(), Bm.data(), dC.data(), q.data(), t.data(),
            Hx.empty() ? nullptr : Hx.data(), Fx.empty() ? nullptr : Fx.data()};
}

GainPool gain_pool_build(const RunConfig& cfg) {
    GainPool pool;
    pool.steps = cfg.steps_until();
    RunConfig c = cfg;
    // a seed of its own: splitmix of the training seed, never equal to a plain on-line seed
    std::uint64_t z = cfg.seed + 0x9E3779B97F4A7C15ull;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    c.online_seed = (z ^ (z >> 31)) >> 1;
    std::vector<TruthRun> runs(static_cast<std::size_t>(cfg.trajectories));
    std::vector<std::int64_t> escaped_at(runs.size(), -1);
    const std::vector<double> bound = truth_escape_bound(cfg, pool.steps);
#pragma omp parallel for schedule(dynamic)
    for (std::int64_t r = 0; r < cfg.trajectories; ++r) {
        runs[r] = truth_simulate_checked(c, Scenario{}, std::uint64_t(r), pool.steps, bound.data(), &escaped_at[r]);
    }
    for (std::size_t r = 0; r < runs.size(); ++r) {
        if (escaped_at[r] < 0) {
            pool.runs.push_back(std::move(runs[r]));
            continue;
        }
        ++pool.escaped;
        const double t = cfg.time_of(escaped_at[r]);
        if (pool.first_escape < 0 || t < pool.first_escape) pool.first_escape = t;
    }
    HINF_CHECK(!pool.runs.empty(), truth_escape_refusal(cfg, cfg.trajectories, "training truth runs", pool.first_escape));
    return pool;
}

std::string gain_pool_note(const RunConfig& cfg, const GainPool& pool) {
    if (pool.escaped == 0) return "";
    return "hinf: note: " + std::to_string(pool.escaped) + " of " + std::to_string(cfg.trajectories) +
           " training truth runs ran away (the first at t = " + format_g(pool.first_escape) +
           " s: " + truth_escape_cause(cfg) + "); training draws its estimates from the other " +
           std::to_string(pool.runs.size()) + " (docs/method.md section 16.3)\n";
}

namespace {

void resize(GainSamples* s, const RunConfig& cfg, const kern::GainSpec& g, std::int64_t N) {
    const int n = cfg.n, nv = cfg.nv, m = cfg.m;
    s->n = n;
    s->nv = nv;
    s->m = m;
    s->xt.resize(N * n);
    s->dA.resize(N * n);
    s->Bm.resize(N * n * nv);
    s->dC.resize(N * m);
    s->q.resize(N);
    s->z.resize(N * g.input_count(n));
    s->xhat.resize(N * n);
    s->x.resize(N * n);
    s->t.resize(N);
    s->Hx.resize(g.knots > 0 || g.kalman ? N * m * n : 0);
    s->Fx.resize(g.kalman ? N * n * n : 0);
}

// the per-sample constants from s->x, s->xhat, s->t (per sample: each has its own time); held: the network input
// z in the filter's box (the on-line check and retraining evaluate the filter's network), else as drawn (training)
void constants(GainSamples* s, const RunConfig& cfg, const kern::GainSpec& g, std::int64_t N, bool held) {
    const int n = s->n, nv = s->nv, m = s->m;
    const System& sys = *cfg.system;
#pragma omp parallel for schedule(static)
    for (std::int64_t i = 0; i < N; ++i) {
        double ah[32], ch[32];
        const double* x = s->x.data() + i * n;
        const double* xh = s->xhat.data() + i * n;
        sys.drift(s->dA.data() + i * n, x, s->t[i], 1);
        sys.drift(ah, xh, s->t[i], 1);
        sys.disturbance_gain(s->Bm.data() + i * n * nv, x, s->t[i], 1);
        sys.measurement(s->dC.data() + i * m, x, s->t[i], 1);
        sys.measurement(ch, xh, s->t[i], 1);
        for (int j = 0; j < n; ++j) s->dA[i * n + j] -= ah[j];
        sys.output_difference(s->dC.data() + i * m, s->dC.data() + i * m, ch);  // an angle output's wrapped
        s->q[i] = quadratic_form(cfg.Q.data(), s->xt.data() + i * n, n);
        g.input_row(s->z.data() + i * g.input_count(n), xh, n, held);
        if (g.knots > 0 || g.kalman) sys.measurement_jacobian(s->Hx.data() + i * m * n, xh, s->t[i]);
        if (g.kalman) sys.drift_jacobian(s->Fx.data() + i * n * n, xh, s->t[i]);
    }
}

void draw_errors(GainSamples* s, const RunConfig& cfg, const kern::GainSpec& g, std::int64_t N, std::uint64_t a,
                 std::vector<double>* u) {
    const int n = cfg.n;
    std::vector<double> xi(static_cast<std::size_t>(N * n));
    u->resize(static_cast<std::size_t>(N * 3));
    kern::rng_normal(xi.data(), N * n, cfg.seed, kern::RNG_STREAM_GAIN, a, 0);
    kern::rng_uniform(u->data(), N * 3, cfg.seed, kern::RNG_STREAM_GAIN, a, 1);
    for (std::int64_t i = 0; i < N; ++i) {
        const double radius = std::pow(10.0, -cfg.radius_decades * (*u)[i * 3 + 2]);
        for (int j = 0; j < n; ++j) s->xt[i * n + j] = radius * g.dx[j] * xi[i * n + j];
    }
}

// [sampling] state_bounds (method.md 16.3): x, and with estimates = true x^, held inside the region where the model is
// meant to hold, x~ = x - x^ where either moved; nothing without bounds (the same bits as before the key)
void hold_in_bounds(GainSamples* s, const RunConfig& cfg, std::int64_t N, bool estimates) {
    if (cfg.state_lo.empty()) return;
    const int n = cfg.n;
    for (std::int64_t i = 0; i < N; ++i)
        for (int j = 0; j < n; ++j) {
            double& x = s->x[i * n + j];
            double& xh = s->xhat[i * n + j];
            const double hx = std::min(cfg.state_hi[j], std::max(cfg.state_lo[j], x));
            const double hxh = estimates ? std::min(cfg.state_hi[j], std::max(cfg.state_lo[j], xh)) : xh;
            if (hx == x && hxh == xh) continue;  // inside: the drawn error stays, bit for bit
            x = hx;
            xh = hxh;
            s->xt[i * n + j] = x - xh;
        }
}

}  // namespace

void gain_samples_build(GainSamples* s, const RunConfig& cfg, const GainPool& pool, const kern::GainSpec& g,
                        std::int64_t N, std::uint64_t a) {
    const int n = cfg.n;
    resize(s, cfg, g, N);
    std::vector<double> u;
    draw_errors(s, cfg, g, N, a, &u);
    const std::int64_t R = std::int64_t(pool.runs.size()), G = std::max(1, g.group);
    for (std::int64_t i = 0; i < N; ++i) {
        const std::int64_t lead = i - i % G;  // the group's first sample draws the run, the time and the estimate
        if (i != lead) {                       // the others: errors around the same estimate, x = x^ + x~
            for (int j = 0; j < n; ++j) {
                s->xhat[i * n + j] = s->xhat[lead * n + j];
                s->x[i * n + j] = s->xhat[lead * n + j] + s->xt[i * n + j];
            }
            s->t[i] = s->t[lead];
            continue;
        }
        const std::int64_t r = std::min(R - 1, std::int64_t(u[i * 3] * double(R)));
        const std::int64_t k = std::min(pool.steps - 1, std::int64_t(u[i * 3 + 1] * double(pool.steps)));
        const double* x = pool.runs[r].x.data() + k * n;
        for (int j = 0; j < n; ++j) {
            s->x[i * n + j] = x[j];
            s->xhat[i * n + j] = x[j] - s->xt[i * n + j];
        }
        s->t[i] = cfg.time_of(k);
    }
    hold_in_bounds(s, cfg, N, true);
    constants(s, cfg, g, N, false);
}

namespace {

// N estimates drawn as gain_samples_build draws its groups' first samples (no per-sample constants), counter a:
// x^ = x - x~ [N x n], held in state_bounds as training holds them
std::vector<double> draw_estimates(const RunConfig& cfg, const kern::GainSpec& g, const GainPool& pool,
                                   std::int64_t N, std::uint64_t a) {
    const int n = cfg.n;
    const std::int64_t R = std::int64_t(pool.runs.size());
    GainSamples s;
    s.xt.resize(static_cast<std::size_t>(N * n));
    std::vector<double> u;
    draw_errors(&s, cfg, g, N, a, &u);
    std::vector<double> xh(static_cast<std::size_t>(N * n));
    for (std::int64_t i = 0; i < N; ++i) {
        const std::int64_t r = std::min(R - 1, std::int64_t(u[i * 3] * double(R)));
        const std::int64_t k = std::min(pool.steps - 1, std::int64_t(u[i * 3 + 1] * double(pool.steps)));
        const double* x = pool.runs[r].x.data() + k * n;
        for (int j = 0; j < n; ++j) {
            double e = x[j] - s.xt[i * n + j];
            if (!cfg.state_lo.empty()) e = std::min(cfg.state_hi[j], std::max(cfg.state_lo[j], e));
            xh[i * n + j] = e;
        }
    }
    return xh;
}

}  // namespace

void gain_input_box(kern::GainSpec* g, const RunConfig& cfg, const GainPool& pool) {
    g->zlo.clear();
    g->zhi.clear();
    if (!(cfg.input_box > 0)) return;
    const int n = cfg.n;
    const std::int64_t N = kInputBoxEstimates;
    std::vector<double> z = draw_estimates(cfg, *g, pool, N, kInputBoxCounter);
    for (std::int64_t i = 0; i < N; ++i)
        for (int j = 0; j < n; ++j) z[i * n + j] = (z[i * n + j] - g->shift[j]) / g->spread[j];
    std::vector<double> col(static_cast<std::size_t>(N)), lo(n), hi(n);
    const double last = double(N - 1);
    for (int j = 0; j < n; ++j) {
        for (std::int64_t i = 0; i < N; ++i) {
            col[i] = z[i * n + j];
            if (!std::isfinite(col[i])) return;  // a truth run that escaped: no box (the trainer says so)
        }
        std::sort(col.begin(), col.end());
        lo[j] = col[std::size_t(std::floor(cfg.input_box * last))];
        hi[j] = col[std::size_t(std::ceil((1.0 - cfg.input_box) * last))];
    }
    g->zlo = lo;
    g->zhi = hi;
}

std::vector<SignCrossing> gain_sign_crossings(const RunConfig& cfg, const GainPool& pool, const kern::GainSpec& g) {
    std::vector<SignCrossing> out;
    if (!cfg.state_lo.empty() || pool.runs.empty()) return out;
    const int n = cfg.n;
    std::vector<double> lo(n, INFINITY), hi(n, -INFINITY);
    for (const TruthRun& run : pool.runs)
        for (std::size_t i = 0; i < run.x.size(); ++i) {
            const int j = int(i % std::size_t(n));
            lo[j] = std::min(lo[j], run.x[i]);
            hi[j] = std::max(hi[j], run.x[i]);
        }
    const std::int64_t N = kInputBoxEstimates;
    const std::vector<double> xh = draw_estimates(cfg, g, pool, N, kInputBoxCounter);
    const std::vector<int>& angles = cfg.system->angle_states();
    for (int j = 0; j < n; ++j) {
        const bool above = lo[j] >= 0 && hi[j] > 0, below = hi[j] <= 0 && lo[j] < 0;
        if (!above && !below) continue;
        if (std::find(angles.begin(), angles.end(), j) != angles.end()) continue;  // an angle's sign means nothing
        std::int64_t crossed = 0;
        for (std::int64_t i = 0; i < N; ++i) crossed += above ? xh[i * n + j] < 0 : xh[i * n + j] > 0;
        const double share = double(crossed) / double(N);
        if (share >= kSignCrossingShare) out.push_back({j, above, share});
    }
    return out;
}

std::string gain_sign_note(const RunConfig& cfg, const std::vector<SignCrossing>& crossings) {
    if (crossings.empty()) return "";
    const std::vector<std::string> names = cfg.system->state_names();
    std::string which, bounds;
    for (std::size_t c = 0; c < crossings.size(); ++c) {
        const SignCrossing& x = crossings[c];
        char pct[32];
        std::snprintf(pct, sizeof pct, "%.1f%%", 100.0 * x.share);
        which += std::string(c == 0 ? "" : c + 1 == crossings.size() ? " and " : ", ") + names[x.state] +
                 (x.positive ? " >= 0" : " <= 0") + " (" + pct + " of the estimates cross)";
    }
    for (int j = 0; j < cfg.n; ++j) {
        std::string pair = "[-inf, inf]";
        for (const SignCrossing& x : crossings)
            if (x.state == j) pair = x.positive ? "[0, inf]" : "[-inf, 0]";
        bounds += (j == 0 ? "" : ", ") + pair;
    }
    return "hinf: note: every training truth run keeps " + which +
           ", but the errors training samples around them (docs/method.md section 16.4) put that share of its "
           "estimates on the other side of 0. If the model means nothing there (a rate divided by a concentration, "
           "the square root of a level), hold the samples where it holds: [sampling] state_bounds = [" + bounds +
           "] (docs/method.md section 16.3, \"Where the model holds\")\n";
}

void gain_samples_at(GainSamples* s, const RunConfig& cfg, const kern::GainSpec& g, const double* xhat, double t,
                     std::int64_t N, std::uint64_t a) {
    const int n = cfg.n;
    resize(s, cfg, g, N);
    std::vector<double> u;
    draw_errors(s, cfg, g, N, a, &u);
    for (std::int64_t i = 0; i < N; ++i) {
        for (int j = 0; j < n; ++j) {
            s->xhat[i * n + j] = xhat[j];
            s->x[i * n + j] = xhat[j] + s->xt[i * n + j];
        }
        s->t[i] = t;
    }
    hold_in_bounds(s, cfg, N, false);  // the estimate is the filter's own: only the errors' states are held
    constants(s, cfg, g, N, true);
}

}  // namespace hinf
