// Monte Carlo comparison of on-line filters: one truth + measurement stream per run (Philox keyed by
// (online seed, run, step), exactly the draws of eval/operate.cpp), fed identically to every filter.
#include "eval/compare.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <omp.h>

#include "hinf/error.hpp"
#include "hinf/h5.hpp"
#include "io/progress.hpp"
#include "random.hpp"
#include "filters/gain_law.hpp"

namespace hinf {

std::uint64_t compare_hash(std::uint64_t h, const void* data, std::size_t bytes) {
    const unsigned char* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < bytes; ++i) {
        h ^= p[i];
        h *= 1099511628211ull;
    }
    return h;
}

std::vector<std::string> compare_scenario_names() {
    return {"nominal",     "cov_small",   "cov_large", "v_cov_small", "v_cov_large",
            "n_cov_small", "n_cov_large", "student_t", "bias",        "energy_pulse"};
}

CompareScenario compare_scenario(const std::string& name) {
    CompareScenario s;
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
        for (const auto& n : compare_scenario_names()) all += (all.empty() ? "" : ", ") + n;
        HINF_FAIL("--scenario '" + name + "' is not one of: " + all);
    }
    return s;
}

namespace {

struct Truth {
    std::vector<double> x, y;  // [steps x n], [steps x m]
    std::vector<double> energy;  // [steps] v'v + n'n
};

// Euler truth of eq. (18) with the draws of operate.cpp; scenarios change n or v (compare.hpp).
Truth simulate_truth(const RunConfig& cfg, const CompareScenario& sc, std::int64_t run, std::int64_t steps) {
    const System& sys = *cfg.system;
    const int n = cfg.n, nv = cfg.nv, m = cfg.m;
    Truth tr;
    tr.x.resize(steps * n);
    tr.y.resize(steps * m);
    tr.energy.resize(steps);
    std::vector<double> x = cfg.x0, noise(nv + m), a(n), B(n * nv), c(m), chi(3 * m);
    const double T = double(steps) * cfg.dt, pulse = cfg.disturbance_std * std::sqrt(T / 5.0);
    for (std::int64_t s = 0; s < steps; ++s) {
        const double t = double(s) * cfg.dt;
        kern::rng_normal(noise.data(), nv + m, cfg.online_seed, kern::RNG_STREAM_NOISE, std::uint64_t(run),
                         std::uint64_t(s));
        double* v = noise.data();
        double* nn = noise.data() + nv;
        for (int j = 0; j < nv; ++j) v[j] *= cfg.disturbance_std;
        if (sc.energy_pulse)
            for (int j = 0; j < nv; ++j) v[j] = (t >= 20.0 && t < 25.0) ? pulse : 0.0;
        if (sc.student_t) {
            // t_3 = z / sqrt(chi2_3 / 3) has variance 3: scaled by 1/sqrt(3) to unit variance
            kern::rng_normal(chi.data(), 3 * m, cfg.online_seed, kern::RNG_STREAM_HEAVY_TAIL, std::uint64_t(run),
                             std::uint64_t(s));
            for (int j = 0; j < m; ++j) {
                const double c2 = chi[3 * j] * chi[3 * j] + chi[3 * j + 1] * chi[3 * j + 1] + chi[3 * j + 2] * chi[3 * j + 2];
                nn[j] = nn[j] / std::sqrt(c2 / 3.0) / std::sqrt(3.0);
            }
        }
        for (int j = 0; j < m; ++j) nn[j] = (nn[j] + sc.noise_bias) * cfg.noise_std;
        sys.drift(a.data(), x.data(), t, 1);
        sys.disturbance_gain(B.data(), x.data(), t, 1);
        sys.measurement(c.data(), x.data(), t, 1);
        double e = 0;
        for (int j = 0; j < nv; ++j) e += v[j] * v[j];
        for (int j = 0; j < m; ++j) {
            tr.y[s * m + j] = c[j] + nn[j];
            e += nn[j] * nn[j];
        }
        tr.energy[s] = e;
        std::copy(x.begin(), x.end(), tr.x.begin() + s * n);
        for (int i = 0; i < n; ++i) {
            double bv = 0;
            for (int j = 0; j < nv; ++j) bv += B[i * nv + j] * v[j];
            x[i] += cfg.dt * (a[i] + bv);
        }
    }
    return tr;
}

struct FilterRun {
    double diverged_at = -1;
    std::vector<double> mean, sd, mean_settled, sd_settled;  // [n] within the run
    double sq_pos = 0, sq_vel = 0, sq_pos_settled = 0, sq_vel_settled = 0;  // mean over steps of |e|^2
    double ratio = 0;
    double seconds = 0;
    std::uint64_t hash = compare_hash_start;
    std::vector<double> err_sub;  // [sub x n] error every `stride` steps
    std::vector<double> xhat;     // run 0 only: [steps x n]
};

FilterRun run_filter(const RunConfig& cfg, OnlineFilter& f, const Truth& tr, std::uint64_t run, std::int64_t steps,
                     std::int64_t stride, bool keep_path) {
    const int n = cfg.n, m = cfg.m;
    // "position" and "velocity": the states of the first and second unit (x, y, z and vx, vy, vz for the missile)
    const std::vector<int> pos = state_unit_group(*cfg.system, 0), vel = state_unit_group(*cfg.system, 1);
    FilterRun r;
    std::vector<double> s1(n, 0), s2(n, 0), t1(n, 0), t2(n, 0), e(n);
    double num = 0, den = 0, settled = 0;
    FilterStart start;
    start.xhat0 = cfg.xhat0;
    start.P0.assign(n * n, 0.0);
    for (int i = 0; i < n; ++i) {
        // the initial estimate's error variance: the actual squared initial error (floor 1), the same for all
        const double d = cfg.x0[i] - cfg.xhat0[i];
        start.P0[i * n + i] = std::max(d * d, 1.0);
    }
    start.seed = cfg.online_seed;
    start.run = run;
    f.reset(start);
    double seconds = 0;
    for (std::int64_t s = 0; s < steps; ++s) {
        const double t = double(s) * cfg.dt;
        const double* x = tr.x.data() + s * n;
        const double* xh = f.estimate();
        for (int i = 0; i < n; ++i) e[i] = x[i] - xh[i];
        if (keep_path) r.xhat.insert(r.xhat.end(), xh, xh + n);
        if (s % stride == 0) r.err_sub.insert(r.err_sub.end(), e.begin(), e.end());
        num += cfg.dt * quadratic_form(cfg.Q.data(), e.data(), n);
        den += cfg.dt * tr.energy[s];
        double pp = 0, vv = 0;
        for (int i : pos) pp += e[i] * e[i];
        for (int i : vel) vv += e[i] * e[i];
        r.sq_pos += pp;
        r.sq_vel += vv;
        for (int i = 0; i < n; ++i) {
            s1[i] += e[i];
            s2[i] += e[i] * e[i];
        }
        if (t >= cfg.settle_time) {
            settled += 1;
            r.sq_pos_settled += pp;
            r.sq_vel_settled += vv;
            for (int i = 0; i < n; ++i) {
                t1[i] += e[i];
                t2[i] += e[i] * e[i];
            }
        }
        const double* y = tr.y.data() + s * m;
        r.hash = compare_hash(r.hash, y, sizeof(double) * m);  // the stream offered to this filter
        if (r.diverged_at >= 0) continue;  // frozen at its last finite estimate, counted as diverged
        auto c0 = std::chrono::steady_clock::now();
        FilterStatus st = f.step(FilterInput{y, t, s, x});
        seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count();
        if (st != FILTER_OK) r.diverged_at = t;
    }
    r.seconds = seconds;
    r.ratio = num / den;
    const double cnt = double(steps);
    r.sq_pos /= cnt;
    r.sq_vel /= cnt;
    r.sq_pos_settled = settled > 0 ? r.sq_pos_settled / settled : NAN;
    r.sq_vel_settled = settled > 0 ? r.sq_vel_settled / settled : NAN;
    r.mean.resize(n);
    r.sd.resize(n);
    r.mean_settled.resize(n);
    r.sd_settled.resize(n);
    for (int i = 0; i < n; ++i) {
        r.mean[i] = s1[i] / cnt;
        r.sd[i] = std::sqrt(std::max(0.0, s2[i] / cnt - r.mean[i] * r.mean[i]));
        r.mean_settled[i] = settled > 0 ? t1[i] / settled : NAN;
        r.sd_settled[i] = settled > 0 ? std::sqrt(std::max(0.0, t2[i] / settled - r.mean_settled[i] * r.mean_settled[i])) : NAN;
    }
    return r;
}

// mean over the kept runs and the 95% half-width 1.96 sd / sqrt(count) (0 with one run)
void mean_ci(double* mean, double* ci, const std::vector<double>& v) {
    const double k = double(v.size());
    if (v.empty()) {
        *mean = *ci = NAN;
        return;
    }
    double s = 0;
    for (double a : v) s += a;
    *mean = s / k;
    double q = 0;
    for (double a : v) q += (a - *mean) * (a - *mean);
    *ci = v.size() > 1 ? 1.96 * std::sqrt(q / (k - 1)) / std::sqrt(k) : 0.0;
}

std::string hex(std::uint64_t h) {
    char b[17];
    std::snprintf(b, sizeof b, "%016llx", static_cast<unsigned long long>(h));
    return b;
}

}  // namespace

CompareSummary compare_run(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                           const CompareOptions& opt) {
    HINF_CHECK(!filters.empty(), "compare: no filters to compare (--filters)");
    HINF_CHECK(opt.runs >= 1, "compare: --runs must be >= 1");
    auto t0 = std::chrono::steady_clock::now();
    const int n = cfg.n, F = static_cast<int>(filters.size());
    const double tf = opt.until >= 0 ? std::min(opt.until, cfg.t_final) : cfg.t_final;
    const std::int64_t steps = static_cast<std::int64_t>(std::llround(tf / cfg.dt));
    HINF_CHECK(steps >= 1, "compare: --until " + std::to_string(tf) + " s is shorter than one time step");
    const std::int64_t stride = std::max<std::int64_t>(1, (steps + 999) / 1000), nsub = (steps + stride - 1) / stride;
    const std::int64_t R = opt.runs;

    std::vector<std::vector<FilterRun>> res(F, std::vector<FilterRun>(R));
    std::vector<std::uint64_t> truth_hash(R);
    Truth truth0;
    Progress progress("compare", 0, R, opt.quiet);
    std::int64_t done = 0;
#pragma omp parallel
    {
        std::vector<std::unique_ptr<OnlineFilter>> local;
        for (const OnlineFilter* f : filters) local.push_back(f->clone());
#pragma omp for schedule(dynamic)
        for (std::int64_t r = 0; r < R; ++r) {
            Truth tr = simulate_truth(cfg, opt.scenario, r, steps);
            truth_hash[r] = compare_hash(compare_hash_start, tr.y.data(), sizeof(double) * tr.y.size());
            for (int k = 0; k < F; ++k) res[k][r] = run_filter(cfg, *local[k], tr, std::uint64_t(r), steps, stride, r == 0);
            if (r == 0) truth0 = std::move(tr);
#pragma omp critical
            progress.update(++done, "runs |");
        }
    }
    CompareSummary sum;
    sum.scenario = opt.scenario.name;
    sum.runs = R;
    sum.steps = steps;
    sum.truth_stream_hash = compare_hash_start;
    for (std::int64_t r = 0; r < R; ++r) sum.truth_stream_hash = compare_hash(sum.truth_stream_hash, &truth_hash[r], 8);

    std::filesystem::create_directories(opt.out_dir);
    const std::string path = opt.out_dir + "/compare.h5";
    h5::Handle file = h5::create_file(path + ".tmp");
    hid_t root = file.get();
    std::vector<double> tt(steps), tsub(nsub);
    for (std::int64_t s = 0; s < steps; ++s) tt[s] = double(s) * cfg.dt;
    for (std::int64_t s = 0; s < nsub; ++s) tsub[s] = double(s * stride) * cfg.dt;

    for (int k = 0; k < F; ++k) {
        CompareFilterResult fr;
        fr.name = filters[k]->name();
        fr.mode = filters[k]->uses_true_state() ? "oracle" : "measured";
        std::vector<FilterRun>& runs = res[k];
        std::vector<double> ratio_all(R), diverged_at(R);
        double secs = 0;
        fr.stream_hash = compare_hash_start;
        std::vector<std::int64_t> kept;
        for (std::int64_t r = 0; r < R; ++r) {
            diverged_at[r] = runs[r].diverged_at;
            ratio_all[r] = runs[r].diverged_at >= 0 ? INFINITY : runs[r].ratio;
            secs += runs[r].seconds;
            fr.stream_hash = compare_hash(fr.stream_hash, &runs[r].hash, 8);
            if (runs[r].diverged_at >= 0) ++fr.diverged_runs;
            else kept.push_back(r);
        }
        fr.us_per_step = 1e6 * secs / double(R * steps);
        auto over_kept = [&](auto get) {
            std::vector<double> v;
            for (std::int64_t r : kept) v.push_back(get(runs[r]));
            return v;
        };
        for (auto* vec : {&fr.mean, &fr.mean_ci, &fr.std, &fr.std_ci, &fr.mean_settled, &fr.mean_settled_ci,
                          &fr.std_settled, &fr.std_settled_ci})
            vec->resize(n);
        for (int i = 0; i < n; ++i) {
            mean_ci(&fr.mean[i], &fr.mean_ci[i], over_kept([i](const FilterRun& q) { return q.mean[i]; }));
            mean_ci(&fr.std[i], &fr.std_ci[i], over_kept([i](const FilterRun& q) { return q.sd[i]; }));
            mean_ci(&fr.mean_settled[i], &fr.mean_settled_ci[i],
                    over_kept([i](const FilterRun& q) { return q.mean_settled[i]; }));
            mean_ci(&fr.std_settled[i], &fr.std_settled_ci[i],
                    over_kept([i](const FilterRun& q) { return q.sd_settled[i]; }));
        }
        double ci;
        mean_ci(&fr.rmse_position, &ci, over_kept([](const FilterRun& q) { return q.sq_pos; }));
        fr.rmse_position = std::sqrt(fr.rmse_position);
        mean_ci(&fr.rmse_velocity, &ci, over_kept([](const FilterRun& q) { return q.sq_vel; }));
        fr.rmse_velocity = std::sqrt(fr.rmse_velocity);
        mean_ci(&fr.rmse_position_settled, &ci, over_kept([](const FilterRun& q) { return q.sq_pos_settled; }));
        fr.rmse_position_settled = std::sqrt(fr.rmse_position_settled);
        mean_ci(&fr.rmse_velocity_settled, &ci, over_kept([](const FilterRun& q) { return q.sq_vel_settled; }));
        fr.rmse_velocity_settled = std::sqrt(fr.rmse_velocity_settled);
        mean_ci(&fr.attenuation_ratio, &fr.attenuation_ratio_ci, over_kept([](const FilterRun& q) { return q.ratio; }));

        // error over time across the kept runs (every `stride` steps), for the +-sigma band plots
        std::vector<double> emt(nsub * n, 0.0), est(nsub * n, 0.0);
        for (std::int64_t j = 0; j < nsub * n; ++j) {
            double s1 = 0, s2 = 0;
            for (std::int64_t r : kept) {
                s1 += runs[r].err_sub[j];
                s2 += runs[r].err_sub[j] * runs[r].err_sub[j];
            }
            const double c = double(kept.size());
            emt[j] = c > 0 ? s1 / c : NAN;
            est[j] = c > 0 ? std::sqrt(std::max(0.0, s2 / c - emt[j] * emt[j])) : NAN;
        }

        h5::Handle g = h5::create_group(root, fr.name);
        hid_t gid = g.get();
        h5::set_attr(gid, "mode", fr.mode);
        h5::set_attr(gid, "diverged_runs", fr.diverged_runs);
        h5::set_attr(gid, "kept_runs", std::int64_t(kept.size()));
        h5::set_attr(gid, "measurement_stream_hash", hex(fr.stream_hash));
        h5::set_attr(gid, "rmse_position", fr.rmse_position);
        h5::set_attr(gid, "rmse_velocity", fr.rmse_velocity);
        h5::set_attr(gid, "rmse_position_settled", fr.rmse_position_settled);
        h5::set_attr(gid, "rmse_velocity_settled", fr.rmse_velocity_settled);
        h5::set_attr(gid, "attenuation_ratio", fr.attenuation_ratio);
        h5::set_attr(gid, "attenuation_ratio_ci95", fr.attenuation_ratio_ci);
        h5::set_attr(gid, "us_per_step", fr.us_per_step);
        const hsize_t hn = hsize_t(n);
        h5::write_doubles(gid, "error_mean", fr.mean.data(), {hn}, "state units",
                          "per state: mean over time of x - x^ within a run, averaged over the kept runs");
        h5::write_doubles(gid, "error_mean_ci95", fr.mean_ci.data(), {hn}, "state units", "95% half-width over runs");
        h5::write_doubles(gid, "error_std", fr.std.data(), {hn}, "state units",
                          "per state: std over time of x - x^ within a run, averaged over the kept runs");
        h5::write_doubles(gid, "error_std_ci95", fr.std_ci.data(), {hn}, "state units", "95% half-width over runs");
        h5::write_doubles(gid, "error_mean_settled", fr.mean_settled.data(), {hn}, "state units", "as error_mean, t >= settle_time");
        h5::write_doubles(gid, "error_mean_settled_ci95", fr.mean_settled_ci.data(), {hn}, "state units", "95% half-width");
        h5::write_doubles(gid, "error_std_settled", fr.std_settled.data(), {hn}, "state units", "as error_std, t >= settle_time");
        h5::write_doubles(gid, "error_std_settled_ci95", fr.std_settled_ci.data(), {hn}, "state units", "95% half-width");
        h5::write_doubles(gid, "attenuation_ratio_per_run", ratio_all.data(), {hsize_t(R)}, "1",
                          "int x~'Qx~ dt / int (v'v + n'n) dt per run (inf: diverged)");
        h5::write_doubles(gid, "diverged_at", diverged_at.data(), {hsize_t(R)}, "s", "divergence time per run (-1: never)");
        h5::write_doubles(gid, "error_mean_t", emt.data(), {hsize_t(nsub), hn}, "state units",
                          "mean over kept runs of x - x^ at t_sub");
        h5::write_doubles(gid, "error_std_t", est.data(), {hsize_t(nsub), hn}, "state units",
                          "std over kept runs of x - x^ at t_sub");
        h5::write_doubles(gid, "xhat", runs[0].xhat.data(), {hsize_t(steps), hn}, "state units", "estimate, run 0");
        sum.filters.push_back(fr);
    }
    std::string names;
    for (const auto& fr : sum.filters) names += (names.empty() ? "" : ",") + fr.name;
    h5::set_attr(root, "format", "hinf-compare");
    h5::set_attr(root, "scenario", sum.scenario);
    h5::set_attr(root, "filters", names);
    h5::set_attr(root, "runs", R);
    h5::set_attr(root, "t_final", tf);
    h5::set_attr(root, "settle_time", cfg.settle_time);
    h5::set_attr(root, "truth_stream_hash", hex(sum.truth_stream_hash));
    std::string sn;
    for (const auto& s : cfg.system->state_names()) sn += (sn.empty() ? "" : ",") + s;
    h5::set_attr(root, "state_names", sn);
    h5::set_attr(root, "meaning",
                 "one group per filter; every filter saw the same truth and measurements (measurement_stream_hash "
                 "== truth_stream_hash); errors are x - x^ of the one-step prediction; statistics over the runs that "
                 "did not diverge (diverged_runs says how many did); mode: oracle = the filter read the true state");
    h5::write_string(root, "config", cfg.doc.text(), "the effective TOML config");
    h5::write_doubles(root, "t", tt.data(), {hsize_t(steps)}, "s", "time");
    h5::write_doubles(root, "t_sub", tsub.data(), {hsize_t(nsub)}, "s", "times of error_mean_t / error_std_t");
    h5::write_doubles(root, "x", truth0.x.data(), {hsize_t(steps), hsize_t(n)}, "state units", "true state, run 0");
    h5::write_doubles(root, "y", truth0.y.data(), {hsize_t(steps), hsize_t(cfg.m)}, "output units", "measurements, run 0");
    file.reset();
    std::filesystem::rename(path + ".tmp", path);

    // CSV beside it: one row per filter
    std::ofstream csv(opt.out_dir + "/compare.csv");
    const auto st = cfg.system->state_names();
    csv << "scenario,filter,mode,runs,diverged_runs";
    for (int i = 0; i < n; ++i)
        csv << ',' << st[i] << "_mean," << st[i] << "_mean_ci95," << st[i] << "_std," << st[i] << "_std_ci95,"
            << st[i] << "_mean_settled," << st[i] << "_mean_settled_ci95," << st[i] << "_std_settled," << st[i]
            << "_std_settled_ci95";
    csv << ",rmse_position,rmse_velocity,rmse_position_settled,rmse_velocity_settled,attenuation_ratio,"
           "attenuation_ratio_ci95,us_per_step\n";
    csv.precision(10);
    for (const auto& fr : sum.filters) {
        csv << sum.scenario << ',' << fr.name << ',' << fr.mode << ',' << R << ',' << fr.diverged_runs;
        for (int i = 0; i < n; ++i)
            csv << ',' << fr.mean[i] << ',' << fr.mean_ci[i] << ',' << fr.std[i] << ',' << fr.std_ci[i] << ','
                << fr.mean_settled[i] << ',' << fr.mean_settled_ci[i] << ',' << fr.std_settled[i] << ','
                << fr.std_settled_ci[i];
        csv << ',' << fr.rmse_position << ',' << fr.rmse_velocity << ',' << fr.rmse_position_settled << ','
            << fr.rmse_velocity_settled << ',' << fr.attenuation_ratio << ',' << fr.attenuation_ratio_ci << ','
            << fr.us_per_step << '\n';
    }
    sum.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return sum;
}

}  // namespace hinf
