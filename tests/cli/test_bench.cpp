// `hinf bench` writes the attributes issue 8 names; bad arguments give one line.
#include <catch2/catch.hpp>

#include "helpers.hpp"
#include "hinf/h5.hpp"

TEST_CASE("hinf bench writes bench.h5 with step times and the FMA peak", "[cli][bench]") {
    hinf::test::TempDir d("bench");
    auto r = hinf::test::run_hinf("bench --threads 1 --precision f32 --batch 40 --repeats 3 --gemm default,eigen --out " +
                                  (d / "b"));
    INFO(r.output);
    REQUIRE(r.status == 0);
    // which kernels ran is printed, for each path
    CHECK(r.output.find("GEMMs (eigen): Eigen") != std::string::npos);
    CHECK((r.output.find("GEMMs (own): hinf's own AVX-512") != std::string::npos ||
           r.output.find("GEMMs (openblas): OpenBLAS") != std::string::npos));
    hinf::h5::Handle f = hinf::h5::open_file(d / "b/bench.h5", false);
    CHECK(hinf::h5::get_attr_double(f.get(), "step_ms_f32_1t") > 0);
    CHECK(hinf::h5::get_attr_double(f.get(), "step_ms_f32_1t_eigen") > 0);
    CHECK(hinf::h5::get_attr_double(f.get(), "peak_gflops_f32_1t") > 0);
    hinf::test::expect_one_line_error("bench --gemm mkl --out " + (d / "c"), "mkl");
    auto bad = hinf::test::run_hinf("bench --precision f16 --out " + (d / "c"));
    CHECK(bad.status == 2);
    CHECK(bad.output.find("f16") != std::string::npos);
    auto bad2 = hinf::test::run_hinf("bench --threads one --out " + (d / "c"));
    CHECK(bad2.status == 2);
}
