// See filter_recorded.hpp. Time convention of filters/filter.hpp: row k of `xhat` is the estimate of
// x(t_k) from y(t_0) ... y(t_{k-1}) (the one-step prediction every filter is scored on in `compare`),
// `xhat_final` the estimate of x(t_{K-1} + dt) after the last measurement.
#include "eval/filter_recorded.hpp"


#include <chrono>
#include <cmath>
#include <cstdio>
#include <algorithm>
#include <filesystem>
#include <fstream>

#include "eval/engine.hpp"
#include "hinf/error.hpp"
#include "hinf/h5.hpp"
#include "io/atomic.hpp"
#include "io/run_lock.hpp"
#include "io/progress.hpp"

namespace hinf {

namespace {

using Path = RecordedPath;  // filter_recorded.hpp

void write_csv(const std::string& path, const RunConfig& cfg, const Measurements& ms, const Path& p) {
    const int n = cfg.n, m = cfg.m;
    const auto names = cfg.system->state_names();
    write_text_atomic(path, [&](std::ostream& out) {
    out << "t";
    for (int i = 0; i < n; ++i) out << ',' << names[i] << "_hat";
    if (p.has_cov)
        for (int i = 0; i < n; ++i) out << ",sd_" << names[i];
    for (int j = 0; j < m; ++j) out << ",innovation_" << (j + 1);
    if (!p.nis.empty()) out << ",nis";
    out << '\n';
    char buf[32];
    auto put = [&](double v) {
        std::snprintf(buf, sizeof buf, ",%.17g", v);
        out << buf;
    };
    for (std::int64_t k = 0; k < ms.rows; ++k) {
        std::snprintf(buf, sizeof buf, "%.17g", ms.t[k]);
        out << buf;
        for (int i = 0; i < n; ++i) put(p.xhat[k * n + i]);
        if (p.has_cov)
            for (int i = 0; i < n; ++i) put(std::sqrt(std::max(0.0, p.P[(k * n + i) * n + i])));
        for (int j = 0; j < m; ++j) put(p.innov[k * m + j]);
        if (!p.nis.empty()) put(p.nis[k]);
        out << '\n';
    }
    });
}

// Whether `path` begins with the header write_csv gives: "t", then only columns named <state>_hat, sd_<state>,
// innovation_<j> and nis, with at least one estimate and one innovation. A rerun removes an earlier run's CSV of a
// filter not in it only where this holds, so a user's own file named estimates_*.csv in DIR stays. Only the first
// line is read (core/csv.hpp's read_csv_table reads the whole table, up to 300 000 rows of an earlier run).
bool is_estimates_csv(const std::filesystem::path& path) {
    std::ifstream in(path);
    std::string head;
    if (!in || !std::getline(in, head)) return false;
    if (!head.empty() && head.back() == '\r') head.pop_back();
    if (head.rfind("t,", 0) != 0) return false;
    bool estimate = false, innovation = false;
    std::size_t at = 2;
    while (at <= head.size()) {
        const std::size_t end = std::min(head.find(',', at), head.size());
        const std::string col = head.substr(at, end - at);
        at = end + 1;
        const auto ends_with = [&](const char* tail) {
            const std::size_t k = std::char_traits<char>::length(tail);
            return col.size() > k && col.compare(col.size() - k, k, tail) == 0;
        };
        if (ends_with("_hat")) {
            estimate = true;
        } else if (col.rfind("innovation_", 0) == 0 && col.size() > 11 &&
                   col.find_first_not_of("0123456789", 11) == std::string::npos) {
            innovation = true;
        } else if (!(col.rfind("sd_", 0) == 0 && col.size() > 3) && col != "nis") {
            return false;
        }
    }
    return estimate && innovation;
}

}  // namespace

void recorded_check_sampling(const RunConfig& cfg, const Measurements& ms, const std::string& source) {
    // a discrete system's step k is t / dt with the config's dt: a record sampled otherwise would be another model
    HINF_CHECK(!cfg.system->discrete_time() || std::fabs(ms.dt - cfg.dt) <= 1e-6 * cfg.dt,
               source + ": the record is sampled every " + std::to_string(ms.dt) + " s, the discrete-time system of " +
                   cfg.doc.source() + " steps every [filter] dt = " + std::to_string(cfg.dt) +
                   " s (set dt to the record's period)");
    // a table of known inputs ([system] inputs) must cover the record's times (a system without one: any time)
    const std::pair<double, double> span = cfg.system->time_span();
    if (ms.rows > 0) {
        const double slack = 1e-9 * ms.dt;
        char buf[200];
        std::snprintf(buf, sizeof buf, "the record runs over [%.10g, %.10g] s, beyond its table of known inputs "
                      "([%.10g, %.10g] s)", ms.t.front(), ms.t.back(), span.first, span.second);
        HINF_CHECK(ms.t.front() >= span.first - slack && ms.t.back() <= span.second + slack,
                   source + ": " + buf + " in " + cfg.doc.source() + " [system] inputs (name the inputs that "
                   "were applied during this record, on its clock)");
    }
}

std::vector<RecordedResult> filter_recorded(const RunConfig& cfg, const std::vector<OnlineFilter*>& filters,
                                            const Measurements& ms, const RecordedOptions& opt) {
    const System& sys = *cfg.system;
    const int n = cfg.n, m = cfg.m;
    const std::int64_t K = ms.rows;
    HINF_CHECK(ms.m == m, "measurements have " + std::to_string(ms.m) + " outputs, the system " + std::to_string(m));
    recorded_check_sampling(cfg, ms, opt.source);
    HINF_CHECK(int(opt.xhat0.size()) == n && opt.P0.size() == std::size_t(n) * n, "filter: initial estimate size");
    const RunDirLock lock(opt.out_dir, "hinf filter");  // before anything there is opened for writing
    std::vector<RecordedResult> results;
    std::vector<Path> paths;
    for (OnlineFilter* f : filters) {
        HINF_CHECK(!f->uses_true_state(), "filter '" + f->name() +
                                              "' reads the true state (oracle mode); recorded data have none: use "
                                              "--mode measured");
        Path p;  // the one loop of `hinf filter` and the library's Filter::run
        results.push_back(filter_record_path(*f, cfg, ms, opt.xhat0, opt.P0, opt.quiet, &p));
        paths.push_back(std::move(p));
    }

    // The set of outputs: every file is first written whole beside its place (CSVs as .csv.new, estimates.h5 as its
    // .tmp); only then are they renamed into place, estimates.h5 last (it lists its CSVs), and the previous run's
    // CSVs of filters not in this run are removed. A kill before the renames leaves the previous set whole; the
    // renames take microseconds (docs/reliability.md).
    const std::string h5path = opt.out_dir + "/estimates.h5";
    std::vector<std::string> csv_names;
    std::string csv_files;
    for (std::size_t i = 0; i < results.size(); ++i) {
        csv_names.push_back("estimates_" + results[i].name + ".csv");
        write_csv(opt.out_dir + "/" + csv_names.back() + ".new", cfg, ms, paths[i]);
        csv_files += (csv_files.empty() ? "" : ",") + csv_names.back();
    }
    {
        AtomicH5 file(h5path);
        hid_t root = file.get();
        h5::set_attr(root, "format", "hinf-estimates");
        h5::set_attr(root, "format_version", std::int64_t(1));
        h5::set_attr(root, "source", opt.source);
        h5::set_attr(root, "system", sys.name());
        h5::set_attr(root, "rows", K);
        h5::set_attr(root, "dt", ms.dt);
        h5::set_attr(root, "system_time", std::string(system_time_name(*cfg.system)));
        h5::set_attr(root, "missing_rows", ms.missing_rows);  // rows without a measurement: predicted only
        h5::set_attr(root, "mode", "measured");
        h5::set_attr(root, "csv_files", csv_files);  // the CSVs of this run, written before this file
        h5::set_attr(root, "meaning",
                     "estimates of recorded measurements, no true state used (mode measured); per filter group: xhat[k] "
                     "estimates x(t_k) from y(t_0..t_{k-1}) (one-step prediction), innovation[k] = y_k - C(xhat[k], t_k)");
        std::string units;
        for (const auto& u : sys.state_units()) units += (units.empty() ? "" : ",") + u;
        std::string names;
        for (const auto& s : sys.state_names()) names += (names.empty() ? "" : ",") + s;
        h5::set_attr(root, "state_names", names);
        h5::set_attr(root, "state_units", units);
        h5::write_doubles(root, "t", ms.t.data(), {hsize_t(K)}, "s", "time of each measurement (from the record)");
        h5::write_doubles(root, "y", ms.y.data(), {hsize_t(K), hsize_t(m)}, "output units", "the recorded measurements");
        write_record_inputs(root, *cfg.system, ms.t.data(), K);
        h5::write_string(root, "config", cfg.doc.text(), "the effective TOML config");
        for (std::size_t i = 0; i < results.size(); ++i) {
            const RecordedResult& r = results[i];
            const Path& p = paths[i];
            h5::Handle g = h5::create_group(root, r.name);
            h5::set_attr(g.get(), "mode", "measured");
            h5::set_attr(g.get(), "diverged_at", r.diverged_at);
            h5::set_attr(g.get(), "us_per_step", r.us_per_step);
            h5::set_attr(g.get(), "innovation_rms", r.innovation_rms);
            h5::set_attr(g.get(), "innovation_mean", r.innovation_mean);
            if (!r.note.empty()) h5::set_attr(g.get(), "note", r.note);  // what the figures do not say
            if (std::isfinite(r.nis_per_output)) {
                h5::set_attr(g.get(), "nis_per_output", r.nis_per_output);
                h5::set_attr(g.get(), "nis_from", r.nis_from);
            }
            h5::write_doubles(g.get(), "xhat", p.xhat.data(), {hsize_t(K), hsize_t(n)}, units,
                              "estimate of x(t_k) from y(t_0..t_{k-1}); frozen after a divergence");
            h5::write_doubles(g.get(), "xhat_final", p.xhat_final.data(), {hsize_t(n)}, units,
                              "estimate after the last measurement: x(t_{K-1} + dt)");
            h5::write_doubles(g.get(), "innovation", p.innov.data(), {hsize_t(K), hsize_t(m)}, "output units",
                              "y_k - C(xhat[k], t_k)");
            if (!p.xhat_filtered.empty())
                h5::write_doubles(g.get(), "xhat_filtered", p.xhat_filtered.data(), {hsize_t(K), hsize_t(n)}, units,
                                  "filtered estimate x^_{k|k} of x(t_k) from y(t_0..t_k); frozen after a divergence");
            if (!p.nis.empty())
                h5::write_doubles(g.get(), "nis", p.nis.data(), {hsize_t(K)}, "1",
                                  "normalised innovation squared of y_k against the covariance the filter expected for "
                                  "it (mean m where its statistics hold); NaN: no measurement, or frozen");
            if (p.has_cov)
                h5::write_doubles(g.get(), "P", p.P.data(), {hsize_t(K), hsize_t(n), hsize_t(n)}, "state units squared",
                                  "the filter's error covariance of xhat[k]");
        }
        for (const std::string& csv : csv_names) commit_rename(opt.out_dir + "/" + csv + ".new", opt.out_dir + "/" + csv);
        file.commit();
    }
    // An earlier run's CSVs of other filters, and leftovers of a kill: named estimates_*.csv(.new) and headed as
    // write_csv heads them. A file of that name with another header is not hinf's and stays.
    std::vector<std::filesystem::path> stale;
    for (const auto& e : std::filesystem::directory_iterator(opt.out_dir)) {
        const std::string name = e.path().filename().string();
        const bool ours = std::find(csv_names.begin(), csv_names.end(), name) != csv_names.end();
        if (name.rfind("estimates_", 0) == 0 && !ours &&
            (e.path().extension() == ".csv" || (name.size() > 8 && name.compare(name.size() - 8, 8, ".csv.new") == 0)) &&
            e.is_regular_file() && is_estimates_csv(e.path()))
            stale.push_back(e.path());
    }
    for (const auto& f : stale) std::filesystem::remove(f);
    return results;
}

std::string innovation_consistency_note(const RecordedResult& r) {
    const double q = r.nis_per_output;
    if (!(q > kOverconfidentNis || q < kUnderconfidentNis) || r.nis_dof < kNisMinDof) return "";  // NaN: no S stated
    char buf[1024];
    if (q > kOverconfidentNis)
        std::snprintf(buf, sizeof buf,
                      "note: %s: its innovations are about %.3g times (RMS) what it expects (mean NIS per output %.3g "
                      "after t = %g s, about 1 where its model and the statistics it is told hold for this record): "
                      "it is overconfident here; the noise or disturbance it is told ([baseline] or [online] "
                      "noise_std, disturbance_std), its start (--initial-std) or its linearisation does not hold for "
                      "this record (docs/compare.md \"Consistency without the truth\")",
                      r.name.c_str(), std::sqrt(q), q, r.nis_from);
    else
        std::snprintf(buf, sizeof buf,
                      "note: %s: its innovations are about %.3g times (RMS) smaller than it expects (mean NIS per output "
                      "%.3g after t = %g s, about 1 where its statistics hold): it states more uncertainty than its "
                      "innovations show; the noise or disturbance it is told ([baseline] or [online] noise_std, "
                      "disturbance_std) may be larger than this record's, or its linearisation or sigma points "
                      "overstate the spread (docs/compare.md \"Consistency without the truth\")",
                      r.name.c_str(), 1.0 / std::sqrt(q), q, r.nis_from);
    return buf;
}

RecordedResult filter_record_path(OnlineFilter& f, const RunConfig& cfg, const Measurements& ms,
                                  const std::vector<double>& xhat0, const std::vector<double>& P0, bool quiet,
                                  RecordedPath* out) {
    const System& sys = *cfg.system;
    const int n = sys.state_dim(), m = sys.output_dim();
    const std::int64_t K = ms.rows;
    HINF_CHECK(ms.m == m, "measurements have " + std::to_string(ms.m) + " outputs, the system " + std::to_string(m));
    HINF_CHECK(int(xhat0.size()) == n && P0.size() == std::size_t(n) * n, "filter: initial estimate size");
    HINF_CHECK(!f.uses_true_state(), "filter '" + f.name() +
                                         "' reads the true state (oracle mode); recorded data have none: use "
                                         "--mode measured");
    RecordedResult r;
    r.name = f.name();
    r.steps = K;
    r.innovation_rms.assign(m, 0.0);
    r.innovation_mean.assign(m, 0.0);
    RecordedPath& p = *out;
    p = RecordedPath();
    FilterStart start;
    start.xhat0 = xhat0;
    start.P0 = P0;
    f.reset(start);
    p.has_cov = f.covariance() != nullptr;
    const bool states_nis = f.covariance_is_statistical();  // the Bayesian filters (OnlineFilter::nis)
    if (states_nis) p.nis.reserve(std::size_t(K));
    if (K > 0) r.nis_from = ms.t[0] + cfg.settle_time <= ms.t[K - 1] ? ms.t[0] + cfg.settle_time : ms.t[0];
    double nis_sum = 0, nis_steps = 0;
    p.xhat.reserve(std::size_t(K) * n);
    p.innov.reserve(std::size_t(K) * m);
    if (p.has_cov) p.P.reserve(std::size_t(K) * n * n);
    std::vector<double> c(m);
    std::int64_t used = 0;
    Progress progress("filter " + r.name, 0, K, quiet);
    // the filters run in the model's units (outputs weighted by their noise, ProblemConfig::output_weight);
    // innovations are reported in the record's, and the states' plausible range comes from the record's y too (the
    // units a position and a measured range share)
    std::vector<double> ym = ms.y;
    outputs_to_model(cfg, ym.data(), K);
    const std::vector<double> bound = plausible_bound(cfg, start, nullptr, ms.y.data(), K);
    const unsigned char* missing = ms.missing.empty() ? nullptr : ms.missing.data();
    StreamResult sr = filter_stream(f, ym.data(), m, ms.t.data(), K, nullptr, n, bound.data(), missing,
                                    [&](std::int64_t k, const double* xh, bool frozen) {
        p.xhat.insert(p.xhat.end(), xh, xh + n);
        if (p.has_cov) {
            const double* P = f.covariance();
            p.P.insert(p.P.end(), P, P + std::size_t(n) * n);
        }
        const double* y = ms.y.data() + k * m;
        sys.measurement(c.data(), xh, ms.t[k], 1);
        outputs_to_user(cfg, c.data(), 1);
        for (int j = 0; j < m; ++j) c[j] = y[j] - c[j];  // the innovation, in the user's units
        for (int j : sys.angle_outputs()) c[j] = wrap_angle(c[j]);
        for (int j = 0; j < m; ++j) p.innov.push_back(c[j]);  // NaN where the measurement is missing
        if (frozen || (missing != nullptr && missing[k])) return;  // frozen, or nothing to compare with
        for (int j = 0; j < m; ++j) {
            r.innovation_mean[j] += c[j];
            r.innovation_rms[j] += c[j] * c[j];
        }
        ++used;
        if (k % 1000 == 999) progress.update(k + 1, "");
    }, [&](std::int64_t k, const double* xf, bool frozen) {
        if (xf != nullptr) p.xhat_filtered.insert(p.xhat_filtered.end(), xf, xf + n);
        if (!states_nis) return;
        const double q = frozen ? NAN : f.nis();  // NaN where y_k is missing
        p.nis.push_back(q);
        if (std::isfinite(q) && ms.t[k] >= r.nis_from) {
            nis_sum += q;
            nis_steps += 1;
        }
    });
    if (nis_steps > 0) r.nis_per_output = nis_sum / nis_steps / double(m);
    r.nis_dof = nis_steps * double(m);
    r.diverged_at = sr.diverged_at;
    const double seconds = sr.seconds;
    r.note = f.run_note();
    p.xhat_final.assign(f.estimate(), f.estimate() + n);
    for (int j = 0; j < m; ++j) {
        r.innovation_mean[j] /= double(std::max<std::int64_t>(used, 1));
        r.innovation_rms[j] = std::sqrt(r.innovation_rms[j] / double(std::max<std::int64_t>(used, 1)));
    }
    r.us_per_step = 1e6 * seconds / double(std::max<std::int64_t>(sr.stepped, 1));
    progress.finish(r.diverged_at >= 0 ? "diverged at t = " + std::to_string(r.diverged_at) + " s" : "no divergence");
    return r;
}

}  // namespace hinf
