// Atomic result files (see atomic.hpp).
#include "io/atomic.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "hinf/error.hpp"

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
    file_ = h5::create_file(tmp_);
}

AtomicH5::~AtomicH5() {
    if (committed_) return;
    file_.reset();
    std::error_code ec;
    std::filesystem::remove(tmp_, ec);
}

void AtomicH5::commit() {
    h5::flush(file_.get());
    file_.reset();
    commit_rename(tmp_, path_);
    committed_ = true;
}

void write_text_atomic(const std::string& path, const std::function<void(std::ostream&)>& body) {
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
