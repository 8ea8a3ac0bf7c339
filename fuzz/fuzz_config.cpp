// libFuzzer target over the config reader: TOML text -> ConfigDoc -> load_run_config (every key's
// type, range and consistency checks). Any input must end in a RunConfig or a hinf::Error; a crash,
// a sanitizer report, another exception type or a hang is a bug. Corpus: tests/corpus/fuzz_config.
#include <cstddef>
#include <cstdint>
#include <string>

#include "hinf/config.hpp"
#include "hinf/error.hpp"
#include "config/run_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size > 4096) return 0;  // the reader caps files at 1 MiB; long inputs only slow the search
    std::string text(reinterpret_cast<const char*>(data), size);
    try {
        hinf::ConfigDoc doc = hinf::ConfigDoc::from_text(text, "fuzz.toml");
        hinf::RunConfig cfg = hinf::load_run_config(std::move(doc));
        (void)cfg;
    } catch (const hinf::Error&) {
    }
    return 0;
}
