// libFuzzer target over the checkpoint loader. The input is a checkpoint file's bytes; it is written
// to a private file and loaded with ckpt_verify / ckpt_read / ckpt_frozen_network. Any input must
// end in a loaded checkpoint or a hinf::Error. Corpus: tests/corpus/fuzz_checkpoint (real
// checkpoints of a tiny run, so that mutations reach the loader's own checks past HDF5's parser).
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

#include "hinf/error.hpp"
#include "io/checkpoint.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size > 1 << 20) return 0;
    static const std::string path = "/tmp/hinf-fuzz-checkpoint-" + std::to_string(::getpid()) + ".h5";
    FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return 0;
    std::fwrite(data, 1, size, f);
    std::fclose(f);
    try {
        hinf::ckpt_verify(path);
        hinf::RunConfig cfg;
        auto net = hinf::ckpt_frozen_network(path, &cfg);
        (void)net;
    } catch (const hinf::Error&) {
    }
    std::remove(path.c_str());
    return 0;
}
