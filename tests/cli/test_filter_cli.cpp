// `hinf filter` on recorded measurements: the DNN filter reproduces `operate`'s measured-mode estimates
// from operate.h5's measurements alone; CSV and HDF5 records give the same estimates; bad records are
// one line naming the row.
#include <catch2/catch.hpp>
#include <fstream>
#include <sstream>

#include "helpers.hpp"
#include "hinf/h5.hpp"

using hinf::test::expect_one_line_error;
using hinf::test::run_hinf;
using hinf::test::TempDir;
using hinf::test::write_file;

namespace {

std::vector<double> read_group_doubles(const std::string& path, const std::string& group, const std::string& name) {
    hinf::h5::Handle f = hinf::h5::open_file(path, false);
    hinf::h5::Handle g = hinf::h5::open_group(f.get(), group);
    return hinf::h5::read_doubles(g.get(), name);
}

// operate.h5's t and y as CSV rows "t,y1,...,y6" with a header
std::string record_as_csv(const std::string& operate_h5) {
    hinf::h5::Handle f = hinf::h5::open_file(operate_h5, false);
    std::vector<hsize_t> dims;
    std::vector<double> t = hinf::h5::read_doubles(f.get(), "t");
    std::vector<double> y = hinf::h5::read_doubles(f.get(), "y", &dims);
    std::ostringstream out;
    out.precision(17);
    out << "# recorded by hinf operate\ntime,r1,r2,r3,r4,r5,r6\n";
    for (std::size_t k = 0; k < t.size(); ++k) {
        out << t[k];
        for (hsize_t j = 0; j < dims[1]; ++j) out << ',' << y[k * dims[1] + j];
        out << '\n';
    }
    return out.str();
}

}  // namespace

TEST_CASE("hinf filter reproduces operate's measured DNN filter from the measurements alone", "[cli][filter]") {
    TempDir d("cli-filter");
    const std::string cfg = write_file(d, "tiny.toml", hinf::test::tiny_missile_config());
    auto t = run_hinf("train " + cfg + " --out " + (d / "run") + " --quiet");
    INFO(t.output);
    REQUIRE(t.status == 0);
    const std::string net = d / "run/checkpoint.h5";
    auto o = run_hinf("operate " + cfg + " --network " + net + " --mode measured --quiet --out " + (d / "op"));
    INFO(o.output);
    REQUIRE(o.status == 0);
    const std::string op = d / "op/operate.h5";

    auto r = run_hinf("filter " + cfg + " --network " + net + " --measurements " + op +
                      " --filters dnn,ekf,ukf,open_loop --quiet --out " + (d / "flt"));
    INFO(r.output);
    REQUIRE(r.status == 0);
    const std::string est = d / "flt/estimates.h5";
    std::vector<double> xhat_operate;
    {
        hinf::h5::Handle f = hinf::h5::open_file(op, false);
        xhat_operate = hinf::h5::read_doubles(f.get(), "xhat");
    }
    // the same adapter on the same measurements: bit for bit, without the true state
    CHECK(hinf::test::bitwise_equal(read_group_doubles(est, "dnn_dissipative_measured", "xhat"), xhat_operate));
    const std::size_t K = xhat_operate.size() / 6;
    REQUIRE(K == 5u);  // the tiny config: t_final 0.05 s
    CHECK(read_group_doubles(est, "ekf", "P").size() == K * 36u);
    CHECK(read_group_doubles(est, "ukf", "innovation").size() == K * 6u);
    CHECK(r.output.find("diverged") != std::string::npos);

    // scripts/plot draws estimates.h5 (no truth in it)
    auto p = hinf::test::run_command("/usr/bin/python3 " + hinf::test::source_path("scripts/plot") + " " + est +
                                     " --out " + (d / "png"));
    INFO(p.output);
    CHECK(p.status == 0);
    for (const char* png : {"estimates.png", "innovations.png"}) {
        std::ifstream img(d / (std::string("png/") + png), std::ios::binary);
        char magic[4] = {0, 0, 0, 0};
        img.read(magic, 4);
        CHECK(std::string(magic + 1, 3) == "PNG");
    }

    // the same record as CSV (17 digits, a comment and a header line): the same estimates
    const std::string csv = write_file(d, "rec.csv", record_as_csv(op));
    auto c = run_hinf("filter " + cfg + " --network " + net + " --measurements " + csv +
                      " --filters dnn,ekf --quiet --out " + (d / "fcsv"));
    INFO(c.output);
    REQUIRE(c.status == 0);
    CHECK(hinf::test::bitwise_equal(read_group_doubles(d / "fcsv/estimates.h5", "ekf", "xhat"),
                                    read_group_doubles(est, "ekf", "xhat")));
    std::ifstream in(d / "fcsv/estimates_ekf.csv");
    std::string header;
    std::getline(in, header);
    CHECK(header.rfind("t,x_hat,y_hat,z_hat,vx_hat,vy_hat,vz_hat,sd_x,", 0) == 0);

    // a wrong-length option is one line
    expect_one_line_error("filter " + cfg + " --measurements " + csv + " --filters open_loop --initial-std 1,2",
                          "--initial-std has 2 values");
}

TEST_CASE("hinf filter names the row of a bad measurement record", "[cli][filter]") {
    TempDir d("cli-filter-bad");
    const std::string cfg = write_file(d, "tiny.toml", hinf::test::tiny_missile_config());
    const std::string good_row = ",1,2,3,4,5,6\n";
    auto csv = [&](const std::string& name, const std::string& body) { return write_file(d, name, body); };
    const std::string base = "filter " + cfg + " --filters ekf --quiet --out " + (d / "o") + " --measurements ";
    // a valid record passes (the checks below can fail)
    auto ok = run_hinf(base + csv("ok.csv", "0" + good_row + "0.01" + good_row + "0.02" + good_row));
    INFO(ok.output);
    CHECK(ok.status == 0);
    expect_one_line_error(base + csv("cols.csv", "t,a,b,c,d,e,f\n0" + good_row + "0.01,1,2,3\n"),
                          "line 3: 4 columns, expected 7");
    expect_one_line_error(base + csv("time.csv", "0" + good_row + "0.02" + good_row + "0.01" + good_row),
                          "line 3: time 0.010000 s is not after");
    expect_one_line_error(base + csv("nan.csv", "0" + good_row + "0.01,1,2,nan,4,5,6\n0.02" + good_row),
                          "line 2: output 3 is not finite");
    expect_one_line_error(base + csv("text.csv", "0" + good_row + "0.01,1,2,x3,4,5,6\n"),
                          "line 2, column 4: 'x3' is not a number");
    expect_one_line_error(base + csv("gap.csv", "0" + good_row + "0.01" + good_row + "0.03" + good_row),
                          "the filters run on a uniform grid");
    expect_one_line_error(base + csv("one.csv", "0" + good_row), "needs at least 2");
    expect_one_line_error(base + csv("rec.dat", "0" + good_row), "unknown file type");
    expect_one_line_error(base + (d / "missing.csv"), "cannot open measurements");
    {
        hinf::h5::Handle f = hinf::h5::create_file(d / "shape.h5");
        std::vector<double> t = {0, 0.01, 0.02}, y(3 * 5, 1.0);
        hinf::h5::write_doubles(f.get(), "t", t.data(), {3});
        hinf::h5::write_doubles(f.get(), "y", y.data(), {3, 5});
    }
    expect_one_line_error(base + (d / "shape.h5"), "dataset 'y' is [3 x 5], expected [3 x 6]");
    expect_one_line_error(base + (d / "shape.h5") + " --dataset z", "no dataset 'z'");
    const std::string garbage = write_file(d, "garbage.h5", "this is not an HDF5 file\n");
    expect_one_line_error(base + garbage, "garbage.h5");
}
