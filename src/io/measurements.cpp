// See measurements.hpp.
#include "io/measurements.hpp"

#include <cmath>
#include <cstdio>
#include <algorithm>

#include "core/csv.hpp"
#include "hinf/error.hpp"
#include "hinf/h5.hpp"
#include "io/isolate.hpp"
#include "models/expr_system.hpp"

namespace hinf {

namespace {

bool ends_with(const std::string& s, const std::string& suffix) {
    return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

template <typename Where>
void resample_rows(Measurements& ms, const std::string& path, double tolerance, const std::string& resample,
                   Where where);

// The checks shared by both formats; `where(k)` names row k (0-based) for the message.
template <typename Where>
void check_rows(Measurements& ms, const std::string& path, double tolerance, const std::string& resample, Where where) {
    const std::int64_t K = ms.rows;
    HINF_CHECK(K >= 2, "measurements '" + path + "': " + std::to_string(K) +
                           " row(s); hinf filter needs at least 2 (a time column and the outputs per row)");
    for (std::int64_t k = 0; k < K; ++k) {
        HINF_CHECK(std::isfinite(ms.t[k]), "measurements '" + path + "' " + where(k) + ": time is not finite (" +
                                              std::to_string(ms.t[k]) + "); remove or repair the row");
        for (int j = 0; j < ms.m; ++j)  // NaN: a missing measurement (a dropout); inf: a broken value
            HINF_CHECK(!std::isinf(ms.y[k * ms.m + j]),
                       "measurements '" + path + "' " + where(k) + ": output " + std::to_string(j + 1) +
                           " is infinite; mark a missing measurement with an empty or NaN cell");
        if (k > 0)
            HINF_CHECK(ms.t[k] > ms.t[k - 1], "measurements '" + path + "' " + where(k) + ": time " +
                                                  std::to_string(ms.t[k]) + " s is not after the previous row's " +
                                                  std::to_string(ms.t[k - 1]) + " s (time must increase strictly)");
    }
    ms.dt = (ms.t[K - 1] - ms.t[0]) / double(K - 1);
    HINF_CHECK(std::isfinite(ms.dt) && ms.dt > 0, "measurements '" + path + "': the time span is not finite");
    resample_rows(ms, path, tolerance, resample, where);
    ms.missing.assign(K, 0);
    ms.missing_rows = 0;
    for (std::int64_t k = 0; k < K; ++k) {
        for (int j = 0; j < ms.m; ++j) ms.missing[k] = ms.missing[k] || std::isnan(ms.y[k * ms.m + j]);
        ms.missing_rows += ms.missing[k];
    }
    HINF_CHECK(ms.missing_rows < K, "measurements '" + path + "': every row has a missing (empty or NaN) output; "
                                    "there is nothing to filter");
}

// The uniform-grid check, or the record put on the grid t_0 + k dt (resample = "linear" or "zoh").
template <typename Where>
void resample_rows(Measurements& ms, const std::string& path, double tolerance, const std::string& resample,
                   Where where) {
    const std::int64_t K = ms.rows;
    if (resample.empty()) {
        for (std::int64_t k = 1; k < K; ++k) {
            const double step = ms.t[k] - ms.t[k - 1];
            if (std::fabs(step - ms.dt) > tolerance * ms.dt) {
                char buf[200];
                std::snprintf(buf, sizeof buf, "time step %.6g s differs from the record's mean step %.6g s by %.3g%% "
                              "(more than --time-tolerance %g)", step, ms.dt, 100 * std::fabs(step / ms.dt - 1), tolerance);
                HINF_FAIL("measurements '" + path + "' " + where(k) + ": " + buf +
                          "; the filters run on a uniform grid: pass --resample linear or --resample zoh, or a larger "
                          "--time-tolerance");
            }
        }
        return;
    }
    // onto the uniform grid t_0 + k dt, dt the mean step; the last grid time is t[K-1] (up to rounding)
    std::vector<double> t(K), y(std::size_t(K) * ms.m);
    std::int64_t j = 0;  // t[j] <= grid time < t[j + 1]
    for (std::int64_t k = 0; k < K; ++k) {
        const double tk = k + 1 == K ? ms.t[K - 1] : ms.t[0] + double(k) * ms.dt;
        while (j + 1 < K && ms.t[j + 1] <= tk) ++j;
        t[k] = tk;
        const double* a = ms.y.data() + j * ms.m;
        if (resample == "zoh" || j + 1 == K) {
            std::copy(a, a + ms.m, y.begin() + k * ms.m);
        } else {
            const double* b = a + ms.m;
            const double w = (tk - ms.t[j]) / (ms.t[j + 1] - ms.t[j]);
            for (int i = 0; i < ms.m; ++i) y[k * ms.m + i] = w == 0 ? a[i] : a[i] + w * (b[i] - a[i]);
        }
    }
    ms.t = std::move(t);
    ms.y = std::move(y);
}

// Every known input or none: a record that has some is refused, naming the others (`has` lists those it has).
void check_all_inputs(const MeasurementSource& src, const std::vector<std::string>& has, const std::string& where) {
    if (has.empty()) return;
    std::string lacking;
    for (const std::string& name : src.known_inputs)
        if (std::find(has.begin(), has.end(), name) == has.end()) lacking += (lacking.empty() ? "" : ", ") + name;
    HINF_CHECK(lacking.empty(), "measurements '" + src.path + "'" + where + ": has known input(s) of the system but not " +
                                    lacking + ": give every known input its column, or none (then the config's table, "
                                    "[system] inputs, is used)");
}

Measurements read_csv(const MeasurementSource& src) {
    const CsvTable table = read_csv_table(src.path, "measurements");
    Measurements ms;
    ms.m = src.outputs;
    std::vector<int> input_of;  // per column: the index into ms.input_names, -1 for the time and the outputs
    if (table.header_line > 0) {
        input_of.assign(table.header.size(), -1);
        for (std::size_t c = 1; c < table.header.size(); ++c) {
            const std::string& cell = table.header[c];
            if (std::find(src.known_inputs.begin(), src.known_inputs.end(), cell) == src.known_inputs.end()) {
                ms.columns.push_back(cell);
                continue;
            }
            HINF_CHECK(std::find(ms.input_names.begin(), ms.input_names.end(), cell) == ms.input_names.end(),
                       "measurements '" + src.path + "' line " + std::to_string(table.header_line) +
                           ": two columns are named '" + cell + "' (a known input): keep one");
            input_of[c] = int(ms.input_names.size());
            ms.input_names.push_back(cell);
        }
        check_all_inputs(src, ms.input_names, " line " + std::to_string(table.header_line));
        const std::string inputs = ms.input_names.empty() ? "" : " + " + std::to_string(ms.input_names.size()) +
                                                                     " known input(s)";
        HINF_CHECK(int(ms.columns.size()) == ms.m,
                   "measurements '" + src.path + "' line " + std::to_string(table.header_line) + ": the header has " +
                       std::to_string(table.header.size()) + " columns, expected " +
                       std::to_string(1 + ms.m + ms.input_names.size()) + " (time + " + std::to_string(ms.m) +
                       " output(s) of the config's system" + inputs + ")");
    }
    const std::size_t q = ms.input_names.size(), width = 1 + ms.m + q;
    for (std::size_t r = 0; r < table.rows.size(); ++r) {
        const std::vector<std::string>& cells = table.rows[r];
        const std::string lineno = std::to_string(table.line_of[r]);
        // a record without a header that has a column per known input too: its columns have no names to tell them
        const bool unnamed = table.header_line == 0 && !src.known_inputs.empty() &&
                             cells.size() == width + src.known_inputs.size();
        HINF_CHECK(cells.size() == width, "measurements '" + src.path + "' line " + lineno + ": " +
                                              std::to_string(cells.size()) + " columns, expected " +
                                              std::to_string(width) + " (time + " + std::to_string(ms.m) +
                                              " output(s) of the config's system" +
                                              (q ? " + " + std::to_string(q) + " known input(s)" : "") + ")" +
                                              (unnamed ? "; to carry the known inputs the record needs a header "
                                                         "naming its columns (e.g. t,y,V)"
                                                       : ""));
        const std::size_t at = ms.input_values.size();
        ms.input_values.resize(at + q);
        for (std::size_t c = 0; c < cells.size(); ++c) {
            const int input = input_of.empty() ? -1 : input_of[c];
            double v = NAN;  // an empty output cell: a missing measurement
            if (c > 0 && input < 0 && cells[c].empty()) {
                ms.y.push_back(v);
                continue;
            }
            HINF_CHECK(csv_number(cells[c], &v), "measurements '" + src.path + "' line " + lineno + ", column " +
                                                     std::to_string(c + 1) + ": '" + cells[c] + "' is not a number" +
                                                     (input >= 0 ? " (known input " + ms.input_names[input] +
                                                                       " has no gaps: fill them)"
                                                                 : ""));
            if (c == 0) ms.t.push_back(v);
            else if (input >= 0) ms.input_values[at + input] = v;
            else ms.y.push_back(v);
        }
    }
    ms.rows = std::int64_t(ms.t.size());
    if (q > 0) ms.input_t = ms.t;  // the inputs stay on the record's own clock (a resampled record moves its outputs)
    check_rows(ms, src.path, src.time_tolerance, src.resample,
               [&](std::int64_t k) { return "line " + std::to_string(table.line_of[k]); });
    return ms;
}

Measurements read_hdf5_here(const MeasurementSource& src) {
    h5::Handle f = h5::open_file(src.path, false);
    for (const std::string* name : {&src.time_dataset, &src.values_dataset})
        HINF_CHECK(h5::exists(f.get(), *name), "measurements '" + src.path + "': no dataset '" + *name +
                                                   "' (name them with --time-dataset / --dataset)");
    Measurements ms;
    ms.m = src.outputs;
    std::vector<hsize_t> td, yd;
    ms.t = h5::read_doubles(f.get(), src.time_dataset, &td);
    ms.y = h5::read_doubles(f.get(), src.values_dataset, &yd);
    HINF_CHECK(td.size() == 1, "measurements '" + src.path + "': dataset '" + src.time_dataset + "' has " +
                                   std::to_string(td.size()) + " dimensions, expected 1 ([K] seconds)");
    const bool shape_ok = (yd.size() == 2 && yd[0] == td[0] && yd[1] == hsize_t(ms.m)) ||
                          (yd.size() == 1 && ms.m == 1 && yd[0] == td[0]);
    std::string shape;
    for (std::size_t i = 0; i < yd.size(); ++i) shape += (i ? " x " : "") + std::to_string(yd[i]);
    HINF_CHECK(shape_ok, "measurements '" + src.path + "': dataset '" + src.values_dataset + "' is [" + shape +
                             "], expected [" + std::to_string(td[0]) + " x " + std::to_string(ms.m) +
                             "] (one row per time in '" + src.time_dataset + "', one column per output)");
    ms.rows = std::int64_t(td[0]);
    // the known inputs' datasets, [K] each, in the group `inputs` (never a top-level name: hinf's own result files,
    // operate.h5 a record among them, hold datasets v, n, x, ... that an input may be named as)
    std::vector<std::vector<double>> columns;
    for (const std::string& name : src.known_inputs) {
        const std::string path = "inputs/" + name;
        if (!h5::exists(f.get(), path)) continue;
        std::vector<hsize_t> ud;
        columns.push_back(h5::read_doubles(f.get(), path, &ud));
        HINF_CHECK(ud.size() == 1 && ud[0] == td[0], "measurements '" + src.path + "': dataset '" + path +
                                                         "' (a known input) is not [" + std::to_string(td[0]) +
                                                         "], one value per time in '" + src.time_dataset + "'");
        ms.input_names.push_back(name);
    }
    check_all_inputs(src, ms.input_names, "");
    if (!columns.empty()) {
        ms.input_t = ms.t;
        ms.input_values.resize(std::size_t(ms.rows) * columns.size());
        for (std::int64_t k = 0; k < ms.rows; ++k)
            for (std::size_t i = 0; i < columns.size(); ++i) ms.input_values[k * columns.size() + i] = columns[i][k];
    }
    check_rows(ms, src.path, src.time_tolerance, src.resample, [](std::int64_t k) { return "row " + std::to_string(k) + " (0-based)"; });
    return ms;
}

}  // namespace

Measurements read_measurements(const MeasurementSource& src) {
    HINF_CHECK(src.outputs >= 1, "measurements: the system has no outputs");
    HINF_CHECK(std::isfinite(src.time_tolerance) && src.time_tolerance >= 0 && src.time_tolerance < 1,
               "--time-tolerance must be a number in [0, 1) (a fraction of the record's mean step)");
    HINF_CHECK(src.resample.empty() || src.resample == "linear" || src.resample == "zoh",
               "--resample '" + src.resample + "' is not one of: linear, zoh");
    const std::string& p = src.path;
    check_input_file(p, "measurements");
    if (ends_with(p, ".csv") || ends_with(p, ".txt")) return read_csv(src);
    if (ends_with(p, ".h5") || ends_with(p, ".hdf5")) {
        const std::string problem = run_isolated([&src] { read_hdf5_here(src); });
        HINF_CHECK(problem.empty(), problem.find(p) == std::string::npos ? "measurements '" + p + "': " + problem : problem);
        return read_hdf5_here(src);
    }
    HINF_FAIL("measurements '" + p + "': unknown file type (use .csv or .txt with a time column, or .h5/.hdf5 "
              "with datasets t and y)");
}

void write_record_inputs(hid_t loc, const System& sys, const double* t, std::int64_t K) {
    const ExprSystem* expr = expr_system_of(sys);
    if (expr == nullptr || expr->inputs().empty() || K <= 0) return;
    const std::vector<std::string>& names = expr->inputs();
    const std::size_t q = names.size();
    std::vector<double> u(q), column(std::size_t(K) * q);
    for (std::int64_t k = 0; k < K; ++k) {
        expr->inputs_at(t[k], u.data());
        for (std::size_t i = 0; i < q; ++i) column[i * std::size_t(K) + std::size_t(k)] = u[i];
    }
    h5::Handle g = h5::create_group(loc, "inputs");
    for (std::size_t i = 0; i < q; ++i)
        h5::write_doubles(g.get(), names[i], column.data() + i * std::size_t(K), {hsize_t(K)}, "input units",
                          "the known input " + names[i] + " at each time t, as the run's f, g, h read it (hinf filter "
                          "on this record reads it in place of its config's table)");
}

Measurements measurements_from_arrays(const double* t, const double* y, std::int64_t rows, int outputs,
                                     const std::string& name) {
    HINF_CHECK(outputs >= 1, "measurements: the system has no outputs");
    HINF_CHECK(rows >= 0, name + ": negative row count");
    Measurements ms;
    ms.m = outputs;
    ms.rows = rows;
    ms.t.assign(t, t + rows);
    ms.y.assign(y, y + rows * outputs);
    check_rows(ms, name, MeasurementSource().time_tolerance, "", [](std::int64_t k) { return "row " + std::to_string(k) + " (0-based)"; });
    return ms;
}

}  // namespace hinf
