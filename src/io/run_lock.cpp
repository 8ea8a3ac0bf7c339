// The run-directory lock (see run_lock.hpp).
#include "io/run_lock.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>

#include "hinf/error.hpp"
#include "io/run_swap.hpp"
#include "par/par.hpp"

namespace hinf {

namespace {
// the directories this process holds the lock of, and how many RunDirLocks hold each (flock(2) locks belong to an
// open file: a second open and flock of the same file in this process would be refused as another's)
std::mutex held_mutex;
std::map<std::string, int>& held() {
    static std::map<std::string, int> table;
    return table;
}

std::string own_command_line() {
    std::ifstream in("/proc/self/cmdline", std::ios::binary);
    std::string raw((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>()), out;
    for (char c : raw) out += c == '\0' ? ' ' : c;
    while (!out.empty() && out.back() == ' ') out.pop_back();
    return out.size() > 300 ? out.substr(0, 300) + "..." : out;
}
}  // namespace

RunDirLock::RunDirLock(const std::string& dir, const std::string& command) {
    if (!par_root()) return;  // one writer per run: the other ranks never open anything there for writing
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    HINF_CHECK(!ec, "cannot create the output directory '" + dir + "': " + ec.message() +
                        " (check the path and permissions, or pass another --out)");
    const std::filesystem::path canonical = std::filesystem::weakly_canonical(dir, ec);
    const std::string key = ec ? dir : canonical.string();
    const std::lock_guard<std::mutex> guard(held_mutex);
    if (auto it = held().find(key); it != held().end()) {  // nested in this process's own hold of DIR
        ++it->second;
        key_ = key;
        return;
    }
    const std::string path = dir + "/.hinf.lock";
    fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    HINF_CHECK(fd_ >= 0, "cannot create the lock file '" + path + "': " + std::strerror(errno) +
                             " (is the output directory writable? pass another --out)");
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
        const int err = errno;
        char buf[512] = {0};
        const ssize_t got = ::pread(fd_, buf, sizeof buf - 1, 0);
        ::close(fd_);
        fd_ = -1;
        std::string holder = got > 0 ? std::string(buf, std::size_t(got)) : std::string("unknown");
        while (!holder.empty() && (holder.back() == '\n' || holder.back() == ' ')) holder.pop_back();
        HINF_CHECK(err != EWOULDBLOCK, "'" + dir + "' is in use by another hinf process (" + holder + "); " +
                                           command + " writes there too: wait for it to finish, or pass another --out");
        HINF_FAIL("cannot lock '" + path + "': " + std::strerror(err) + " (a file system without flock? pass another --out)");
    }
    std::ostringstream who;
    who << "pid " << ::getpid() << ": " << own_command_line() << "\n";
    const std::string text = who.str();
    if (::ftruncate(fd_, 0) == 0) {
        const ssize_t wrote = ::pwrite(fd_, text.data(), text.size(), 0);
        (void)wrote;  // the holder's description is for messages only; the flock is the lock
    }
    // two runs' exchange a kill interrupted (eval/acceptance.cpp swap_runs): finished before anything else is done
    // here; where it cannot be (a damaged journal), the lock is dropped with the error (no destructor runs)
    std::string alt;
    try {
        alt = finish_interrupted_swap(dir);
    } catch (...) {
        ::close(fd_);
        fd_ = -1;
        throw;
    }
    held()[key] = 1;
    key_ = key;
    if (!alt.empty())
        std::fprintf(stderr, "hinf: note: %s held two runs being exchanged with %s when a process was killed; the "
                             "exchange is finished: %s holds the run that was kept, %s the other (docs/reliability.md)\n",
                     dir.c_str(), alt.c_str(), dir.c_str(), alt.c_str());
}

RunDirLock::~RunDirLock() {
    if (key_.empty()) return;
    const std::lock_guard<std::mutex> guard(held_mutex);
    if (auto it = held().find(key_); it != held().end() && --it->second == 0) held().erase(it);
    if (fd_ >= 0) ::close(fd_);  // closing drops the flock
}

}  // namespace hinf
