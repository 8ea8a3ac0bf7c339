// Trajectory file writer (see trajectory.hpp).
#include "io/trajectory.hpp"

#include "hinf/error.hpp"

namespace hinf {

TrajectoryWriter TrajectoryWriter::create(const std::string& path, const std::vector<TrajectoryColumn>& columns,
                                          const std::map<std::string, std::string>& attrs) {
    TrajectoryWriter w;
    w.file_ = h5::create_file(path);
    w.columns_ = columns;
    for (const auto& [k, v] : attrs) h5::set_attr(w.file_.get(), k, v);
    for (const auto& c : columns)
        w.writers_.push_back(h5::RowWriter::create(w.file_.get(), c.name, hsize_t(c.width), c.units, c.meaning));
    h5::flush(w.file_.get());
    return w;
}

TrajectoryWriter TrajectoryWriter::reopen(const std::string& path, const std::vector<TrajectoryColumn>& columns,
                                          hsize_t rows) {
    TrajectoryWriter w;
    w.file_ = h5::open_file(path, true);
    w.columns_ = columns;
    for (const auto& c : columns) {
        w.writers_.push_back(h5::RowWriter::open_truncated(w.file_.get(), c.name, rows));
        HINF_CHECK(w.writers_.back().cols() == hsize_t(c.width),
                   "trajectory '" + path + "': column '" + c.name + "' has the wrong width");
    }
    return w;
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

}  // namespace hinf
