// The truth simulator (see truth.hpp): Philox draws keyed by (online seed, run, step), scenario changes, and
// the system step shared with the filters (models/system.hpp).
#include "sim/truth.hpp"

#include <algorithm>
#include <cmath>

#include "hinf/error.hpp"
#include "random.hpp"

namespace hinf {

std::vector<std::string> scenario_names() {
    return {"nominal",     "cov_small",   "cov_large", "v_cov_small", "v_cov_large",
            "n_cov_small", "n_cov_large", "student_t", "bias",        "energy_pulse"};
}

double energy_pulse_span(const RunConfig& cfg, std::int64_t steps) {
    return std::max(0.0, std::min(cfg.time_of(steps), kPulseEnd) - kPulseStart);
}

Scenario scenario_named(const std::string& name, Spelling spelling) {
    Scenario s;
    s.name = name;
    if (name == "nominal") return s;
    if (name == "cov_small") s.told_disturbance_factor = s.told_noise_factor = 0.1;
    else if (name == "cov_large") s.told_disturbance_factor = s.told_noise_factor = 10.0;
    else if (name == "v_cov_small") s.told_disturbance_factor = 0.1;
    else if (name == "v_cov_large") s.told_disturbance_factor = 10.0;
    else if (name == "n_cov_small") s.told_noise_factor = 0.1;
    else if (name == "n_cov_large") s.told_noise_factor = 10.0;
    else if (name == "student_t") s.student_t = true;
    else if (name == "bias") s.noise_bias = 1.0;
    else if (name == "energy_pulse") s.energy_pulse = true;
    else {
        std::string all;
        for (const auto& n : scenario_names()) all += (all.empty() ? "" : ", ") + n;
        HINF_FAIL(option_name("--scenario", spelling) + " '" + name + "' is not one of: " + all);
    }
    return s;
}

FilterModel scenario_told_model(const RunConfig& cfg, const Scenario& sc) {
    // [baseline]: the filters' own model and statistics (default: the truth's), then the scenario's factors
    FilterModel m{cfg.told_system ? cfg.told_system.get() : cfg.system.get(), cfg.dt,
                  cfg.told_disturbance_std >= 0 ? cfg.told_disturbance_std : cfg.disturbance_std,
                  cfg.told_noise_std >= 0 ? cfg.told_noise_std : cfg.noise_std, {}, {}, {}, {}};
    m.disturbance_weight = cfg.told_disturbance_weight;
    m.noise_weight = cfg.told_noise_weight;
    m.disturbance_chol = cfg.told_disturbance_chol;
    m.noise_chol = cfg.told_noise_chol;
    m.disturbance_std *= std::sqrt(sc.told_disturbance_factor);
    m.noise_std *= std::sqrt(sc.told_noise_factor);
    return m;
}

TruthRun truth_simulate(const RunConfig& cfg, const Scenario& sc, std::uint64_t run, std::int64_t steps,
                        const Signals* given) {
    const System& sys = *cfg.system;
    const int n = cfg.n, nv = cfg.nv, m = cfg.m;
    if (given != nullptr)
        HINF_CHECK(std::int64_t(given->v.size()) == steps * nv && std::int64_t(given->n.size()) == steps * m,
                   "truth: the given signals hold " + std::to_string(given->v.size()) + " disturbance and " +
                       std::to_string(given->n.size()) + " noise values, " + std::to_string(steps) +
                       " steps need " + std::to_string(steps * nv) + " and " + std::to_string(steps * m));
    TruthRun tr;
    tr.x.resize(steps * n);
    tr.y.resize(steps * m);
    tr.v.resize(steps * nv);
    tr.n.resize(steps * m);
    tr.energy.resize(steps);
    std::vector<double> x = cfg.x0, x_next(n), noise(nv + m), c(m), chi(3 * m);
    const double T = cfg.time_of(steps), pulse = cfg.disturbance_std * std::sqrt(T / 5.0);
    for (std::int64_t s = 0; s < steps; ++s) {
        const double t = cfg.time_of(s);
        double* v = noise.data();
        double* nn = noise.data() + nv;
        if (given != nullptr) {
            std::copy(given->v.begin() + s * nv, given->v.begin() + (s + 1) * nv, v);
            std::copy(given->n.begin() + s * m, given->n.begin() + (s + 1) * m, nn);
        } else {
            kern::rng_normal(noise.data(), nv + m, cfg.online_seed, kern::RNG_STREAM_NOISE, run, std::uint64_t(s));
            for (int j = 0; j < nv; ++j) v[j] *= cfg.disturbance_std;
            if (sc.energy_pulse)
                for (int j = 0; j < nv; ++j) v[j] = (t >= kPulseStart && t < kPulseEnd) ? pulse : 0.0;
            if (sc.student_t) {
                // t_3 = z / sqrt(chi2_3 / 3) has variance 3: scaled by 1/sqrt(3) to unit variance
                kern::rng_normal(chi.data(), 3 * m, cfg.online_seed, kern::RNG_STREAM_HEAVY_TAIL, run,
                                 std::uint64_t(s));
                for (int j = 0; j < m; ++j) {
                    const double c2 =
                        chi[3 * j] * chi[3 * j] + chi[3 * j + 1] * chi[3 * j + 1] + chi[3 * j + 2] * chi[3 * j + 2];
                    nn[j] = nn[j] / std::sqrt(c2 / 3.0) / std::sqrt(3.0);
                }
            }
            for (int j = 0; j < m; ++j) nn[j] = (nn[j] + sc.noise_bias) * cfg.noise_std;
        }
        sys.measurement(c.data(), x.data(), t, 1);
        double vv = 0, nsq = 0;
        for (int j = 0; j < nv; ++j) vv += v[j] * v[j];
        for (int j = 0; j < m; ++j) {
            tr.y[s * m + j] = c[j] + nn[j];
            nsq += nn[j] * nn[j];
        }
        tr.energy[s] = vv + nsq;
        std::copy(x.begin(), x.end(), tr.x.begin() + s * n);
        std::copy(v, v + nv, tr.v.begin() + s * nv);
        std::copy(nn, nn + m, tr.n.begin() + s * m);
        system_advance(sys, x_next.data(), x.data(), v, t, cfg.dt);  // eq. (18) with the real v
        x.swap(x_next);
    }
    return tr;
}

std::vector<double> truth_escape_bound(const RunConfig& cfg, std::int64_t steps) {
    const int n = cfg.n;
    Signals quiet;  // the noise-free run: no disturbance, no noise
    quiet.v.assign(std::size_t(steps) * cfg.nv, 0.0);
    quiet.n.assign(std::size_t(steps) * cfg.m, 0.0);
    const TruthRun nf = truth_simulate(cfg, Scenario{}, 0, steps, &quiet);
    std::vector<double> bound(n);
    for (int i = 0; i < n; ++i) {
        double s = std::max(std::fabs(cfg.x0[i]), std::fabs(cfg.xhat0[i]));
        if (!cfg.initial_std.empty()) s = std::max(s, cfg.initial_std[i]);
        for (std::int64_t k = 0; k < steps; ++k)
            if (std::isfinite(nf.x[k * n + i])) s = std::max(s, std::fabs(nf.x[k * n + i]));
        bound[i] = s > 0 ? kTruthEscapeFactor * s : INFINITY;
    }
    return bound;
}

std::int64_t truth_escape_step(const TruthRun& run, int n, int m, const double* bound) {
    const std::int64_t K = n > 0 ? std::int64_t(run.x.size()) / n : 0;
    for (std::int64_t k = 0; k < K; ++k) {
        for (int i = 0; i < n; ++i) {
            const double x = run.x[k * n + i];
            if (!std::isfinite(x) || (bound != nullptr && std::fabs(x) > bound[i])) return k;
        }
        for (int j = 0; j < m && std::size_t(k * m + j) < run.y.size(); ++j)
            if (!std::isfinite(run.y[k * m + j])) return k;
    }
    return -1;
}

TruthRun truth_simulate_checked(const RunConfig& cfg, const Scenario& sc, std::uint64_t run, std::int64_t steps,
                                const double* bound, std::int64_t* escaped_at, const Signals* given) {
    const std::int64_t L = steps + kTruthEscapeLookahead;
    Signals padded;
    if (given != nullptr) {  // the signals end at the horizon; the look continues without any
        padded = *given;
        padded.v.resize(std::size_t(L) * cfg.nv, 0.0);
        padded.n.resize(std::size_t(L) * cfg.m, 0.0);
    }
    TruthRun tr = truth_simulate(cfg, sc, run, L, given != nullptr ? &padded : nullptr);
    *escaped_at = truth_escape_step(tr, cfg.n, cfg.m, bound);
    tr.x.resize(std::size_t(steps) * cfg.n);
    tr.y.resize(std::size_t(steps) * cfg.m);
    tr.v.resize(std::size_t(steps) * cfg.nv);
    tr.n.resize(std::size_t(steps) * cfg.m);
    tr.energy.resize(std::size_t(steps));
    return tr;
}

std::string truth_escape_refusal(const RunConfig& cfg, std::int64_t runs, const std::string& what, double first) {
    const std::string t = format_g(first);
    std::string msg = "the truth of every one of the " + std::to_string(runs) + " " + what + " of " + cfg.doc.source() +
                      " ran away (the first at t = " + t +
                      " s: not finite, or 1e12 times beyond every scale its config gives it): the system escapes from "
                      "[filter] x0 under its [online] noise; start it inside the region "
                      "it stays in, lower the noise";
    if (cfg.system != nullptr && !cfg.system->discrete_time())
        msg += ", take a shorter [filter] dt (the truth is stepped by forward Euler, and a step too long for the "
               "dynamics runs away)";
    return msg + " or check the model";
}

std::string truth_escape_cause(const RunConfig& cfg) {
    std::string s = "the system escapes under its [online] noise";
    if (cfg.system != nullptr && !cfg.system->discrete_time())
        s += ", or forward Euler's step dt = " + format_g(cfg.dt) +
             " s is too long for its dynamics where the noise took it (a shorter [filter] dt tells which)";
    return s;
}

}  // namespace hinf
