// Recorded measurements for `hinf filter`: a time column and m outputs per row, from CSV or HDF5,
// checked row by row before any filtering. Layout and rules: docs/formats.md "Measurement files".
// Not the filters (src/filters) nor the run over them (eval/filter_recorded.cpp).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "hinf/h5.hpp"

namespace hinf {

class System;

struct MeasurementSource {
    std::string path;
    int outputs = 0;                   // m: the config's system's measurement dimension
    std::string time_dataset = "t";    // HDF5 only: [K] seconds
    std::string values_dataset = "y";  // HDF5 only: [K x m] (or [K] when m = 1)
    double time_tolerance = 0.05;      // |t[k] - t[k-1] - dt| <= time_tolerance * dt (relative to the step)
    std::string resample;              // "" (the record must be uniform), "linear" or "zoh": onto t_0 + k dt
    std::vector<std::string> known_inputs;  // the system's known inputs ([system] inputs): read where the record has them
};

struct Measurements {
    std::vector<double> t;  // [K] s, strictly increasing, uniformly spaced
    std::vector<double> y;  // [K x m] row-major; NaN in a missing row
    std::vector<unsigned char> missing;  // [K] 1: the row's measurement is missing (an empty or NaN cell)
    std::int64_t missing_rows = 0;
    int m = 0;
    std::int64_t rows = 0;
    double dt = 0;                      // the sampling interval (t[K-1] - t[0]) / (K - 1)
    std::vector<std::string> columns;   // CSV header names of the outputs (empty if none)
    // the known inputs the record carries beside its outputs (CSV columns, HDF5 datasets inputs/NAME; src.known_inputs),
    // on the record's own times (before any resampling): names [q] in the record's order, input_t [R], values [R x q]
    std::vector<std::string> input_names;
    std::vector<double> input_t, input_values;
};

/// Default relative tolerance on the spacing: |t[k] - t[k-1] - dt| <= tolerance * dt for every row, dt the mean
/// step. Relative to the step, never to the absolute time (Unix-epoch time columns are common).
constexpr double kUniformTolerance = 0.05;

/// Reads and checks src.path: *.csv / *.txt as CSV (comma-separated; '#' lines and one header row
/// allowed), *.h5 / *.hdf5 as HDF5 (read in a child process first, io/isolate.hpp). Throws hinf::Error
/// naming the file and the row for: wrong column count, unparsable or infinite values, a missing time,
/// time not strictly increasing, non-uniform spacing (beyond src.time_tolerance, unless src.resample), fewer
/// than 2 rows. With src.resample = "linear" or "zoh" the record is put on the uniform grid t_0 + k dt (dt the
/// mean step) by linear interpolation or zero-order hold (the last sample at or before each grid time).
/// An empty or NaN output cell marks the row's measurement as missing (a dropout: the filters predict only
/// at that time); a grid time interpolated from or held at a missing row is missing too.
/// Known inputs: a CSV header cell or an HDF5 dataset inputs/NAME ([K]) named as one of src.known_inputs is that input's
/// values (input_names, input_t, input_values), the other columns as the outputs; a record with some of the inputs
/// but not all is refused, and an input has no missing cells.
Measurements read_measurements(const MeasurementSource& src);

/// Writes the known inputs of the run a record comes from where read_measurements reads them: the group `inputs`, one
/// dataset [K] per input of sys ([system] inputs), u(t_k) as f reads it at each record time t [K] (so `hinf filter` on
/// the record sees the inputs the run saw, whatever table its config names). Nothing where sys has no known inputs.
void write_record_inputs(hid_t loc, const System& sys, const double* t, std::int64_t K);

/// The same checks on arrays in memory (the library and the Python module): t [rows], y [rows x outputs];
/// `name` stands for the file in the messages.
Measurements measurements_from_arrays(const double* t, const double* y, std::int64_t rows, int outputs,
                                     const std::string& name);

}  // namespace hinf
