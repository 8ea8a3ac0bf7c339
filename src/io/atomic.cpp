// Atomic result files (see atomic.hpp).
#include "io/atomic.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "hinf/error.hpp"
#include "par/par.hpp"

namespace hinf {

void sync_path(const std::string& path) {
    int fd = ::open(path.c_str(), O_RDONLY);
    if (fd < 0) return;
    ::fsync(fd);
    ::close(fd);
}

void commit_rename(const std::string& tmp, const std::string& path) {
    sync_path(tmp);
    std::error_code ec;
    std::filesystem::rename(tmp, path, ec);
    HINF_CHECK(!ec, "cannot rename '" + tmp + "' to '" + path + "': " + ec.message());
    const std::string dir = std::filesystem::path(path).parent_path().string();
    sync_path(dir.empty() ? "." : dir);
}

AtomicH5::AtomicH5(std::string path) : path_(std::move(path)), tmp_(path_ + ".tmp") {
    if (par_rank() != 0) {
        // under mpirun every rank computes the same result and rank 0 alone writes it: the others write into
        // memory (HDF5's core driver without a backing store), so the code that fills the file stays one
        h5::Handle fapl(H5Pcreate(H5P_FILE_ACCESS));
        H5Pset_fapl_core(fapl.get(), 1 << 20, 0);
        tmp_ = path_ + ".rank" + std::to_string(par_rank());
        file_ = h5::Handle(H5Fcreate(tmp_.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, fapl.get()));
        HINF_CHECK(file_.valid(), "cannot create an in-memory HDF5 file on rank " + std::to_string(par_rank()));
        in_memory_ = true;
        return;
    }
    file_ = h5::create_file(tmp_);
}

AtomicH5::~AtomicH5() {
    if (committed_ || in_memory_) return;
    file_.reset();
    std::error_code ec;
    std::filesystem::remove(tmp_, ec);
}

void AtomicH5::commit() {
    if (in_memory_) {
        file_.reset();
        committed_ = true;
        return;
    }
    h5::flush(file_.get());
    file_.reset();
    commit_rename(tmp_, path_);
    committed_ = true;
}

void write_text_atomic(const std::string& path, const std::function<void(std::ostream&)>& body) {
    if (par_rank() != 0) {  // rank 0 writes (see AtomicH5)
        std::ostringstream discard;
        body(discard);
        return;
    }
    const std::string tmp = path + ".tmp";
    {
        std::ofstream out(tmp);
        HINF_CHECK(out.good(), "cannot write '" + tmp + "' (check that the output directory exists and is writable)");
        body(out);
        out.close();
        if (out.fail()) {
            std::error_code ec;
            std::filesystem::remove(tmp, ec);
            HINF_CHECK(false, "writing '" + tmp + "' failed (disk full?)");
        }
    }
    commit_rename(tmp, path);
}

}  // namespace hinf
