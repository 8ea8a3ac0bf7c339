// See observability.hpp.
#include "eval/observability.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "eval/engine.hpp"
#include "filters/ekf.hpp"
#include "sim/truth.hpp"

namespace hinf {

StateInformation state_information(const RunConfig& cfg) {
    StateInformation s;
    const int n = cfg.n, m = cfg.m, nv = cfg.nv;
    const std::int64_t K = cfg.steps_until();
    s.steps = K;
    s.ratio.assign(std::size_t(n), NAN);
    s.growth.assign(std::size_t(n), NAN);
    if (K < 2) return s;
    // the noise-free run from x0: y = C(x) exactly
    Signals zero;
    zero.v.assign(std::size_t(K * nv), 0.0);
    zero.n.assign(std::size_t(K * m), 0.0);
    const TruthRun tr = truth_simulate(cfg, Scenario{}, 0, K, &zero);
    // the EKF told the exact model with a thousandth of its measurement noise (a millionth of its variance; a
    // noiseless sensor: a thousandth of the outputs' RMS), so that what it cannot learn is what the outputs do not
    // carry, not what their noise hides; started on the truth with compare's P0
    FilterModel told = filter_model(cfg);
    if (told.noise_std > 0) told.noise_std *= kSeenNoiseFactor;
    else {
        double sum = 0;
        for (double y : tr.y) sum += y * y;
        told.noise_std = kSeenNoiseFactor * std::max(std::sqrt(sum / double(tr.y.size())), 1e-300);
    }
    FilterStart start = engine_filter_start(cfg, 0);
    start.xhat0 = cfg.x0;
    std::unique_ptr<OnlineFilter> seen = make_ekf(told), blind = make_ekf(told);
    seen->reset(start);
    blind->reset(start);
    const std::int64_t half = K / 2;
    std::vector<double> sum_seen(std::size_t(n), 0.0), sum_blind(std::size_t(n), 0.0), at_half(std::size_t(n), 0.0);
    for (std::int64_t k = 0; k < K; ++k) {
        FilterInput in;
        in.t = double(k) * cfg.dt;
        in.step = k;
        in.x_true = tr.x.data() + k * n;
        in.y = tr.y.data() + k * m;
        const FilterStatus a = seen->step(in);
        in.y = nullptr;  // no measurement: the prediction alone
        const FilterStatus b = blind->step(in);
        if (a != FILTER_OK || b != FILTER_OK) return s;
        const double *P = seen->covariance(), *Q = blind->covariance();
        for (int i = 0; i < n; ++i) {
            const double p = P[std::size_t(i) * n + i], q = Q[std::size_t(i) * n + i];
            if (!std::isfinite(p) || !std::isfinite(q)) return s;
            if (k == half) at_half[std::size_t(i)] = p;
            if (k >= half) {
                sum_seen[std::size_t(i)] += p;
                sum_blind[std::size_t(i)] += q;
            }
            if (k == K - 1) s.growth[std::size_t(i)] = at_half[std::size_t(i)] > 0 ? p / at_half[std::size_t(i)] : NAN;
        }
    }
    for (int i = 0; i < n; ++i)
        if (sum_blind[std::size_t(i)] > 0) s.ratio[std::size_t(i)] = sum_seen[std::size_t(i)] / sum_blind[std::size_t(i)];
    s.ran = true;
    return s;
}

std::string unseen_states_note(const RunConfig& cfg, const StateInformation& s) {
    if (!s.ran) return "";
    const std::vector<std::string> names = cfg.system->state_names();
    std::string which, shares, growing;
    int count = 0;
    char buf[160];
    for (int i = 0; i < cfg.n; ++i) {
        const double r = s.ratio[std::size_t(i)];
        if (!(r >= kUnseenRatio)) continue;
        const std::string name = std::size_t(i) < names.size() ? names[std::size_t(i)] : std::to_string(i + 1);
        which += (count ? ", " : "") + name;
        std::snprintf(buf, sizeof buf, "%s%.0f %%", count ? ", " : "", 100 * r);
        shares += buf;
        const double g = s.growth[std::size_t(i)];
        if (g > kUnseenGrowth) {
            std::snprintf(buf, sizeof buf, "%s%s %.3gx", growing.empty() ? "" : ", ", name.c_str(), g);
            growing += buf;
        }
        ++count;
    }
    if (count == 0) return "";
    const std::string them = count > 1 ? "them" : "it";
    std::string note = "hinf: note: the outputs tell next to nothing about " + which +
                       ": along the noise-free run the EKF's covariance equation, told every measurement with a "
                       "thousandth of its noise, keeps " + shares +
                       " of the open-loop predictor's error variance there over the run's second half";
    if (!growing.empty())
        note += ", and that still grows (" + growing + " over the half): no filter can estimate " +
                (growing.find(',') == std::string::npos ? "it" : "them") + " from these outputs";
    note += ". Either the outputs do not depend on " + them + " or the disturbance masks what they would tell; no "
            "filter does much better there than the model's own prediction, whatever its training; a sensor that "
            "sees " + them + " does (docs/method.md section 16.18)";
    return note;
}

}  // namespace hinf
