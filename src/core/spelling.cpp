#include "core/spelling.hpp"

namespace hinf {

std::string option_name(const std::string& flag, Spelling s) {
    if (s == Spelling::program) return flag;
    if (flag == "--mode") return "modes";
    if (flag == "--network") return "networks";
    if (flag == "--set") return "the override";
    std::string name = flag.rfind("--", 0) == 0 ? flag.substr(2) : flag;
    for (char& ch : name)
        if (ch == '-') ch = '_';
    return name;
}

}  // namespace hinf
