// hinf::fail_at: formats a user-facing error with its source location.
#include "hinf/error.hpp"

#include <cstring>

namespace hinf {

void fail_at(const std::string& message, const char* file, int line) {
    const char* base = std::strrchr(file, '/');
    throw Error(message + " [" + (base ? base + 1 : file) + ":" + std::to_string(line) + "]");
}

}  // namespace hinf
