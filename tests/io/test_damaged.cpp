// `hinf resume` on damaged checkpoints: truncated, emptied, a flipped bit in the weights, another
// format version, an edited config, missing parts; each gives one line naming the file and the
// problem, exit 2, and points at the previous checkpoint when that one is good.
#include <sys/stat.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>

#include "helpers.hpp"
#include "hinf/h5.hpp"
#include "io/checkpoint.hpp"
#include "train/trainer.hpp"

using namespace hinf;
namespace fs = std::filesystem;

namespace {

const char* kSmall = R"([system]
kind = "missile"
[filter]
t_final = 0.08
[network]
hidden = [16, 8]
chunk = 30
[training]
samples = 100
batch = 40
adam_steps = 2
checkpoint_every = 4
)";

// A run with checkpoint.h5 (step 8) and checkpoint.prev.h5 (step 4) in dir.
void make_run(const std::string& dir) {
    TrainOptions opt;
    opt.out_dir = dir;
    opt.quiet = true;
    TrainSummary s = train_start(load_run_config(ConfigDoc::from_text(kSmall, "small.toml")), opt);
    REQUIRE(s.status == 0);
    REQUIRE(fs::exists(dir + "/checkpoint.prev.h5"));
}

std::string read_bytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}
void write_bytes(const std::string& path, const std::string& bytes) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

using hinf::test::count_lines;

// hinf resume <ckpt>: one line "hinf: error: ..." naming the file, with the fragment; exit 2.
void expect_resume_error(const std::string& ckpt, const std::string& fragment, bool suggests_prev) {
    auto r = test::run_command("timeout 60 " + std::string(HINF_CLI_PATH) + " resume " + ckpt + " --quiet");
    INFO("hinf resume " << ckpt << "\n" << r.output);
    CHECK(r.status == 2);
    CHECK(r.output.rfind("hinf: error: ", 0) == 0);
    CHECK(count_lines(r.output) == 1);
    CHECK(r.output.find(ckpt) != std::string::npos);
    CHECK(r.output.find(fragment) != std::string::npos);
    const bool suggested = r.output.find("the previous checkpoint is good: hinf resume ") != std::string::npos;
    CHECK(suggested == suggests_prev);
}

}  // namespace

TEST_CASE("resume from each kind of damaged checkpoint gives its message", "[errors][checkpoint]") {
    test::TempDir d("damaged");
    const std::string dir = d / "run", ck = dir + "/checkpoint.h5", prev = dir + "/checkpoint.prev.h5";
    make_run(dir);
    const std::string good = read_bytes(ck);
    const std::string good_prev = read_bytes(prev);
    auto restore = [&] {
        write_bytes(ck, good);
        write_bytes(prev, good_prev);
    };

    SECTION("truncated to half") {
        write_bytes(ck, good.substr(0, good.size() / 2));
        expect_resume_error(ck, "truncated", true);
    }
    SECTION("emptied") {
        write_bytes(ck, "");
        expect_resume_error(ck, "is not an HDF5 file", true);
    }
    SECTION("missing, with the previous checkpoint beside it") {
        fs::remove(ck);
        expect_resume_error(ck, "cannot open", true);
    }
    SECTION("a flipped bit in the first layer's weights (fletcher32)") {
        Checkpoint<float> c = ckpt_read<float>(ck);
        const std::int64_t nw = std::int64_t(c.net.step.shape.sizes[0]) * c.net.step.shape.sizes[1];
        std::string w(reinterpret_cast<const char*>(c.net.theta.data()), std::size_t(nw) * sizeof(float));
        std::size_t at = good.find(w);
        REQUIRE(at != std::string::npos);
        std::string bad = good;
        bad[at + 13] = char(bad[at + 13] ^ 0x10);
        write_bytes(ck, bad);
        expect_resume_error(ck, "checksum mismatch", true);
    }
    SECTION("another format version") {
        {
            h5::Handle f = h5::open_file(ck, true);
            h5::set_attr(f.get(), "format_version", std::int64_t(99));
        }
        expect_resume_error(ck, "has format version 99", true);
    }
    SECTION("config edited after writing (hash mismatch)") {
        {
            h5::Handle f = h5::open_file(ck, true);
            std::string text = h5::read_string(f.get(), "config");
            H5Ldelete(f.get(), "config", H5P_DEFAULT);
            h5::write_string(f.get(), "config", text + "\n# edited\n");
        }
        expect_resume_error(ck, "does not match its hash", true);
    }
    SECTION("config of another network (hash updated)") {
        {
            h5::Handle f = h5::open_file(ck, true);
            std::string text = h5::read_string(f.get(), "config");
            std::size_t at = text.find("16, 8");
            REQUIRE(at != std::string::npos);
            text.replace(at, 5, "12, 8");
            H5Ldelete(f.get(), "config", H5P_DEFAULT);
            h5::write_string(f.get(), "config", text);
            h5::set_attr(f.get(), "config_hash", config_hash(text));
        }
        expect_resume_error(ck, "network sizes do not match its config", true);
    }
    SECTION("Adam state removed") {
        {
            h5::Handle f = h5::open_file(ck, true);
            H5Ldelete(f.get(), "adam", H5P_DEFAULT);
        }
        expect_resume_error(ck, "group 'adam' is missing", true);
    }
    SECTION("Adam moment of the wrong size") {
        {
            h5::Handle f = h5::open_file(ck, true);
            h5::Handle adam(H5Gopen2(f.get(), "adam", H5P_DEFAULT));
            H5Ldelete(adam.get(), "m", H5P_DEFAULT);
            std::vector<float> m(7, 0.0f);
            h5::write_floats(adam.get(), "m", m.data(), {7}, "", "", true);
        }
        expect_resume_error(ck, "Adam moments have the wrong size", true);
    }
    SECTION("a trajectory file passed as the checkpoint") {
        expect_resume_error(dir + "/trajectory.h5", "is not a hinf checkpoint", false);
    }
    SECTION("both checkpoints damaged: no suggestion") {
        write_bytes(ck, good.substr(0, good.size() / 3));
        write_bytes(prev, good_prev.substr(0, 100));
        expect_resume_error(ck, "truncated", false);
    }
    SECTION("the suggested previous checkpoint resumes") {
        write_bytes(ck, good.substr(0, good.size() / 2));
        auto r = test::run_command("timeout 60 " + std::string(HINF_CLI_PATH) + " resume " + prev + " --quiet");
        INFO(r.output);
        CHECK(r.status == 0);
        CHECK(r.output.find("trained time steps 4..8") != std::string::npos);
        ckpt_verify(ck);  // the resumed run rewrote a good checkpoint.h5
    }
    restore();
}

// A process does not read again in a child a checkpoint it has seen read cleanly (io/checkpoint.cpp), but only while
// every byte is the same: the same file damaged in place, its size kept, is read in a child again and refused.
TEST_CASE("a checkpoint this process wrote is checked again once a byte of it changed", "[io][damaged]") {
    test::TempDir d("damaged-in-place");
    make_run(d / "run");  // in this process: checkpoint.h5 was written and read back here
    const std::string ck = d / "run/checkpoint.h5";
    ckpt_verify(ck);
    const std::string good = read_bytes(ck);
    std::string bad = good;
    for (std::size_t i = bad.size() / 3; i < 2 * bad.size() / 3; ++i) bad[i] = 0;
    REQUIRE(bad.size() == good.size());
    struct stat before {}, after {};
    REQUIRE(::stat(ck.c_str(), &before) == 0);
    write_bytes(ck, bad);  // in place: the same inode and size
    REQUIRE(::stat(ck.c_str(), &after) == 0);
    CHECK(after.st_ino == before.st_ino);
    CHECK(after.st_size == before.st_size);
    CHECK_THROWS_AS(ckpt_verify(ck), hinf::Error);
    write_bytes(ck, good);
    ckpt_verify(ck);
}

// Edited, not damaged: every checksum is valid (HDF5 recomputes fletcher32 on write), but the file no longer is
// what it claims. The step is stored three times and every value is bound by the content digest; a non-finite
// weight is refused on load by resume and by operate (which would otherwise run the open-loop predictor).
TEST_CASE("checkpoints edited after writing are refused", "[io][damaged][edited]") {
    test::TempDir d("edited");
    make_run(d / "run");
    const std::string ckpt = d / "run/checkpoint.h5", cfg = d / "small.toml";
    std::ofstream(cfg) << kSmall;
    const std::string saved = read_bytes(ckpt);
    auto replace_weight = [&](float value) {
        h5::Handle f = h5::open_file(ckpt, true);
        h5::Handle g = h5::open_group(f.get(), "network/layer_1");
        std::vector<hsize_t> dims;
        std::vector<float> w = h5::read_floats(g.get(), "W", &dims);
        w[3] = value;
        REQUIRE(H5Ldelete(g.get(), "W", H5P_DEFAULT) >= 0);
        h5::write_floats(g.get(), "W", w.data(), dims, "", "weights", true);
    };
    SECTION("the root step relabelled") {
        {
            h5::Handle f = h5::open_file(ckpt, true);
            REQUIRE(H5Adelete(f.get(), "step") >= 0);
            h5::set_attr(f.get(), "step", std::int64_t(5));
        }
        expect_resume_error(ckpt, "its step attributes disagree (root 5, state 8)", true);
    }
    SECTION("a weight replaced by NaN, checksum recomputed") {
        replace_weight(NAN);
        expect_resume_error(ckpt, "network weight[3] = nan is not finite", true);
        auto r = test::run_command("timeout 60 " + std::string(HINF_CLI_PATH) + " operate " + cfg + " --network " +
                                   ckpt + " --runs 1 --until 0.05 --out " + (d / "op"));
        INFO(r.output);
        CHECK(r.status == 2);
        CHECK(r.output.find("is not finite") != std::string::npos);
    }
    SECTION("a weight changed to another finite value") {
        replace_weight(0.25f);
        expect_resume_error(ckpt, "do not match its digest", true);
    }
    write_bytes(ckpt, saved);
    auto ok = test::run_command("timeout 60 " + std::string(HINF_CLI_PATH) + " resume " + ckpt + " --quiet");
    CHECK(ok.status == 0);  // the untouched file still resumes
}

// A trajectory is bound to its checkpoint by the config both store: another run's trajectory (and snapshot)
// placed beside a checkpoint is refused, not spliced in and relabelled.
TEST_CASE("another run's trajectory beside a checkpoint is refused", "[io][damaged][edited]") {
    test::TempDir d("spliced");
    make_run(d / "a");
    TrainOptions opt;
    opt.out_dir = d / "b";
    opt.quiet = true;
    std::string other = kSmall;
    other += "seed = 2\n";  // [training] is the last section of kSmall
    REQUIRE(train_start(load_run_config(ConfigDoc::from_text(other, "other.toml")), opt).status == 0);
    for (const char* f : {"trajectory.h5", "trajectory.ckpt.h5"})
        fs::copy_file(d / (std::string("b/") + f), d / (std::string("a/") + f), fs::copy_options::overwrite_existing);
    auto r = test::run_command("timeout 60 " + std::string(HINF_CLI_PATH) + " resume " + (d / "a/checkpoint.h5") +
                               " --until 0.2 --quiet");
    INFO(r.output);
    CHECK(r.status == 2);
    CHECK(r.output.find("belongs to another run") != std::string::npos);
}
