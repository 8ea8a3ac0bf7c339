// The training trajectory file: one row per time step in extendible, chunked HDF5 datasets,
// flushed at every checkpoint so a crash loses at most the rows since. Layout: docs/formats.md.
#pragma once
#include <map>
#include <string>
#include <vector>

#include "hinf/h5.hpp"

namespace hinf {

struct TrajectoryColumn {
    std::string name;
    int width;
    std::string units, meaning;
};

class TrajectoryWriter {
public:
    /// Creates `path` with the given columns; `attrs` become root attributes.
    static TrajectoryWriter create(const std::string& path, const std::vector<TrajectoryColumn>& columns,
                                   const std::map<std::string, std::string>& attrs);
    /// Reopens `path` and cuts every column to `rows` rows (continuing after a checkpoint). When the
    /// snapshot `<path minus .h5>.ckpt.h5` holds at least `rows` rows it replaces `path` first: a
    /// process killed mid-append can leave the live file's HDF5 metadata half-written. Every attribute in
    /// `expect` must hold the given value (the checkpoint's config: a trajectory of another run is refused).
    static TrajectoryWriter reopen(const std::string& path, const std::vector<TrajectoryColumn>& columns,
                                   hsize_t rows, const std::map<std::string, std::string>& expect = {});
    /// Appends one row: values[name] must hold `width` numbers for every column.
    void append(const std::map<std::string, std::vector<double>>& values);
    void flush();
    /// Replaces the root text `name` (an attribute, or a dataset when long: h5::set_text).
    void set_text(const std::string& name, const std::string& value);
    /// Flushes, then copies the file to its snapshot name (temporary + rename): called at every
    /// checkpoint, before the checkpoint itself is renamed into place.
    void snapshot();

private:
    std::string path_;
    h5::Handle file_;
    std::vector<TrajectoryColumn> columns_;
    std::vector<h5::RowWriter> writers_;
};

}  // namespace hinf
