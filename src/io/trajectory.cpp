// Trajectory file writer (see trajectory.hpp).
#include "io/trajectory.hpp"

#include <filesystem>

#include "hinf/error.hpp"
#include "io/atomic.hpp"

namespace hinf {

namespace {

std::string snapshot_name(const std::string& path) {
    std::string base = path;
    if (base.size() > 3 && base.compare(base.size() - 3, 3, ".h5") == 0) base.resize(base.size() - 3);
    return base + ".ckpt.h5";
}

// Rows in the snapshot, or -1 when it is missing or unreadable (then the live file is used).
long long snapshot_rows(const std::string& snap) {
    if (!std::filesystem::exists(snap)) return -1;
    try {
        h5::Handle f = h5::open_file(snap, false);
        std::vector<hsize_t> dims;
        h5::read_doubles(f.get(), "t", &dims);
        return dims.empty() ? -1 : static_cast<long long>(dims[0]);
    } catch (const Error&) {
        return -1;
    }
}

void copy_replace(const std::string& from, const std::string& to) {
    std::error_code ec;
    std::filesystem::copy_file(from, to + ".tmp", std::filesystem::copy_options::overwrite_existing, ec);
    HINF_CHECK(!ec, "cannot copy '" + from + "' to '" + to + ".tmp': " + ec.message() + " (disk full?)");
    commit_rename(to + ".tmp", to);
}

}  // namespace

TrajectoryWriter TrajectoryWriter::create(const std::string& path, const std::vector<TrajectoryColumn>& columns,
                                          const std::map<std::string, std::string>& attrs) {
    TrajectoryWriter w;
    w.path_ = path;
    w.file_ = h5::create_file(path);
    w.columns_ = columns;
    for (const auto& [k, v] : attrs) h5::set_text(w.file_.get(), k, v);  // a large config becomes a dataset
    for (const auto& c : columns)
        w.writers_.push_back(h5::RowWriter::create(w.file_.get(), c.name, hsize_t(c.width), c.units, c.meaning));
    h5::flush(w.file_.get());
    return w;
}

TrajectoryWriter TrajectoryWriter::reopen(const std::string& path, const std::vector<TrajectoryColumn>& columns,
                                          hsize_t rows, const std::map<std::string, std::string>& expect) {
    const std::string snap = snapshot_name(path);
    if (snapshot_rows(snap) >= static_cast<long long>(rows)) copy_replace(snap, path);
    TrajectoryWriter w;
    w.path_ = path;
    w.file_ = h5::open_file(path, true);
    // bound to its checkpoint: another run's trajectory beside it must not be spliced and relabelled
    for (const auto& [k, v] : expect)
        HINF_CHECK(h5::has_text(w.file_.get(), k) && h5::get_text(w.file_.get(), k) == v,
                   "trajectory '" + path + "' belongs to another run (its '" + k + "' differs from the checkpoint's): "
                   "keep each run's trajectory.h5 beside its own checkpoint.h5, or start afresh with hinf train --force");
    w.columns_ = columns;
    for (const auto& c : columns) {
        w.writers_.push_back(h5::RowWriter::open_truncated(w.file_.get(), c.name, rows));
        HINF_CHECK(w.writers_.back().cols() == hsize_t(c.width),
                   "trajectory '" + path + "': column '" + c.name + "' has the wrong width");
    }
    return w;
}

void TrajectoryWriter::set_text(const std::string& name, const std::string& value) {
    h5::set_text(file_.get(), name, value);
}

void TrajectoryWriter::append(const std::map<std::string, std::vector<double>>& values) {
    for (std::size_t i = 0; i < columns_.size(); ++i) {
        auto it = values.find(columns_[i].name);
        HINF_CHECK(it != values.end() && int(it->second.size()) == columns_[i].width,
                   "internal: trajectory row lacks column '" + columns_[i].name + "'");
        writers_[i].append(it->second.data());
    }
}

void TrajectoryWriter::flush() { h5::flush(file_.get()); }

void TrajectoryWriter::snapshot() {
    flush();
    copy_replace(path_, snapshot_name(path_));
}

}  // namespace hinf
