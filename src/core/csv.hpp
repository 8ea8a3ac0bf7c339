// Comma-separated tables as hinf reads them (a measurement record, a table of known inputs): '#' lines and blank
// lines skipped, a UTF-8 byte-order mark dropped, one optional header row (its first cell not a number), cells
// trimmed. Only the lexing: what the columns mean, and their checks, belong to the caller (io/measurements.cpp,
// config/run_config.cpp).
#pragma once
#include <cstdint>
#include <string>
#include <vector>

namespace hinf {

struct CsvTable {
    std::vector<std::string> header;             // the header row's cells; empty when the file has none
    std::int64_t header_line = 0;                // its line in the file (1-based), 0 without one
    std::vector<std::vector<std::string>> rows;  // the data rows' cells, trimmed ("" for an empty cell)
    std::vector<std::int64_t> line_of;           // the file line (1-based) of each data row
};

/// Reads `path` (opened after check_input_file, naming the file as `what`); throws hinf::Error naming it when it
/// cannot be read, or when it has more than `max_rows` data rows (0: no bound; a bound stops the reading there).
/// Column counts are not checked here.
CsvTable read_csv_table(const std::string& path, const std::string& what, std::int64_t max_rows = 0);

/// true and *v when the whole cell is one number (strtod's grammar: "nan" and "inf" are numbers, for the caller
/// to judge).
bool csv_number(const std::string& cell, double* v);

}  // namespace hinf
