// The journalled exchange of two runs' files (see run_swap.hpp).
#include "io/run_swap.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>

#include "hinf/error.hpp"
#include "io/atomic.hpp"

namespace hinf {

namespace {

namespace fs = std::filesystem;

// every entry of `names` still in `from` renamed into `to` (a rename is atomic: each entry is on one side)
void move_entries(const fs::path& from, const fs::path& to, const std::vector<std::string>& names) {
    for (const std::string& name : names) {
        std::error_code ec;
        if (fs::symlink_status(from / name, ec).type() != fs::file_type::not_found && !ec)
            fs::rename(from / name, to / name);
    }
}

void write_journal(const fs::path& folder, int phase, const std::string& alt, const std::vector<std::string>& names) {
    write_text_atomic((folder / kSwapJournal).string(), [&](std::ostream& out) {
        out << "phase " << phase << "\n" << alt << "\n";
        for (const std::string& name : names) out << name << "\n";
    });
}

// the phases from `phase` on, each journalled before its first move; the folder removed at the end
void run_phases(const fs::path& dir, const std::string& alt, int phase, const std::vector<std::string>& names) {
    const fs::path folder = dir / kSwapFolder;
    if (phase <= 1) {
        move_entries(dir, folder, names);
        write_journal(folder, 2, alt, names);
    }
    if (phase <= 2) {
        move_entries(alt, dir, names);
        write_journal(folder, 3, alt, names);
    }
    move_entries(folder, alt, names);
    fs::remove_all(folder);  // the journal (and a journal's temporary file a kill left): every entry has moved out
}

}  // namespace

std::string finish_interrupted_swap(const std::string& dir) {
    const fs::path folder = fs::path(dir) / kSwapFolder;
    std::error_code ec;
    if (!fs::exists(folder, ec)) return "";
    const fs::path journal = folder / kSwapJournal;
    if (!fs::exists(journal, ec)) {  // killed before the first move: at most a journal's temporary file inside
        fs::remove_all(folder);
        return "";
    }
    std::ifstream in(journal);
    std::string line, alt;
    int phase = 0;
    std::vector<std::string> names;
    if (std::getline(in, line)) std::istringstream(line.size() > 6 ? line.substr(6) : "") >> phase;
    const bool read = line.rfind("phase ", 0) == 0 && phase >= 1 && phase <= 3 && std::getline(in, alt) && !alt.empty();
    for (std::string name; read && std::getline(in, name);)
        if (!name.empty()) names.push_back(name);
    HINF_CHECK(read && !names.empty(),
               "'" + journal.string() + "' is damaged: a swap of two runs was interrupted there and cannot be finished; "
               "move the entries in '" + folder.string() + "' back into '" + dir + "' by hand, then remove the folder");
    run_phases(dir, alt, phase, names);
    return alt;
}

void swap_entries(const std::string& dir, const std::string& alt, const std::vector<std::string>& names) {
    finish_interrupted_swap(dir);
    const fs::path folder = fs::path(dir) / kSwapFolder;
    fs::create_directories(folder);
    const std::string where = fs::absolute(alt).string();  // a later process may run from another directory
    write_journal(folder, 1, where, names);
    run_phases(dir, where, 1, names);
}

}  // namespace hinf
