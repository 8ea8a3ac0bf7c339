// How an error line names an option: the program's flag or the library's argument. The checks in eval/ and filters/
// are shared by `hinf compare`/`hinf worst` and by hinf::compare/hinf::worst (and Python's hinf.compare/worst), so a
// line such as "evals must be >= 1" must name what the caller actually typed.
#pragma once
#include <string>

namespace hinf {

enum class Spelling { program, library };

/// `flag` as the caller spells it: "--random-starts" for the program; "random_starts" for the library, with the two
/// names that differ there: "--mode" is `modes`, "--network" is `networks`; "--set" (a config override) is "the
/// override" (Config::load's overrides).
std::string option_name(const std::string& flag, Spelling s);

}  // namespace hinf
