// See isolate.hpp. Why a child: Debian's libhdf5 1.10 can itself crash (use-after-free in H5Aexists,
// found by fuzz/fuzz_checkpoint.cpp) on a damaged object header, and no check of ours runs before it
// parses one. A crash then ends the child, and the user gets one line instead of a segfault.
#include "io/isolate.hpp"

#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <exception>

#include "hinf/error.hpp"

namespace hinf {

namespace {
std::string run_here(const std::function<void()>& fn) {
    try {
        fn();
        return "";
    } catch (const Error& e) {
        return e.what();
    }
}
}  // namespace

std::string run_isolated(const std::function<void()>& fn) {
    int fds[2];
    if (::pipe(fds) != 0) return run_here(fn);
    std::fflush(nullptr);
    pid_t pid = ::fork();
    if (pid == 0) {
        ::close(fds[0]);
        int devnull = ::open("/dev/null", O_WRONLY);  // the message goes through the pipe; a crash report would
        if (devnull >= 0) ::dup2(devnull, 2);          // break the CLI's one-line promise
        int code = 0;
        std::string what;
        try {
            fn();
        } catch (const Error& e) {
            what = e.what();
            code = 3;
        } catch (const std::exception& e) {
            what = std::string("cannot be read: ") + e.what();
            code = 3;
        }
        if (!what.empty() && ::write(fds[1], what.data(), what.size()) < 0) code = 4;
        ::_exit(code);
    }
    ::close(fds[1]);
    if (pid < 0) {
        ::close(fds[0]);
        return run_here(fn);
    }
    std::string msg;
    char buf[4096];
    for (ssize_t n; (n = ::read(fds[0], buf, sizeof buf)) > 0;) msg.append(buf, std::size_t(n));
    ::close(fds[0]);
    int st = 0;
    ::waitpid(pid, &st, 0);
    if (WIFEXITED(st) && WEXITSTATUS(st) == 0) return "";
    if (WIFEXITED(st) && WEXITSTATUS(st) == 3 && !msg.empty()) return msg;
    return "the file is damaged: reading it crashed the HDF5 library (" +
           (WIFSIGNALED(st) ? "signal " + std::to_string(WTERMSIG(st)) : "status " + std::to_string(WEXITSTATUS(st))) +
           ")";
}

}  // namespace hinf
