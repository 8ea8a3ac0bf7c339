// See csv.hpp.
#include "core/csv.hpp"

#include <cerrno>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "hinf/error.hpp"

namespace hinf {

namespace {

std::string trim_cell(const std::string& s) {
    const auto a = s.find_first_not_of(" \t\r");
    if (a == std::string::npos) return "";
    const auto b = s.find_last_not_of(" \t\r");
    return s.substr(a, b - a + 1);
}

std::vector<std::string> split_commas(const std::string& line) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) cells.push_back(trim_cell(cell));
    if (!line.empty() && line.back() == ',') cells.push_back("");
    return cells;
}

}  // namespace

bool csv_number(const std::string& cell, double* v) {
    if (cell.empty()) return false;
    char* end = nullptr;
    errno = 0;
    *v = std::strtod(cell.c_str(), &end);
    return end == cell.c_str() + cell.size();
}

CsvTable read_csv_table(const std::string& path, const std::string& what, std::int64_t max_rows) {
    check_input_file(path, what);
    std::ifstream in(path);
    HINF_CHECK(in.good(), what + " '" + path + "' cannot be opened (check the path)");
    CsvTable table;
    std::string line;
    std::int64_t lineno = 0;
    while (std::getline(in, line)) {
        ++lineno;
        if (lineno == 1 && line.compare(0, 3, "\xEF\xBB\xBF") == 0) line.erase(0, 3);  // a UTF-8 byte-order mark
        const std::string s = trim_cell(line);
        if (s.empty() || s[0] == '#') continue;
        std::vector<std::string> cells = split_commas(s);
        double first = 0;
        if (table.rows.empty() && table.header_line == 0 && !csv_number(cells[0], &first)) {
            table.header = std::move(cells);
            table.header_line = lineno;
            continue;
        }
        HINF_CHECK(max_rows <= 0 || std::int64_t(table.rows.size()) < max_rows,
                   what + " '" + path + "': more than " + std::to_string(max_rows) + " rows of values (line " +
                       std::to_string(lineno) + "), the most read here: thin the table");
        table.rows.push_back(std::move(cells));
        table.line_of.push_back(lineno);
    }
    HINF_CHECK(!in.bad(), what + " '" + path + "': a read error at line " + std::to_string(lineno + 1));
    return table;
}

}  // namespace hinf
