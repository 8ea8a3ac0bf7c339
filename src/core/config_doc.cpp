// TOML config reading with strict checking (types, ranges, unknown keys) on top of toml++.
// Not the meaning of keys: see src/config/run_config.cpp and docs/formats.md.
#include "hinf/config.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <toml++/toml.h>

#include "hinf/error.hpp"

namespace hinf {

namespace {

constexpr std::size_t kMaxConfigBytes = 1u << 20;
constexpr int kMaxConfigNesting = 64;  // levels of dotted keys, table headers, arrays and inline tables

// toml++ parses nesting by recursion: tens of thousands of levels (an 80 kB file) overflow the stack. hinf's
// own configs nest 3 levels; bound it before parsing. Counts, outside strings and comments, the open [ and {
// and the dots of one key segment (between = , [ ] { } and line ends); a float has one dot, so values pass.
void check_nesting(const std::string& text, const std::string& source) {
    int depth = 0, dots = 0, line = 1;
    char quote = 0;  // inside a "..." or '...' string
    bool comment = false;
    for (std::size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (c == '\n') {
            ++line;
            comment = false;
            dots = 0;
            if (quote == '\'' && !(i >= 2 && text.compare(i - 2, 3, "'''") == 0)) quote = 0;
            continue;
        }
        if (comment) continue;
        if (quote) {
            if (c == '\\' && quote == '"') ++i;
            else if (c == quote) quote = 0;
            continue;
        }
        if (c == '"' || c == '\'') quote = c;
        else if (c == '#') comment = true;
        else if (c == '[' || c == '{') ++depth, dots = 0;
        else if (c == ']' || c == '}') depth = depth > 0 ? depth - 1 : 0, dots = 0;
        else if (c == '=' || c == ',') dots = 0;
        else if (c == '.') ++dots;
        HINF_CHECK(depth + dots <= kMaxConfigNesting,
                   source + ":" + std::to_string(line) + ": keys, tables or arrays nested more than " +
                       std::to_string(kMaxConfigNesting) + " levels deep (hinf's configs nest at most 3: see "
                       "docs/formats.md)");
    }
}

std::string line_of(const toml::node& node) {
    const auto& src = node.source();
    if (src.begin.line == 0) return "";
    return ":" + std::to_string(src.begin.line);
}

std::string nearest(const std::string& key, const std::set<std::string>& known) {
    std::string best;
    int best_d = 1 << 30;
    for (const auto& k : known) {
        int d = edit_distance(key, k);
        if (d < best_d) {
            best_d = d;
            best = k;
        }
    }
    return best;
}

std::string list_of(const std::set<std::string>& known) {
    std::string out;
    for (const auto& k : known) out += (out.empty() ? "" : ", ") + k;
    return out;
}

}  // namespace

int edit_distance(const std::string& a, const std::string& b) {
    std::vector<int> prev(b.size() + 1), cur(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = static_cast<int>(j);
    for (std::size_t i = 1; i <= a.size(); ++i) {
        cur[0] = static_cast<int>(i);
        for (std::size_t j = 1; j <= b.size(); ++j) {
            int sub = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
            cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
        }
        std::swap(prev, cur);
    }
    return prev[b.size()];
}

ConfigDoc::ConfigDoc() : root_(std::make_unique<toml::table>()) {}
ConfigDoc::~ConfigDoc() = default;
ConfigDoc::ConfigDoc(ConfigDoc&&) noexcept = default;
ConfigDoc& ConfigDoc::operator=(ConfigDoc&&) noexcept = default;
ConfigDoc::ConfigDoc(const ConfigDoc& o) : root_(std::make_unique<toml::table>(*o.root_)), source_(o.source_) {}
ConfigDoc& ConfigDoc::operator=(const ConfigDoc& o) {
    root_ = std::make_unique<toml::table>(*o.root_);
    source_ = o.source_;
    return *this;
}

ConfigDoc ConfigDoc::from_file(const std::string& path) {
    check_input_file(path, "config file");
    std::ifstream in(path, std::ios::binary);
    HINF_CHECK(in.good(), "cannot open config file '" + path + "' (check the path and permissions)");
    // at most 1 MiB + 1 bytes: /dev/zero or a multi-GB file must not hang or exhaust memory
    std::string text(kMaxConfigBytes + 1, '\0');
    in.read(text.data(), std::streamsize(text.size()));
    text.resize(std::size_t(in.gcount()));
    HINF_CHECK(!text.empty(), "config file '" + path + "' is empty (see runs/missile_hinf.toml for an example)");
    HINF_CHECK(text.size() <= kMaxConfigBytes,
               "config file '" + path + "' is larger than 1 MiB (is it really a TOML config?)");
    HINF_CHECK(text.find('\0') == std::string::npos,
               "config file '" + path + "' contains NUL bytes: it looks binary, not TOML (pass the .toml file)");
    return from_text(text, path);
}

ConfigDoc ConfigDoc::from_text(const std::string& text, const std::string& source) {
    ConfigDoc doc;
    doc.source_ = source;
    check_nesting(text, source);
    try {
        *doc.root_ = toml::parse(text, source);
    } catch (const toml::parse_error& e) {
        std::string what(e.description());
        HINF_FAIL(source + ":" + std::to_string(e.source().begin.line) + ":" + std::to_string(e.source().begin.column) +
                  ": not valid TOML: " + what + " (fix the syntax at that line)");
    }
    return doc;
}

void ConfigDoc::unset(const std::string& key) {
    const std::size_t dot = key.rfind('.');
    toml::table* t = dot == std::string::npos ? root_.get() : root_->at_path(key.substr(0, dot)).as_table();
    if (t != nullptr) t->erase(key.substr(dot == std::string::npos ? 0 : dot + 1));
}

void ConfigDoc::set(const std::string& assignment) {
    auto eq = assignment.find('=');
    HINF_CHECK(eq != std::string::npos && eq > 0,
               "--set '" + assignment + "' is not of the form section.key=value (e.g. --set training.K=10)");
    std::string key = assignment.substr(0, eq);
    std::string value = assignment.substr(eq + 1);
    toml::table parsed;
    try {
        parsed = toml::parse("v = " + value);
    } catch (const toml::parse_error&) {
        parsed = toml::table{};
        parsed.insert("v", value);  // a bare word: take it as a string
    }
    std::vector<std::string> parts;
    std::stringstream ks(key);
    for (std::string part; std::getline(ks, part, '.');) {
        HINF_CHECK(!part.empty(), "--set '" + assignment + "': empty key segment (write section.key=value)");
        parts.push_back(part);
    }
    toml::table* t = root_.get();
    for (std::size_t i = 0; i + 1 < parts.size(); ++i) {
        toml::node* n = t->get(parts[i]);
        if (!n) {
            t->insert(parts[i], toml::table{});
            n = t->get(parts[i]);
        }
        HINF_CHECK(n->is_table(), "--set '" + assignment + "': '" + parts[i] + "' is not a table in the config");
        t = n->as_table();
    }
    t->insert_or_assign(parts.back(), *parsed.get("v"));
}

std::string ConfigDoc::text() const {
    std::ostringstream ss;
    ss << *root_;
    return ss.str();
}

std::string ConfigDoc::section_text(const std::string& path) const {
    const toml::node* n = root_->get(path);
    if (n == nullptr) return "";
    std::ostringstream ss;
    n->visit([&ss](const auto& node) { ss << node; });  // a table, or whatever stands in its place
    return ss.str();
}

ConfigSection::ConfigSection(const ConfigDoc& doc, const std::string& path) : doc_(doc), path_(path) {
    const toml::node* n = doc.root().get(path);
    if (n) {
        HINF_CHECK(n->is_table(), doc.source() + line_of(*n) + ": '" + path + "' must be a table [" + path + "]");
        table_ = n->as_table();
    }
}

std::string ConfigSection::where(const std::string& key) const {
    std::string line;
    if (table_) {
        if (const toml::node* n = table_->get(key)) line = line_of(*n);
    }
    return doc_.source() + line + ": [" + path_ + "] " + key;
}

void ConfigSection::reject(const std::string& key, const std::string& problem) const {
    HINF_FAIL(where(key) + ": " + problem);
}

bool ConfigSection::has(const std::string& key) const { return table_ && table_->get(key) != nullptr; }

bool ConfigSection::is_list(const std::string& key) const { return has(key) && table_->get(key)->is_array(); }

void ConfigSection::require(const std::string& key, const std::string& problem) const {
    if (has(key)) return;
    std::string near;
    int best = 1 + int(key.size()) / 4;  // a near miss: at most a quarter of the name (at least one edit) off
    if (table_)
        for (const auto& [k, v] : *table_) {
            const int d = edit_distance(std::string(k.str()), key);
            if (d <= best) {
                best = d;
                near = std::string(k.str());
            }
        }
    reject(key, problem + (near.empty() ? "" : " ('" + near + "' is there: did you mean '" + key + "'?)"));
}

double ConfigSection::get_double(const std::string& key, double fallback, double lo, double hi) {
    known_.insert(key);
    if (!has(key)) return fallback;
    const toml::node* n = table_->get(key);
    std::optional<double> v = n->value<double>();
    if (!v || n->is_boolean()) reject(key, "must be a number");
    if (!std::isfinite(*v)) reject(key, "must be finite");
    if (*v < lo || *v > hi) {
        std::ostringstream ss;
        ss << "= " << *v << " is out of range [" << lo << ", " << hi << "]";
        reject(key, ss.str());
    }
    return *v;
}

std::int64_t ConfigSection::get_int(const std::string& key, std::int64_t fallback, std::int64_t lo, std::int64_t hi) {
    known_.insert(key);
    if (!has(key)) return fallback;
    const toml::node* n = table_->get(key);
    if (!n->is_integer()) reject(key, "must be an integer");
    std::int64_t v = *n->value<std::int64_t>();
    if (v < lo || v > hi)
        reject(key, "= " + std::to_string(v) + " is out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    return v;
}

bool ConfigSection::get_bool(const std::string& key, bool fallback) {
    known_.insert(key);
    if (!has(key)) return fallback;
    const toml::node* n = table_->get(key);
    if (!n->is_boolean()) reject(key, "must be true or false");
    return *n->value<bool>();
}

std::string ConfigSection::get_string(const std::string& key, const std::string& fallback,
                                      const std::vector<std::string>& allowed) {
    known_.insert(key);
    if (!has(key)) return fallback;
    const toml::node* n = table_->get(key);
    if (!n->is_string()) reject(key, "must be a string");
    std::string v = *n->value<std::string>();
    if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), v) == allowed.end()) {
        std::string opts;
        for (const auto& a : allowed) opts += (opts.empty() ? "" : ", ") + a;
        reject(key, "= \"" + v + "\" is not one of: " + opts);
    }
    return v;
}

std::vector<double> ConfigSection::get_doubles(const std::string& key, const std::vector<double>& fallback,
                                               int length) {
    known_.insert(key);
    if (!has(key)) return fallback;
    const toml::node* n = table_->get(key);
    if (!n->is_array()) reject(key, "must be a list of numbers, e.g. [1.0, 2.0]");
    const toml::array& a = *n->as_array();
    std::vector<double> out;
    for (const auto& e : a) {
        std::optional<double> v = e.value<double>();
        if (!v || e.is_boolean()) reject(key, "must contain numbers only");
        if (!std::isfinite(*v)) reject(key, "must contain finite numbers only");
        out.push_back(*v);
    }
    if (out.empty()) reject(key, "must not be empty");
    if (length >= 0 && static_cast<int>(out.size()) != length)
        reject(key, "has " + std::to_string(out.size()) + " entries, expected " + std::to_string(length));
    return out;
}

std::vector<std::int64_t> ConfigSection::get_ints(const std::string& key, const std::vector<std::int64_t>& fallback,
                                                  std::int64_t lo, std::int64_t hi) {
    known_.insert(key);
    if (!has(key)) return fallback;
    const toml::node* n = table_->get(key);
    if (!n->is_array()) reject(key, "must be a list of integers, e.g. [256, 128, 32]");
    std::vector<std::int64_t> out;
    for (const auto& e : *n->as_array()) {
        if (!e.is_integer()) reject(key, "must contain integers only");
        std::int64_t v = *e.value<std::int64_t>();
        if (v < lo || v > hi)
            reject(key, "entry " + std::to_string(v) + " is out of range [" + std::to_string(lo) + ", " +
                            std::to_string(hi) + "]");
        out.push_back(v);
    }
    if (out.empty()) reject(key, "must not be empty");
    return out;
}

namespace {

// The text of one list entry: a string as is, a number as its TOML text; anything else is rejected.
bool entry_text(const toml::node& e, std::string* out) {
    if (const auto* s = e.as_string()) {
        *out = s->get();
        return true;
    }
    if (e.is_integer() || e.is_floating_point()) {
        std::ostringstream ss;
        if (const auto* i = e.as_integer())
            ss << *i;
        else
            ss << *e.as_floating_point();
        *out = ss.str();
        return true;
    }
    return false;
}

}  // namespace

std::vector<std::string> ConfigSection::get_strings(const std::string& key, const std::vector<std::string>& fallback,
                                                    int length) {
    known_.insert(key);
    if (!has(key)) return fallback;
    const toml::node* n = table_->get(key);
    if (!n->is_array()) reject(key, "must be a list of strings, e.g. [\"a\", \"b\"]");
    std::vector<std::string> out;
    for (const auto& e : *n->as_array()) {
        std::string text;
        if (!entry_text(e, &text)) reject(key, "must contain strings (or numbers) only");
        out.push_back(text);
    }
    if (out.empty()) reject(key, "must not be empty");
    if (length >= 0 && static_cast<int>(out.size()) != length)
        reject(key, "has " + std::to_string(out.size()) + " entries, expected " + std::to_string(length));
    return out;
}

std::vector<std::vector<std::string>> ConfigSection::get_string_rows(const std::string& key) {
    known_.insert(key);
    std::vector<std::vector<std::string>> out;
    if (!has(key)) return out;
    const toml::node* n = table_->get(key);
    if (!n->is_array()) reject(key, "must be a list of rows, e.g. [[\"0\"], [\"1\"]]");
    for (const auto& e : *n->as_array()) {
        std::vector<std::string> row;
        std::string text;
        if (const toml::array* r = e.as_array()) {
            for (const auto& c : *r) {
                if (!entry_text(c, &text)) reject(key, "must contain strings (or numbers) only");
                row.push_back(text);
            }
        } else if (entry_text(e, &text)) {
            row.push_back(text);
        } else {
            reject(key, "must contain rows of strings (or numbers) only");
        }
        out.push_back(row);
    }
    if (out.empty()) reject(key, "must not be empty");
    return out;
}

std::vector<std::pair<std::string, double>> ConfigSection::get_number_table(const std::string& key) {
    known_.insert(key);
    std::vector<std::pair<std::string, double>> out;
    if (!has(key)) return out;
    const toml::node* n = table_->get(key);
    if (!n->is_table()) reject(key, "must be a table of numbers, e.g. { mu = 1.0, k = 2.0 }");
    for (auto&& [k, v] : *n->as_table()) {
        std::optional<double> d = v.value<double>();
        if (!d || v.is_boolean()) reject(key, "entry '" + std::string(k.str()) + "' must be a number");
        if (!std::isfinite(*d)) reject(key, "entry '" + std::string(k.str()) + "' must be finite");
        out.emplace_back(std::string(k.str()), *d);
    }
    return out;
}

std::vector<std::pair<std::string, std::vector<double>>> ConfigSection::get_column_table(const std::string& key) {
    known_.insert(key);
    std::vector<std::pair<std::string, std::vector<double>>> out;
    if (!has(key)) return out;
    const toml::node* n = table_->get(key);
    if (!n->is_table()) reject(key, "must be a table of equal-length lists of numbers, e.g. { t = [0, 1], u = [2, 3] }");
    for (auto&& [k, v] : *n->as_table()) {
        const std::string name(k.str());
        if (!v.is_array()) reject(key, "entry '" + name + "' must be a list of numbers");
        std::vector<double> column;
        for (const toml::node& e : *v.as_array()) {
            std::optional<double> d = e.value<double>();
            if (!d || e.is_boolean()) reject(key, "entry '" + name + "' must be a list of numbers");
            if (!std::isfinite(*d)) reject(key, "entry '" + name + "' must hold finite numbers only");
            column.push_back(*d);
        }
        if (column.size() < 2) reject(key, "entry '" + name + "' has " + std::to_string(column.size()) + " value(s), at least 2 are needed");
        if (!out.empty() && column.size() != out.front().second.size())
            reject(key, "entry '" + name + "' has " + std::to_string(column.size()) + " values, '" + out.front().first +
                            "' has " + std::to_string(out.front().second.size()) + " (one value per row of the table)");
        out.emplace_back(name, std::move(column));
    }
    return out;
}

std::vector<double> ConfigSection::get_matrix(const std::string& key, const std::vector<double>& fallback, int rows,
                                              int cols) {
    known_.insert(key);
    if (!has(key)) return fallback;
    const toml::node* n = table_->get(key);
    if (!n->is_array()) reject(key, "must be a list of rows [[...], ...] or a diagonal [d1, d2, ...]");
    const toml::array& a = *n->as_array();
    std::vector<double> out(static_cast<std::size_t>(rows) * cols, 0.0);
    bool nested = !a.empty() && a[0].is_array();
    if (!nested) {
        if (rows != cols || static_cast<int>(a.size()) != rows)
            reject(key, "a diagonal must have " + std::to_string(rows) + " entries");
        for (int i = 0; i < rows; ++i) {
            std::optional<double> v = a[i].value<double>();
            if (!v || !std::isfinite(*v)) reject(key, "must contain finite numbers only");
            out[static_cast<std::size_t>(i) * cols + i] = *v;
        }
        return out;
    }
    if (static_cast<int>(a.size()) != rows) reject(key, "must have " + std::to_string(rows) + " rows");
    for (int i = 0; i < rows; ++i) {
        const toml::array* row = a[i].as_array();
        if (!row || static_cast<int>(row->size()) != cols)
            reject(key, "row " + std::to_string(i + 1) + " must have " + std::to_string(cols) + " numbers");
        for (int j = 0; j < cols; ++j) {
            std::optional<double> v = (*row)[j].value<double>();
            if (!v || !std::isfinite(*v)) reject(key, "must contain finite numbers only");
            out[static_cast<std::size_t>(i) * cols + j] = *v;
        }
    }
    return out;
}

void ConfigSection::finish() {
    if (!table_) return;
    for (auto&& [k, v] : *table_) {
        std::string key(k.str());
        if (known_.count(key)) continue;
        std::string hint = nearest(key, known_);
        HINF_FAIL(doc_.source() + line_of(v) + ": [" + path_ + "] unknown key '" + key + "'" +
                  (hint.empty() ? std::string(" (this section takes no keys)")
                                : " (did you mean '" + hint + "'? valid keys: " + list_of(known_) + ")"));
    }
}

void config_check_sections(const ConfigDoc& doc, const std::vector<std::string>& sections) {
    std::set<std::string> known(sections.begin(), sections.end());
    for (auto&& [k, v] : doc.root()) {
        std::string key(k.str());
        if (known.count(key)) continue;
        if (!v.is_table())
            HINF_FAIL(doc.source() + line_of(v) + ": top-level key '" + key +
                      "' must be inside a section (did you mean [" + nearest(key, known) + "]?)");
        HINF_FAIL(doc.source() + line_of(v) + ": unknown section [" + key + "] (did you mean [" + nearest(key, known) +
                  "]? valid sections: " + list_of(known) + ")");
    }
}

}  // namespace hinf
