// A `gain` checkpoint written before network.storage_knots existed (one constant S; the default is now a
// time-varying S(t)) still means what it meant: hinf reads it with storage_knots = 0, compares with it, and a resume
// continues bit for bit as the uninterrupted training of that hinf did (fixtures in tests/corpus/legacy, written by
// the hinf of commit e8e26a9: the 0.3 s checkpoint with its trajectory, and the 0.5 s checkpoint of the full run).
#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "helpers.hpp"
#include "hinf/h5.hpp"

using hinf::test::run_hinf;
using hinf::test::source_path;

TEST_CASE("a gain checkpoint with a constant S from before storage_knots loads and resumes as trained", "[cli][gain]") {
    hinf::test::TempDir d("legacy");
    const std::string dir = d / "run";
    hinf::test::copy_legacy_run("gain_constant_s", dir);
    const std::string cfg = source_path("tests/corpus/legacy/gain_constant_s.toml");

    auto c = run_hinf("compare " + cfg + " --network " + dir + "/checkpoint.h5 --filters dnn --runs 1 --quiet --out " +
                      (d / "cmp"));
    INFO(c.output);
    CHECK(c.status == 0);

    auto r = run_hinf("resume " + dir + "/checkpoint.h5 --quiet");
    INFO(r.output);
    REQUIRE(r.status == 0);
    hinf::h5::Handle got = hinf::h5::open_file(dir + "/checkpoint.h5", false);
    hinf::h5::Handle want = hinf::h5::open_file(source_path("tests/corpus/legacy/gain_constant_s_full.h5"), false);
    for (const char* name : {"network/layer_1/W", "network/layer_2/W", "network/storage"})
        CHECK(hinf::h5::read_doubles(got.get(), name) == hinf::h5::read_doubles(want.get(), name));
    hinf::h5::Handle net = hinf::h5::open_group(got.get(), "network");
    CHECK(hinf::h5::get_attr_int(net.get(), "storage_knots") == 0);
    const std::string text = hinf::h5::read_string(got.get(), "config");
    CHECK(text.find("# hinf resume at step 30: --set network.storage_knots=0") != std::string::npos);
}
