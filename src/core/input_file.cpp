// The one check every user-supplied input file passes before anything opens it (config, record, HDF5 file,
// checkpoint, network): it must exist, be readable and be a regular file. Not the parsing of any of them.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "hinf/error.hpp"

namespace hinf {

void check_input_file(const std::string& path, const std::string& what) {
    const std::string name = what + " '" + path + "'";
    // O_NONBLOCK: opening a FIFO without a writer must not wait for one; fstat on the open descriptor then
    // judges the very file we would read
    const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        const int err = errno;
        struct stat st {};
        if (::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode))
            HINF_FAIL(name + " is a directory (pass the file inside it)");
        HINF_FAIL("cannot open " + name + ": " + std::strerror(err) + " (check the path and permissions)");
    }
    struct stat st {};
    const int rc = ::fstat(fd, &st);
    ::close(fd);
    HINF_CHECK(rc == 0, "cannot open " + name + " (check the path and permissions)");
    HINF_CHECK(!S_ISDIR(st.st_mode), name + " is a directory (pass the file inside it)");
    const char* kind = S_ISFIFO(st.st_mode)  ? "a FIFO (named pipe)"
                       : S_ISCHR(st.st_mode) ? "a character device"
                       : S_ISBLK(st.st_mode) ? "a block device"
                       : S_ISSOCK(st.st_mode) ? "a socket"
                                              : "not a regular file";
    HINF_CHECK(S_ISREG(st.st_mode), name + " is " + kind +
                                        ", not a regular file: hinf reads inputs from files only (save it to a "
                                        "file first, e.g. cat ... > input.toml)");
}

}  // namespace hinf
