// libFuzzer target over the config reader: TOML text -> ConfigDoc -> load_run_config (every key's
// type, range and consistency checks). Any input must end in a RunConfig or a hinf::Error; a crash,
// a sanitizer report, another exception type or a hang is a bug. Corpus: tests/corpus/fuzz_config.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include <toml++/toml.h>

#include "hinf/config.hpp"
#include "hinf/error.hpp"
#include "config/run_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size > 4096) return 0;  // the reader caps files at 1 MiB; long inputs only slow the search
    std::string text(reinterpret_cast<const char*>(data), size);
    try {
        hinf::ConfigDoc doc = hinf::ConfigDoc::from_text(text, "fuzz.toml");
        // A config that names no rho gets rho* at load: the linearised game integrated over the whole horizon
        // (config/game_level.cpp), real work that grows with the steps. The missile written as expressions over
        // 7000 steps takes 0.8 s in Release and 14 s under ASan, past the fuzzer's 20 s timeout once instrumented
        // (found by CI's run of 2026-11-29). No check of the reader depends on the horizon's length, so a valid
        // horizon is cut to 300 steps here (3 s for that missile under the instrumented ASan build).
        if (toml::table* f = doc.root()["filter"].as_table()) {
            const std::optional<double> dt = (*f)["dt"].value<double>(), T = (*f)["t_final"].value<double>();
            const double step = dt && *dt > 0 && std::isfinite(*dt) ? *dt : 0.01;  // 0.01: the default dt
            if (T && std::isfinite(*T) && *T > 300.0 * step) f->insert_or_assign("t_final", 300.0 * step);
        }
        hinf::RunConfig cfg = hinf::load_run_config(std::move(doc));
        (void)cfg;
    } catch (const hinf::Error&) {
    }
    return 0;
}
