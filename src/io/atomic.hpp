// Atomic result files: every file hinf writes as a result (operate.h5, compare.h5/.csv, estimates*, lmi,
// bench.h5) is written as PATH.tmp, flushed, fsynced, closed and only then renamed to PATH, and the directory
// is fsynced. A crash at any moment leaves either the previous PATH or the new one, never a half-written PATH.
// Under mpirun only rank 0 (of its group) writes; the other ranks fill the same file in memory and drop it.
// Checkpoints follow the same protocol with a read-back and a kept previous copy (io/checkpoint.hpp).
#pragma once
#include <hdf5.h>

#include <functional>
#include <ostream>
#include <string>

#include "hinf/h5.hpp"

namespace hinf {

/// Forces a file's (or a directory's) contents to disk; a rename is only as durable as what it names.
void sync_path(const std::string& path);

/// Renames tmp to path and fsyncs path's directory; errors name both paths.
void commit_rename(const std::string& tmp, const std::string& path);

/// One HDF5 result file written atomically. Write into get(); commit() closes, fsyncs and renames.
/// Destroyed without commit() (an exception on the way): PATH.tmp is removed and PATH is untouched.
class AtomicH5 {
public:
    explicit AtomicH5(std::string path);
    ~AtomicH5();
    AtomicH5(const AtomicH5&) = delete;
    AtomicH5& operator=(const AtomicH5&) = delete;
    hid_t get() const { return file_.get(); }
    const std::string& path() const { return path_; }
    void commit();

private:
    std::string path_, tmp_;
    h5::Handle file_;
    bool committed_ = false;
    bool in_memory_ = false;  // a rank other than 0 of an MPI job: nothing reaches the disk
};

/// Writes a text file atomically: body writes into the stream; a failed write (disk full) throws naming PATH.
void write_text_atomic(const std::string& path, const std::function<void(std::ostream&)>& body);

}  // namespace hinf
