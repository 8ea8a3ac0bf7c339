// Recorded measurements for `hinf filter`: a time column and m outputs per row, from CSV or HDF5,
// checked row by row before any filtering. Layout and rules: docs/formats.md "Measurement files".
// Not the filters (src/filters) nor the run over them (eval/filter_recorded.cpp).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace hinf {

struct MeasurementSource {
    std::string path;
    int outputs = 0;                   // m: the config's system's measurement dimension
    std::string time_dataset = "t";    // HDF5 only: [K] seconds
    std::string values_dataset = "y";  // HDF5 only: [K x m] (or [K] when m = 1)
};

struct Measurements {
    std::vector<double> t;  // [K] s, strictly increasing, uniformly spaced
    std::vector<double> y;  // [K x m] row-major
    int m = 0;
    std::int64_t rows = 0;
    double dt = 0;                      // the sampling interval (t[K-1] - t[0]) / (K - 1)
    std::vector<std::string> columns;   // CSV header names after the time column (empty if none)
};

/// Relative tolerance on the spacing: |t[k] - t[k-1] - dt| <= kUniformTolerance * dt for every row.
constexpr double kUniformTolerance = 1e-6;

/// Reads and checks src.path: *.csv / *.txt as CSV (comma-separated; '#' lines and one header row
/// allowed), *.h5 / *.hdf5 as HDF5 (read in a child process first, io/isolate.hpp). Throws hinf::Error
/// naming the file and the row for: wrong column count, unparsable or non-finite values (NaN, inf),
/// time not strictly increasing, non-uniform spacing, fewer than 2 rows.
Measurements read_measurements(const MeasurementSource& src);

/// The same checks on arrays in memory (the library and the Python module): t [rows], y [rows x outputs];
/// `name` stands for the file in the messages.
Measurements measurements_from_arrays(const double* t, const double* y, std::int64_t rows, int outputs,
                                     const std::string& name);

}  // namespace hinf
