// On-line phase: true system with v, n ~ std * N(0,1), filter (19) with the frozen network's gain,
// in `oracle` (true x~ and C(x), the paper's protocol) or `measured` (innovation only) mode.
#include "eval/operate.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <omp.h>

#include "hinf/error.hpp"
#include "hinf/h5.hpp"
#include "io/progress.hpp"
#include "hjie.hpp"
#include "random.hpp"
#include "filters/dnn.hpp"
#include "filters/gain_law.hpp"

namespace hinf {

namespace {

struct RunResult {
    double num = 0, den = 0, num_open = 0;
    double diverged_at = -1;  // time [s] the estimate left every finite bound; < 0: did not diverge
    std::vector<double> err_sum, err_sq, err_sum_open, err_sq_open;
    std::vector<double> set_sum, set_sq;  // over t >= settle_time only
    double set_count = 0;
    double hji_violations = 0, hji_steps = 0;  // on-line: steps with HJIE(p at the true x~) > 0.01 S
    std::vector<double> x, xhat, xhat_open;  // run 0 only: [steps x n]
    std::vector<double> y;                   // run 0 only: [steps x m] the measurements fed to the filter
};

RunResult one_run(const RunConfig& cfg, FrozenNetwork& net, OnlineFilter& filter, std::int64_t run,
                  std::int64_t steps, bool keep_path) {
    const System& sys = *cfg.system;
    const int n = cfg.n, nv = cfg.nv, m = cfg.m;
    RunResult r;
    r.err_sum.assign(n, 0);
    r.err_sq.assign(n, 0);
    r.err_sum_open.assign(n, 0);
    r.err_sq_open.assign(n, 0);
    r.set_sum.assign(n, 0);
    r.set_sq.assign(n, 0);
    std::vector<double> x = cfg.x0, xhat = cfg.xhat0, xo = cfg.xhat0;  // xo: open-loop predictor
    std::vector<double> noise(nv + m), a_x(n), a_h(n), a_o(n), B(n * nv), c_x(m), c_h(m), y(m), e(m), dc(m), xt(n);
    FilterStart start;
    start.xhat0 = cfg.xhat0;
    start.seed = cfg.online_seed;
    start.run = std::uint64_t(run);
    filter.reset(start);
    for (std::int64_t s = 0; s < steps; ++s) {
        xhat.assign(filter.estimate(), filter.estimate() + n);
        const double t = double(s) * cfg.dt;
        kern::rng_normal(noise.data(), nv + m, cfg.online_seed, kern::RNG_STREAM_NOISE, std::uint64_t(run),
                         std::uint64_t(s));
        const double* v = noise.data();
        std::vector<double> nn(m);
        for (int j = 0; j < nv; ++j) noise[j] *= cfg.disturbance_std;
        for (int j = 0; j < m; ++j) nn[j] = noise[nv + j] * cfg.noise_std;
        sys.drift(a_x.data(), x.data(), t, 1);
        sys.drift(a_h.data(), xhat.data(), t, 1);
        sys.drift(a_o.data(), xo.data(), t, 1);
        sys.disturbance_gain(B.data(), x.data(), t, 1);
        sys.measurement(c_x.data(), x.data(), t, 1);
        sys.measurement(c_h.data(), xhat.data(), t, 1);
        for (int j = 0; j < m; ++j) {
            y[j] = c_x[j] + nn[j];
            e[j] = y[j] - c_h[j];
            dc[j] = c_x[j] - c_h[j];
        }
        for (int i = 0; i < n; ++i) xt[i] = x[i] - xhat[i];
        {
            // does the network satisfy the HJI inequality at the errors it meets on-line? (true x~ and x)
            std::vector<double> pt(n), dA(n), q1(1, quadratic_form(cfg.Q.data(), xt.data(), n));
            net.gradient(pt.data(), xt.data(), 1);
            for (int i = 0; i < n; ++i) dA[i] = a_x[i] - a_h[i];
            kern::HjieSystemView v1{n, nv, m, xt.data(), dA.data(), B.data(), dc.data(), q1.data()};
            double terms[4];
            kern::hjie_terms(terms, pt.data(), v1, 0, cfg.rho);
            double S = std::fabs(terms[0]) + std::fabs(terms[1]) + std::fabs(terms[2]) + std::fabs(terms[3]);
            r.hji_violations += (terms[0] + terms[1] + terms[2] + terms[3]) > 0.01 * S ? 1 : 0;
            r.hji_steps += 1;
        }
        // attenuation integrals (rectangle rule on the sampled data)
        double vv = 0, nsq = 0;
        for (int j = 0; j < nv; ++j) vv += v[j] * v[j];
        for (int j = 0; j < m; ++j) nsq += nn[j] * nn[j];
        r.den += cfg.dt * (vv + nsq);
        r.num += cfg.dt * quadratic_form(cfg.Q.data(), xt.data(), n);
        std::vector<double> xto(n);
        for (int i = 0; i < n; ++i) xto[i] = x[i] - xo[i];
        r.num_open += cfg.dt * quadratic_form(cfg.Q.data(), xto.data(), n);
        for (int i = 0; i < n; ++i) {
            r.err_sum[i] += xt[i];
            r.err_sq[i] += xt[i] * xt[i];
            r.err_sum_open[i] += xto[i];
            r.err_sq_open[i] += xto[i] * xto[i];
            if (t >= cfg.settle_time) {
                r.set_sum[i] += xt[i];
                r.set_sq[i] += xt[i] * xt[i];
            }
        }
        if (t >= cfg.settle_time) r.set_count += 1;
        if (keep_path) {
            r.x.insert(r.x.end(), x.begin(), x.end());
            r.xhat.insert(r.xhat.end(), xhat.begin(), xhat.end());
            r.xhat_open.insert(r.xhat_open.end(), xo.begin(), xo.end());
            r.y.insert(r.y.end(), y.begin(), y.end());
        }
        // eq. (19): the DNN filter (gain (8), oracle or measured) through the adapter of src/filters;
        // a diverged filter stays diverged: its estimate is frozen at the last finite value
        if (r.diverged_at < 0 && filter.step(FilterInput{y.data(), t, s, x.data()}) == FILTER_DIVERGED)
            r.diverged_at = t;
        if (r.diverged_at >= 0) r.num = INFINITY;
        // eq. (18) with the real v
        for (int i = 0; i < n; ++i) {
            double bv = 0;
            for (int j = 0; j < nv; ++j) bv += B[i * nv + j] * v[j];
            x[i] += cfg.dt * (a_x[i] + bv);
            xo[i] += cfg.dt * a_o[i];
        }
    }
    return r;
}

void mean_std(std::vector<double>* mean, std::vector<double>* sd, const std::vector<double>& sum,
              const std::vector<double>& sq, double count) {
    mean->resize(sum.size());
    sd->resize(sum.size());
    for (std::size_t i = 0; i < sum.size(); ++i) {
        (*mean)[i] = sum[i] / count;
        (*sd)[i] = std::sqrt(std::max(0.0, sq[i] / count - (*mean)[i] * (*mean)[i]));
    }
}

}  // namespace

OperateSummary operate_run(const RunConfig& cfg, FrozenNetwork& network, const std::string& network_path,
                           const OperateOptions& opt) {
    HINF_CHECK(network.step_config().head.n == cfg.n,
               "network '" + network_path + "' was trained for " + std::to_string(network.step_config().head.n) +
                   " states, the config's system has " + std::to_string(cfg.n) + " (use the matching config)");
    auto t0 = std::chrono::steady_clock::now();
    OperateSummary sum;
    sum.mode = opt.mode.empty() ? cfg.mode : opt.mode;
    HINF_CHECK(sum.mode == "oracle" || sum.mode == "measured",
               "--mode '" + sum.mode + "' is not one of: oracle, measured");
    sum.runs = opt.runs > 0 ? opt.runs : cfg.runs;
    const bool measured = sum.mode == "measured";
    const double tf = opt.until >= 0 ? std::min(opt.until, cfg.t_final) : cfg.t_final;
    const std::int64_t steps = static_cast<std::int64_t>(std::llround(tf / cfg.dt));
    const int n = cfg.n;

    std::vector<RunResult> results(static_cast<std::size_t>(sum.runs));
    Progress progress("operate", 0, sum.runs, opt.quiet);
    std::int64_t done = 0;
#pragma omp parallel
    {
        std::unique_ptr<FrozenNetwork> local = network.clone();
        FilterModel model{cfg.system.get(), cfg.dt, cfg.disturbance_std, cfg.noise_std};
        std::unique_ptr<OnlineFilter> filter =
            make_dnn_filter(model, network, *make_hinf_gain_law(cfg.rho), measured, "dnn");
#pragma omp for schedule(dynamic)
        for (std::int64_t r = 0; r < sum.runs; ++r) {
            results[r] = one_run(cfg, *local, *filter, r, steps, r == 0);
#pragma omp critical
            progress.update(++done, "runs |");
        }
    }
    // V(x~(0)) along the segment (defined for the quadratic head: p^T x~ > 0 on every ray)
    std::vector<double> xt0(n);
    for (int i = 0; i < n; ++i) xt0[i] = cfg.x0[i] - cfg.xhat0[i];
    const bool v_defined = network.step_config().head.kind == kern::HEAD_QUADRATIC;
    sum.v0 = network.value(xt0.data(), n);

    std::vector<double> ratio(sum.runs), ratio_open(sum.runs), ratio_v0(sum.runs), diverged_at(sum.runs);
    for (std::int64_t r = 0; r < sum.runs; ++r) {
        diverged_at[r] = results[r].diverged_at;
        if (diverged_at[r] >= 0) {
            ++sum.diverged_runs;
            if (sum.first_divergence < 0 || diverged_at[r] < sum.first_divergence) sum.first_divergence = diverged_at[r];
        }
    }
    std::vector<double> es(n, 0), eq(n, 0), eso(n, 0), eqo(n, 0), ss(n, 0), sq(n, 0);
    double set_count = 0, hji_v = 0, hji_n = 0;
    for (std::int64_t r = 0; r < sum.runs; ++r) {
        const RunResult& R = results[r];
        ratio[r] = R.num / R.den;
        ratio_open[r] = R.num_open / R.den;
        ratio_v0[r] = (R.num - sum.v0) / R.den;
        sum.attenuation_ratio += ratio[r] / double(sum.runs);
        sum.attenuation_ratio_open_loop += ratio_open[r] / double(sum.runs);
        sum.attenuation_ratio_minus_v0 += ratio_v0[r] / double(sum.runs);
        for (int i = 0; i < n; ++i) {
            es[i] += R.err_sum[i];
            eq[i] += R.err_sq[i];
            eso[i] += R.err_sum_open[i];
            eqo[i] += R.err_sq_open[i];
            ss[i] += R.set_sum[i];
            sq[i] += R.set_sq[i];
        }
        set_count += R.set_count;
        hji_v += R.hji_violations;
        hji_n += R.hji_steps;
    }
    if (!v_defined) sum.attenuation_ratio_minus_v0 = NAN;
    const double count = double(steps) * double(sum.runs);
    mean_std(&sum.error_mean, &sum.error_std, es, eq, count);
    mean_std(&sum.error_mean_open_loop, &sum.error_std_open_loop, eso, eqo, count);
    sum.online_hji_violation_fraction = hji_n > 0 ? hji_v / hji_n : 0.0;
    if (set_count > 0) mean_std(&sum.error_mean_settled, &sum.error_std_settled, ss, sq, set_count);
    else sum.error_mean_settled = sum.error_std_settled = std::vector<double>(n, NAN);
    for (int i : state_unit_group(*cfg.system, 0)) {  // the states of the first state's unit
        sum.rmse_position += eq[i] / count;
        sum.rmse_position_open_loop += eqo[i] / count;
    }
    sum.rmse_position = std::sqrt(sum.rmse_position);
    sum.rmse_position_open_loop = std::sqrt(sum.rmse_position_open_loop);
    sum.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

    std::filesystem::create_directories(opt.out_dir);
    const std::string path = opt.out_dir + "/operate.h5";
    h5::Handle f = h5::create_file(path + ".tmp");
    hid_t root = f.get();
    h5::set_attr(root, "format", "hinf-operate");
    h5::set_attr(root, "mode", sum.mode);
    h5::set_attr(root, "network", network_path);
    h5::set_attr(root, "filter_type", cfg.type);
    h5::set_attr(root, "variant", cfg.variant);
    h5::set_attr(root, "runs", sum.runs);
    h5::set_attr(root, "t_final", tf);
    h5::set_attr(root, "attenuation_ratio", sum.attenuation_ratio);
    h5::set_attr(root, "attenuation_ratio_open_loop", sum.attenuation_ratio_open_loop);
    h5::set_attr(root, "attenuation_ratio_minus_v0", sum.attenuation_ratio_minus_v0);
    h5::set_attr(root, "v0", sum.v0);
    h5::set_attr(root, "diverged_runs", sum.diverged_runs);
    h5::set_attr(root, "first_divergence_time", sum.first_divergence);
    h5::set_attr(root, "v0_defined", std::int64_t(v_defined ? 1 : 0));
    h5::set_attr(root, "error_mean", sum.error_mean);
    h5::set_attr(root, "error_std", sum.error_std);
    h5::set_attr(root, "settle_time", cfg.settle_time);
    h5::set_attr(root, "online_hji_violation_fraction", sum.online_hji_violation_fraction);
    h5::set_attr(root, "error_mean_settled", sum.error_mean_settled);
    h5::set_attr(root, "error_std_settled", sum.error_std_settled);
    h5::set_attr(root, "error_mean_open_loop", sum.error_mean_open_loop);
    h5::set_attr(root, "error_std_open_loop", sum.error_std_open_loop);
    h5::set_attr(root, "rmse_position", sum.rmse_position);
    h5::set_attr(root, "rmse_position_open_loop", sum.rmse_position_open_loop);
    h5::set_attr(root, "meaning",
                 "attenuation_ratio = int_0^T x~^T Q x~ dt / int_0^T (v^T v + n^T n) dt, mean over runs (seed 000 "
                 "Section IV); _open_loop: the same noise with the gain set to zero; _minus_v0: numerator minus "
                 "V(x~(0)); error_mean/std: per state, over time and runs, of x - x^; _settled: over t >= settle_time only (mode says whether the "
                 "filter used the true state: oracle, or only measurements: measured)");
    h5::write_string(root, "config", cfg.doc.text(), "the effective TOML config");
    h5::write_doubles(root, "attenuation_ratio_per_run", ratio.data(), {hsize_t(sum.runs)}, "1", "per Monte Carlo run");
    h5::write_doubles(root, "diverged_at", diverged_at.data(), {hsize_t(sum.runs)}, "s",
                      "time the estimate became non-finite or left |x^| < 1e12 (-1: never); from then on it is frozen");
    h5::write_doubles(root, "attenuation_ratio_open_loop_per_run", ratio_open.data(), {hsize_t(sum.runs)}, "1",
                      "per Monte Carlo run, gain set to zero");
    std::vector<double> tt(steps);
    for (std::int64_t s = 0; s < steps; ++s) tt[s] = double(s) * cfg.dt;
    h5::write_doubles(root, "t", tt.data(), {hsize_t(steps)}, "s", "time");
    const RunResult& R0 = results[0];
    h5::write_doubles(root, "x", R0.x.data(), {hsize_t(steps), hsize_t(n)}, "state units", "true state, run 0");
    h5::write_doubles(root, "xhat", R0.xhat.data(), {hsize_t(steps), hsize_t(n)}, "state units",
                      "DNN filter estimate, run 0");
    h5::write_doubles(root, "y", R0.y.data(), {hsize_t(steps), hsize_t(cfg.m)}, "output units",
                      "measurements y(t_k) = C(x(t_k)) + n_k fed to the filter, run 0 (input for `hinf filter`)");
    h5::write_doubles(root, "xhat_open_loop", R0.xhat_open.data(), {hsize_t(steps), hsize_t(n)}, "state units",
                      "open-loop predictor, run 0");
    f.reset();
    std::filesystem::rename(path + ".tmp", path);
    return sum;
}

}  // namespace hinf
