// Monte Carlo comparison of on-line filters: the engine's runs (one truth per run, fed identically to every
// filter) reduced to the comparison table, compare.h5 and compare.csv.
#include "eval/compare.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "hinf/config.hpp"
#include "hinf/error.hpp"
#include "hinf/h5.hpp"
#include "io/atomic.hpp"
#include "io/measurements.hpp"
#include "io/run_lock.hpp"
#include "eval/engine.hpp"
#include "eval/filter_recorded.hpp"

namespace hinf {

namespace {

// One run of one filter reduced to what the table reports: per-state mean and std over time, mean squared errors
// per unit group, the attenuation ratio.
struct FilterRun {
    double diverged_at = -1;
    std::vector<double> mean, sd, mean_settled, sd_settled;  // [n] within the run
    double sq_pos = 0, sq_vel = 0, sq_pos_settled = 0, sq_vel_settled = 0;  // mean over steps of |e|^2
    double ratio = 0;
    double mse = 0, mse_filtered = NAN;  // mean over states and steps of e^2 (prediction, filtered estimate)
};

FilterRun reduce_run(const FilterRunStats& s, std::int64_t steps, int n) {
    FilterRun r;
    r.diverged_at = s.diverged_at;
    r.ratio = s.error_energy / s.signal_energy;
    const double cnt = double(steps), settled = s.settled_steps;
    r.sq_pos = s.sq_pos / cnt;
    r.sq_vel = s.sq_vel / cnt;
    r.sq_pos_settled = settled > 0 ? s.sq_pos_settled / settled : NAN;
    r.sq_vel_settled = settled > 0 ? s.sq_vel_settled / settled : NAN;
    double sq = 0, sqf = 0;
    for (int i = 0; i < n; ++i) sq += s.err_sq[i];
    r.mse = sq / (cnt * n);
    if (!s.err_sq_filtered.empty()) {
        for (int i = 0; i < n; ++i) sqf += s.err_sq_filtered[i];
        r.mse_filtered = sqf / (cnt * n);
    }
    r.mean.resize(n);
    r.sd.resize(n);
    r.mean_settled.resize(n);
    r.sd_settled.resize(n);
    for (int i = 0; i < n; ++i) {
        r.mean[i] = s.err_sum[i] / cnt;
        r.sd[i] = std::sqrt(std::max(0.0, s.err_sq[i] / cnt - r.mean[i] * r.mean[i]));
        r.mean_settled[i] = settled > 0 ? s.err_sum_settled[i] / settled : NAN;
        r.sd_settled[i] = settled > 0 ? std::sqrt(std::max(0.0, s.err_sq_settled[i] / settled -
                                                                      r.mean_settled[i] * r.mean_settled[i]))
                                      : NAN;
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

double q_weighted_ms(const RunConfig& cfg, const double* mean, const double* sd) {
    double q = 0;
    for (int j = 0; j < cfg.n; ++j) q += cfg.Q[std::size_t(j) * cfg.n + j] * (mean[j] * mean[j] + sd[j] * sd[j]);
    return q;
}

SettleCheck settle_check(const std::vector<double>& t, const std::vector<double>& ms, double t0) {
    SettleCheck c;
    const std::size_t N = std::min(t.size(), ms.size());
    std::size_t first = 0;
    while (first < N && t[first] < t0) ++first;
    if (N - first >= 8) {
        const std::size_t mid = first + (N - first) / 2;
        double a = 0, b = 0;
        for (std::size_t k = first; k < mid; ++k) a += ms[k];
        for (std::size_t k = mid; k < N; ++k) b += ms[k];
        a /= double(mid - first);
        b /= double(N - mid);
        if (b > 0) c.halves = a / b;
    }
    if (N >= 40) {
        constexpr int kBlocks = 20, kLast = 5;
        std::vector<double> block(kBlocks, 0.0);
        auto begin = [N](int i) { return std::size_t(i) * N / kBlocks; };
        for (int i = 0; i < kBlocks; ++i) {
            for (std::size_t k = begin(i); k < begin(i + 1); ++k) block[i] += ms[k];
            block[i] /= double(begin(i + 1) - begin(i));
        }
        double level = 0;
        for (int i = kBlocks - kLast; i < kBlocks; ++i) level += block[i] / kLast;
        int from = 0;
        for (int i = 0; i < kBlocks; ++i)
            if (!(block[i] <= kSettleFactor * level)) from = i + 1;  // NaN counts as not settled
        if (from < kBlocks) c.settled_after = t[begin(from)];
    }
    return c;
}

bool settle_time_named(const RunConfig& cfg) { return ConfigSection(cfg.doc, "online").has("settle_time"); }

std::string settle_note(const RunConfig& cfg, const CompareSummary& s, const char* who) {
    if (settle_time_named(cfg)) return "";
    const CompareFilterResult* ref = nullptr;
    for (const char* name : {"ekf", "ukf", "pf"})
        for (const auto& fr : s.filters)
            if (!ref && fr.name == name) ref = &fr;
    if (!ref || !(ref->settle_halves > kSettleFactor)) return "";
    const bool known = std::isfinite(ref->settled_after);
    const std::string from = known ? ", and it stays within " + format_g(kSettleFactor) +
                                         " times its level over the run's last quarter from t = " +
                                         format_g(ref->settled_after) + " s"
                                   : "";
    char buf[900];
    std::snprintf(buf, sizeof buf,
                  "%s: note: the %s's error is still falling after t = %g s, where the default settled window starts "
                  "(the config names no settle_time): over the first half of the settled window its mean square error "
                  "is %.3g times the second half's%s. The settled figures hold that transient; name the time this "
                  "system settles in, e.g. --set online.settle_time=%.3g (docs/compare.md, \"Settled\")",
                  who, ref->name == "pf" ? "PF" : ref->name == "ukf" ? "UKF" : "EKF", cfg.settle_time,
                  ref->settle_halves, from.c_str(), known ? ref->settled_after : cfg.t_final / 2);
    return buf;
}

CompareSummary compare_run(const RunConfig& cfg, const std::vector<const OnlineFilter*>& filters,
                           const CompareOptions& opt) {
    auto t0 = std::chrono::steady_clock::now();
    const int n = cfg.n, F = static_cast<int>(filters.size());
    const std::int64_t steps = cfg.steps_until(opt.until);
    const double tf = cfg.final_time(opt.until);
    const std::int64_t stride = std::max<std::int64_t>(1, (steps + 999) / 1000), nsub = (steps + stride - 1) / stride;
    const std::int64_t R = opt.runs;

    EngineOptions eo;
    eo.runs = R;
    eo.steps = steps;
    eo.stride = stride;
    eo.scenario = opt.scenario;
    eo.label = "compare";
    eo.quiet = opt.quiet;
    // before the runs, not only before anything there is opened for writing: a second `hinf compare` into the same
    // directory is told at once, not after the first one's runs
    const RunDirLock lock(opt.out_dir, "hinf compare");
    EngineResult er = engine_run(cfg, filters, eo);
    const TruthRun& truth0 = er.truth0;
    CompareSummary sum;
    sum.scenario = opt.scenario.name;
    sum.runs = R;
    sum.steps = steps;
    sum.rank_seconds = er.rank_seconds;
    sum.truth_stream_hash = hash_start;
    for (std::int64_t r = 0; r < R; ++r) sum.truth_stream_hash = hash_bytes(sum.truth_stream_hash, &er.truth_hash[r], 8);
    // runs whose truth ran away (sim/truth.hpp) count for no filter (docs/compare.md "Divergence")
    for (std::int64_t r = 0; r < R; ++r) {
        const double e = er.truth_escaped_at[r];
        if (e < 0) continue;
        ++sum.truth_escaped_runs;
        if (sum.first_truth_escape < 0 || e < sum.first_truth_escape) sum.first_truth_escape = e;
    }
    HINF_CHECK(sum.truth_escaped_runs < R, "compare: " + truth_escape_refusal(cfg, R, "run(s)", sum.first_truth_escape));

    const std::string path = opt.out_dir + "/compare.h5";
    AtomicH5 file(path);
    hid_t root = file.get();
    const std::vector<double>& tt = er.t;
    std::vector<double> tsub(nsub);
    for (std::int64_t s = 0; s < nsub; ++s) tsub[s] = cfg.time_of(s * stride);

    for (int k = 0; k < F; ++k) {
        CompareFilterResult fr;
        fr.name = filters[k]->name();
        fr.mode = filters[k]->uses_true_state() ? "oracle" : "measured";
        std::vector<FilterRun> runs(R);
        for (std::int64_t r = 0; r < R; ++r) runs[r] = reduce_run(er.runs[k][r], steps, n);
        std::vector<double> ratio_all(R), diverged_at(R);
        double secs = 0;
        fr.stream_hash = hash_start;
        std::vector<std::int64_t> kept;
        for (std::int64_t r = 0; r < R; ++r) {
            const bool escaped = er.truth_escaped_at[r] >= 0;  // not the filter's doing: no figure of this run counts
            diverged_at[r] = escaped ? NAN : runs[r].diverged_at;
            ratio_all[r] = escaped ? NAN : runs[r].diverged_at >= 0 ? INFINITY : runs[r].ratio;
            secs += er.runs[k][r].seconds;
            fr.stream_hash = hash_bytes(fr.stream_hash, &er.runs[k][r].stream_hash, 8);
            if (escaped) continue;
            const std::vector<double>& rep = er.runs[k][r].reported;
            if (fr.report_sum.size() < rep.size()) fr.report_sum.resize(rep.size(), 0.0);
            bool any = false;
            for (std::size_t j = 0; j < rep.size(); ++j) {
                fr.report_sum[j] += rep[j];
                any = any || rep[j] != 0;
            }
            fr.report_runs += any ? 1 : 0;
            fr.notes.see(r, er.runs[k][r].note);
            if (runs[r].diverged_at >= 0) ++fr.diverged_runs;
            else kept.push_back(r);
        }
        fr.us_per_step = 1e6 * secs / double(R * steps);
        double nees_sum = 0, nees_steps = 0;
        for (std::int64_t r : kept) {
            nees_sum += er.runs[k][r].nees_sum;
            nees_steps += er.runs[k][r].nees_steps;
        }
        if (nees_steps > 0) fr.nees_per_state = nees_sum / nees_steps / double(n);
        double nis_sum = 0, nis_steps = 0;
        for (std::int64_t r : kept) {
            nis_sum += er.runs[k][r].nis_sum;
            nis_steps += er.runs[k][r].nis_steps;
        }
        if (nis_steps > 0) fr.nis_per_output = nis_sum / nis_steps / double(cfg.m);
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
        std::vector<double> mse_runs(R), msef_runs(R);
        for (std::int64_t r = 0; r < R; ++r) {
            const bool escaped = er.truth_escaped_at[r] >= 0;
            mse_runs[r] = escaped ? NAN : runs[r].mse;
            msef_runs[r] = escaped ? NAN : runs[r].mse_filtered;
        }
        mean_ci(&fr.mse, &ci, over_kept([](const FilterRun& q) { return q.mse; }));
        fr.mse_db = 10.0 * std::log10(fr.mse);
        bool has_filtered = false;  // a filter that diverged at its first step in every run never gave one
        for (std::int64_t r = 0; r < R; ++r) has_filtered = has_filtered || !er.runs[k][r].err_sq_filtered.empty();
        if (has_filtered) {
            mean_ci(&fr.mse_filtered, &ci, over_kept([](const FilterRun& q) { return q.mse_filtered; }));
            fr.mse_filtered_db = 10.0 * std::log10(fr.mse_filtered);
        }

        // error over time across the kept runs (every `stride` steps), for the +-sigma band plots
        std::vector<double> emt(nsub * n, 0.0), est(nsub * n, 0.0);
        for (std::int64_t j = 0; j < nsub * n; ++j) {
            double s1 = 0, s2 = 0;
            for (std::int64_t r : kept) {
                const double ej = er.runs[k][r].err_sub[j];
                s1 += ej;
                s2 += ej * ej;
            }
            const double c = double(kept.size());
            emt[j] = c > 0 ? s1 / c : NAN;
            est[j] = c > 0 ? std::sqrt(std::max(0.0, s2 / c - emt[j] * emt[j])) : NAN;
        }

        std::vector<double> msq(nsub);  // Q-weighted mean square over the kept runs, for the settle check
        for (std::int64_t t = 0; t < nsub; ++t) msq[t] = q_weighted_ms(cfg, emt.data() + t * n, est.data() + t * n);
        const SettleCheck sc = settle_check(tsub, msq, cfg.settle_time);
        fr.settle_halves = sc.halves;
        fr.settled_after = sc.settled_after;

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
        h5::set_attr(gid, "mse", fr.mse);
        h5::set_attr(gid, "mse_db", fr.mse_db);
        h5::set_attr(gid, "mse_filtered", fr.mse_filtered);
        h5::set_attr(gid, "mse_filtered_db", fr.mse_filtered_db);
        h5::set_attr(gid, "settle_halves", fr.settle_halves);
        h5::set_attr(gid, "settled_after", fr.settled_after);
        if (std::isfinite(fr.nees_per_state)) h5::set_attr(gid, "nees_per_state", fr.nees_per_state);
        if (std::isfinite(fr.nis_per_output)) h5::set_attr(gid, "nis_per_output", fr.nis_per_output);
        if (fr.notes.runs > 0) {  // what the figures do not say (OnlineFilter::run_note)
            h5::set_attr(gid, "note", fr.notes.first);
            h5::set_attr(gid, "note_runs", fr.notes.runs);
            h5::set_attr(gid, "note_first_run", fr.notes.first_run);
        }
        h5::write_doubles(gid, "mse_per_run", mse_runs.data(), {hsize_t(R)}, "state units^2",
                          "mean over states and steps of (x - x^_{k|k-1})^2 per run (the prediction)");
        h5::write_doubles(gid, "mse_filtered_per_run", msef_runs.data(), {hsize_t(R)}, "state units^2",
                          "mean over states and steps of (x - x^_{k|k})^2 per run (NaN: no filtered estimate)");
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
                          "int x~'Qx~ dt / int (v'v + n'n) dt per run (inf: diverged; NaN: the truth escaped)");
        h5::write_doubles(gid, "diverged_at", diverged_at.data(), {hsize_t(R)}, "s",
                          "divergence time per run (-1: never; NaN: the truth escaped, the run counts for no filter)");
        h5::write_doubles(gid, "error_mean_t", emt.data(), {hsize_t(nsub), hn}, "state units",
                          "mean over kept runs of x - x^ at t_sub");
        h5::write_doubles(gid, "error_std_t", est.data(), {hsize_t(nsub), hn}, "state units",
                          "std over kept runs of x - x^ at t_sub");
        h5::write_doubles(gid, "xhat", er.runs[k][0].xhat.data(), {hsize_t(steps), hn}, "state units", "estimate, run 0");
        sum.filters.push_back(fr);
    }
    std::string names;
    for (const auto& fr : sum.filters) names += (names.empty() ? "" : ",") + fr.name;
    h5::set_attr(root, "format", "hinf-compare");
    h5::set_attr(root, "scenario", sum.scenario);
    h5::set_attr(root, "filters", names);
    h5::set_attr(root, "runs", R);
    h5::set_attr(root, "t_final", tf);
    h5::set_attr(root, "system_time", std::string(system_time_name(*cfg.system)));
    h5::set_attr(root, "settle_time", cfg.settle_time);
    h5::set_attr(root, "truth_stream_hash", hex(sum.truth_stream_hash));
    h5::set_attr(root, "truth_escaped_runs", sum.truth_escaped_runs);
    h5::write_doubles(root, "truth_escaped_at", er.truth_escaped_at.data(), {hsize_t(R)}, "s",
                      "per run: time the true state ran away (not finite, or 1e12 times beyond every scale the config "
                      "gives it; sim/truth.hpp) or a measurement became non-finite (-1: never); such a run "
                      "counts for no filter");
    std::string sn;
    for (const auto& s : cfg.system->state_names()) sn += (sn.empty() ? "" : ",") + s;
    h5::set_attr(root, "state_names", sn);
    std::string su;  // the states' units, for axis labels (scripts/plot)
    for (const auto& u : cfg.system->state_units()) su += (su.empty() ? "" : ",") + u;
    h5::set_attr(root, "state_units", su);
    h5::set_attr(root, "meaning",
                 "one group per filter; every filter saw the same truth and measurements (measurement_stream_hash "
                 "== truth_stream_hash); errors are x - x^ of the one-step prediction (mse_filtered*: of the filtered estimate x^_{k|k}); statistics over the runs that "
                 "did not diverge (diverged_runs says how many did) and whose truth did not run away (truth_escaped_at); mode: oracle = the filter read the true state");
    h5::write_string(root, "config", cfg.doc.text(), "the effective TOML config");
    h5::write_doubles(root, "t", tt.data(), {hsize_t(steps)}, "s", "time");
    h5::write_doubles(root, "t_sub", tsub.data(), {hsize_t(nsub)}, "s", "times of error_mean_t / error_std_t");
    h5::write_doubles(root, "x", truth0.x.data(), {hsize_t(steps), hsize_t(n)}, "state units", "true state, run 0");
    std::vector<double> y_user = truth0.y;
    outputs_to_user(cfg, y_user.data(), steps);
    h5::write_doubles(root, "y", y_user.data(), {hsize_t(steps), hsize_t(cfg.m)}, "output units", "measurements, run 0");
    write_record_inputs(root, *cfg.system, tt.data(), steps);
    file.commit();

    // CSV beside it: one row per filter
    const auto st = cfg.system->state_names();
    write_text_atomic(opt.out_dir + "/compare.csv", [&](std::ostream& csv) {
    csv << "scenario,filter,mode,runs,diverged_runs";
    for (int i = 0; i < n; ++i)
        csv << ',' << st[i] << "_mean," << st[i] << "_mean_ci95," << st[i] << "_std," << st[i] << "_std_ci95,"
            << st[i] << "_mean_settled," << st[i] << "_mean_settled_ci95," << st[i] << "_std_settled," << st[i]
            << "_std_settled_ci95";
    csv << ",rmse_position,rmse_velocity,rmse_position_settled,rmse_velocity_settled,attenuation_ratio,"
           "attenuation_ratio_ci95,us_per_step,mse,mse_db,mse_filtered,mse_filtered_db,truth_escaped_runs,"
           "nees_per_state,nis_per_output\n";
    csv.precision(10);
    for (const auto& fr : sum.filters) {
        csv << sum.scenario << ',' << fr.name << ',' << fr.mode << ',' << R << ',' << fr.diverged_runs;
        for (int i = 0; i < n; ++i)
            csv << ',' << fr.mean[i] << ',' << fr.mean_ci[i] << ',' << fr.std[i] << ',' << fr.std_ci[i] << ','
                << fr.mean_settled[i] << ',' << fr.mean_settled_ci[i] << ',' << fr.std_settled[i] << ','
                << fr.std_settled_ci[i];
        csv << ',' << fr.rmse_position << ',' << fr.rmse_velocity << ',' << fr.rmse_position_settled << ','
            << fr.rmse_velocity_settled << ',' << fr.attenuation_ratio << ',' << fr.attenuation_ratio_ci << ','
            << fr.us_per_step << ',' << fr.mse << ',' << fr.mse_db << ',' << fr.mse_filtered << ','
            << fr.mse_filtered_db << ',' << sum.truth_escaped_runs << ',' << fr.nees_per_state << ','
            << fr.nis_per_output << '\n';
    }
    });
    sum.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return sum;
}

std::string consistency_note(const RunConfig& cfg, const CompareFilterResult& fr) {
    if (!(fr.nees_per_state > kOverconfidentNees)) return "";  // NaN: no covariance stated
    const bool particles = fr.name.rfind("pf", 0) == 0;
    // what the truth-free check of recorded data (hinf filter's NIS) reads on the same steps
    char seen[256] = "";
    if (std::isfinite(fr.nis_per_output))
        std::snprintf(seen, sizeof seen, "; its innovations' mean NIS per output is %.3g, %s", fr.nis_per_output,
                      fr.nis_per_output > kOverconfidentNis
                          ? "so on a record without the truth `hinf filter` would say so too"
                          : "so on a record without the truth it would pass unnoticed: the errors lie where the "
                            "outputs do not look");
    char buf[1400];
    std::snprintf(buf, sizeof buf,
                  "note: %s: its settled errors are about %.3g times what its own covariance says (mean NEES per state "
                  "%.3g after t = %g, about 1 for a filter whose covariance is its error's): it is overconfident, and "
                  "its figures say how far it lost the state, not what the filter can do here; %s%s (docs/compare.md "
                  "\"Consistency\")",
                  fr.name.c_str(), std::sqrt(fr.nees_per_state), fr.nees_per_state, cfg.settle_time,
                  particles ? "its particle cloud collapsed onto too few distinct states: ten times the --particles, "
                              "or --pf-roughening 0.2, repaired that on some systems, not on all"
                            : "its linearisation, or the statistics it is told ([baseline] disturbance_std, noise_std, "
                              "initial_std), does not hold along these runs: compare the ukf and the pf",
                  seen);
    return buf;
}

}  // namespace hinf
