// The `hinf` binary end to end: --help, a tiny train/resume/operate, and every bad input giving a
// non-zero exit with one line on stderr.
#include <catch2/catch.hpp>
#include <fstream>

#include "helpers.hpp"

using hinf::test::run_hinf;
using hinf::test::TempDir;

namespace {

const char* kTiny = R"([system]
kind = "missile"
[filter]
t_final = 0.05
[network]
hidden = [8]
[training]
samples = 50
batch = 20
adam_steps = 2
checkpoint_every = 2
)";

std::string write(const TempDir& d, const std::string& name, const std::string& text) {
    std::string path = d / name;
    std::ofstream(path, std::ios::binary) << text;
    return path;
}

int count_lines(const std::string& s) {
    int n = 0;
    for (char c : s) n += c == '\n';
    return n;
}

void expect_error(const std::string& args, const std::string& fragment) {
    INFO("hinf " << args);
    auto r = run_hinf(args);
    INFO(r.output);
    CHECK(r.status != 0);
    CHECK(r.output.find(fragment) != std::string::npos);
    CHECK(r.output.rfind("hinf: error: ", 0) == 0);
    CHECK(count_lines(r.output) == 1);
}

}  // namespace

TEST_CASE("hinf --help and subcommand --help", "[cli]") {
    auto r = run_hinf("--help");
    CHECK(r.status == 0);
    CHECK(r.output.find("train") != std::string::npos);
    for (const char* sub : {"train", "resume", "operate"}) {
        auto s = run_hinf(std::string(sub) + " --help");
        CHECK(s.status == 0);
        CHECK(s.output.find("--threads") != std::string::npos);
    }
}

TEST_CASE("hinf train, resume and operate on a tiny config", "[cli]") {
    TempDir d("cli");
    std::string cfg = write(d, "tiny.toml", kTiny);
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --until 0.02 --quiet");
    INFO(t.output);
    REQUIRE(t.status == 0);
    CHECK(t.output.find("trained time steps 0..2") != std::string::npos);
    auto r = run_hinf("resume " + (d / "run/checkpoint.h5") + " --quiet");
    INFO(r.output);
    REQUIRE(r.status == 0);
    CHECK(r.output.find("trained time steps 2..5") != std::string::npos);
    auto o = run_hinf("operate " + cfg + " --network " + (d / "run/checkpoint.h5") + " --out " + (d / "op") +
                      " --mode measured --runs 2 --quiet");
    INFO(o.output);
    REQUIRE(o.status == 0);
    CHECK(o.output.find("measured mode, 2 run(s)") != std::string::npos);
    CHECK(o.output.find("attenuation ratio") != std::string::npos);
}

TEST_CASE("bad inputs give one line and a non-zero exit", "[cli][errors]") {
    TempDir d("bad");
    std::string good = write(d, "good.toml", kTiny);
    expect_error("train " + (d / "missing.toml"), "cannot open config file");
    expect_error("train", "config is required");
    expect_error("", "A subcommand is required");
    expect_error("trian x.toml", "trian");
    expect_error("operate " + good + " --runs abc", "--runs");
    expect_error("train " + write(d, "empty.toml", ""), "is empty");
    expect_error("train " + write(d, "bin.toml", std::string("a\0b", 3)), "looks binary");
    expect_error("train " + write(d, "syntax.toml", "[training\nK=1\n"), "not valid TOML");
    expect_error("train " + write(d, "unknown.toml", "[training]\nsampels = 10\n"), "did you mean 'samples'");
    expect_error("train " + write(d, "section.toml", "[trainig]\nsamples = 10\n"), "unknown section [trainig]");
    expect_error("train " + write(d, "type.toml", "[training]\nsamples = \"many\"\n"), "must be an integer");
    expect_error("train " + write(d, "mn.toml", "[training]\nsamples = 100\nbatch = 200\n"), "must be <= N");
    expect_error("train " + write(d, "rho.toml", "[filter]\nrho = 0.0\n"), "rho: must be > 0");
    expect_error("train " + write(d, "rhoneg.toml", "[filter]\nrho = -1.0\n"), "out of range");
    expect_error("train " + write(d, "dim.toml", "[filter]\nx0 = [1.0, 2.0]\n"), "expected 6");
    expect_error("train " + write(d, "variant.toml", "[filter]\nvariant = \"magic\"\n"), "is not one of");
    expect_error("train " + write(d, "ftype.toml", "[filter]\ntype = \"h2\"\n"), "is not one of");
    expect_error("train " + write(d, "mkey.toml", "[system]\nkind = \"missile\"\nmaneuver_amplitude = 1.0\n"),
                 "maneuver_amplitude");
    expect_error("train " + write(d, "slopes.toml", "[network]\nslopes = [1.0, -0.1]\n"), "slopes");
    expect_error("train " + good + " --set training.batch=5000", "must be <= N");
    expect_error("train " + good + " --set novalue", "--set 'novalue'");
    expect_error("train " + good + " --threads -3", "--threads");
    expect_error("resume " + (d / "nothing.h5"), "cannot open");
    expect_error("resume " + good, "is not an HDF5 file");
    expect_error("operate " + good + " --network " + good, "is not an HDF5 file");
    expect_error("operate " + good + " --network " + (d / "none.h5"), "cannot open");
    expect_error("operate " + good, "operate needs --network");
    // an existing run is never overwritten silently
    REQUIRE(run_hinf("train " + good + " --out " + (d / "run") + " --until 0.01 --quiet").status == 0);
    expect_error("train " + good + " --out " + (d / "run") + " --until 0.01 --quiet", "already holds a run");
    CHECK(run_hinf("train " + good + " --out " + (d / "run") + " --until 0.01 --quiet --force").status == 0);
}

TEST_CASE("a full-size network trains through its checkpoints without hanging", "[cli][train]") {
    // regression: the checkpoint read-back runs in a forked child; a random re-initialisation there
    // used OpenMP, whose thread pool does not survive fork(), and the first checkpoint hung forever
    TempDir d("fullsize");
    std::string cfg = write(d, "full.toml", "[training]\nsamples = 200\nbatch = 80\nadam_steps = 1\ncheckpoint_every = 1\n");
    auto r = hinf::test::run_command("timeout 120 " + std::string(HINF_CLI_PATH) + " train " + cfg + " --out " +
                                     (d / "run") + " --until 0.03 --quiet");
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK(r.output.find("trained time steps 0..3") != std::string::npos);
}
