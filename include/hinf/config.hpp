// Reading TOML configuration with every key checked: type, range, and no unknown keys.
// Not the meaning of the keys: each module reads its own section (see docs/formats.md).
#pragma once
#include <cstdint>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace toml {
inline namespace v3 {
class table;
}
}  // namespace toml

namespace hinf {

/// A parsed TOML document plus its source name, with `--set key=value` overrides applied.
/// text() is the effective configuration (stored in checkpoints and result files).
class ConfigDoc {
public:
    /// Parses a file; throws hinf::Error naming the file and line on any problem
    /// (missing, unreadable, empty, binary, over 1 MiB, or not TOML).
    static ConfigDoc from_file(const std::string& path);
    /// Parses TOML text; `source` names it in error messages.
    static ConfigDoc from_text(const std::string& text, const std::string& source);
    ConfigDoc();
    ~ConfigDoc();
    ConfigDoc(ConfigDoc&&) noexcept;
    ConfigDoc& operator=(ConfigDoc&&) noexcept;
    ConfigDoc(const ConfigDoc&);
    ConfigDoc& operator=(const ConfigDoc&);

    /// Applies "section.key=value"; value is TOML (1e-3, true, "text", [1, 2]) or a bare string.
    void set(const std::string& assignment);
    /// Removes "section.key" (dotted, as set names it); nothing where it is not there.
    void unset(const std::string& key);
    std::string text() const;
    /// The TOML text of one top-level table ("system"), "" where the document has none.
    std::string section_text(const std::string& path) const;
    const std::string& source() const { return source_; }
    toml::table& root() { return *root_; }
    const toml::table& root() const { return *root_; }

private:
    std::unique_ptr<toml::table> root_;
    std::string source_;
};

/// One table of the config. Every get_* marks the key as known; finish() rejects any key that was
/// not asked for, suggesting the nearest known key.
class ConfigSection {
public:
    /// `path` is the dotted name ("training"); a missing table reads as empty (all defaults).
    ConfigSection(const ConfigDoc& doc, const std::string& path);
    ConfigSection(const ConfigSection&) = delete;
    ConfigSection& operator=(const ConfigSection&) = delete;

    bool has(const std::string& key) const;
    /// true where the key is there and holds a list.
    bool is_list(const std::string& key) const;
    double get_double(const std::string& key, double fallback, double lo, double hi);
    std::int64_t get_int(const std::string& key, std::int64_t fallback, std::int64_t lo, std::int64_t hi);
    bool get_bool(const std::string& key, bool fallback);
    std::string get_string(const std::string& key, const std::string& fallback,
                           const std::vector<std::string>& allowed = {});
    /// A list of numbers; `length` < 0 accepts any non-empty length.
    std::vector<double> get_doubles(const std::string& key, const std::vector<double>& fallback, int length = -1);
    std::vector<std::int64_t> get_ints(const std::string& key, const std::vector<std::int64_t>& fallback,
                                       std::int64_t lo, std::int64_t hi);
    /// A list of texts (strings; numbers are taken as their TOML text, e.g. 0 -> "0"); `length` < 0: any length >= 1.
    std::vector<std::string> get_strings(const std::string& key, const std::vector<std::string>& fallback,
                                         int length = -1);
    /// A list of rows of texts ([["a", "b"], ["c", 0]]); a flat list reads as rows of one entry each.
    std::vector<std::vector<std::string>> get_string_rows(const std::string& key);
    /// A table of named numbers ({ mu = 1.0, k = 2 } or a [section.key] sub-table), sorted by name.
    std::vector<std::pair<std::string, double>> get_number_table(const std::string& key);
    /// A table of named lists of finite numbers, all of one length >= 2 ({ t = [0, 1], u = [2, 3] }), sorted by name.
    std::vector<std::pair<std::string, std::vector<double>>> get_column_table(const std::string& key);
    /// A square matrix given as a list of rows, or a list of n numbers for a diagonal.
    std::vector<double> get_matrix(const std::string& key, const std::vector<double>& fallback, int rows, int cols);
    /// Throws on keys never asked for. Call once after all get_*.
    void finish();
    /// "file.toml: [training] M" style prefix for messages about a key.
    std::string where(const std::string& key) const;
    /// Throws a hinf::Error "<where(key)>: <problem>".
    [[noreturn]] void reject(const std::string& key, const std::string& problem) const;
    /// For a required key: when it is missing, rejects it with `problem`, adding "did you mean" when a key
    /// present in the table is a near miss of it ("measurement = 1" for "measurements").
    void require(const std::string& key, const std::string& problem) const;

private:
    const ConfigDoc& doc_;
    std::string path_;
    const toml::table* table_ = nullptr;
    std::set<std::string> known_;
};

/// Rejects any top-level table not in `sections`, suggesting the nearest.
void config_check_sections(const ConfigDoc& doc, const std::vector<std::string>& sections);

/// Levenshtein distance, for "did you mean" hints.
int edit_distance(const std::string& a, const std::string& b);

}  // namespace hinf
