// Errors at module boundaries (config, files, shapes): one line saying what, where and how to fix.
// Not for numerical trouble inside a training step: that is a returned status (see train/driver.hpp).
#pragma once
#include <stdexcept>
#include <string>

namespace hinf {

/// An error a user can act on. what() is one line: "<what is wrong> (<how to fix>) [source.cpp:line]".
/// The CLI prints it after "hinf: error: " and exits with status 2.
class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// Throws hinf::Error with the message and the source location appended.
[[noreturn]] void fail_at(const std::string& message, const char* file, int line);

/// The check every user-supplied input passes before it is opened (src/core/input_file.cpp): it exists, is
/// readable and is a regular file. A FIFO, device, socket or directory gives one line naming it and `what`
/// ("config file", "checkpoint", "measurements", ...) instead of a read that blocks forever.
void check_input_file(const std::string& path, const std::string& what);

}  // namespace hinf

/// Always-on check at a module boundary (stays on in Release builds).
#define HINF_CHECK(cond, message)                                \
    do {                                                         \
        if (!(cond)) ::hinf::fail_at((message), __FILE__, __LINE__); \
    } while (0)
#define HINF_FAIL(message) ::hinf::fail_at((message), __FILE__, __LINE__)
