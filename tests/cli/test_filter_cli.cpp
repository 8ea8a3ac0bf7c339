// `hinf filter` on recorded measurements: the DNN filter reproduces `operate`'s measured-mode estimates
// from operate.h5's measurements alone; CSV and HDF5 records give the same estimates; bad records are
// one line naming the row.
#include <catch2/catch.hpp>
#include <cmath>
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
    for (const char* png : {"estimates.png", "innovations.png", "nis.png"}) {  // nis.png: the ekf and ukf state one
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
    expect_one_line_error(base + csv("inf.csv", "0" + good_row + "0.01,1,2,-inf,4,5,6\n0.02" + good_row),
                          "line 2: output 3 is infinite");  // NaN or empty: a missing measurement (a dropout)
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

// Records as real clocks and other tools write them (issue 15): Unix-epoch times with jitter, a gap put on a
// uniform grid, a byte-order mark without a header, an integer time column and gzip-compressed HDF5.
TEST_CASE("hinf filter accepts records from real clocks and other tools", "[cli][filter][records]") {
    TempDir d("cli-filter-clock");
    const std::string cfg = write_file(d, "tiny.toml", hinf::test::tiny_missile_config());
    const std::string base = "filter " + cfg + " --filters ekf --quiet --out " + (d / "o") + " --measurements ";
    auto rows = [](const std::vector<double>& t, int digits) {
        std::ostringstream out;
        out.precision(digits);
        for (double tk : t) out << tk << ',' << 100 * (tk - t[0]) << ",2,3,4,5,6\n";
        return out.str();
    };
    auto est = [&](const std::string& name) {
        hinf::h5::Handle f = hinf::h5::open_file(d / "o/estimates.h5", false);
        return hinf::h5::read_doubles(f.get(), name);
    };
    // Unix-epoch seconds at 0.01 s with 1e-4 s of jitter: 1 % of the step, within the default tolerance
    const double e0 = 1732550400.0;
    const std::string epoch =
        write_file(d, "epoch.csv", rows({e0, e0 + 0.0101, e0 + 0.0199, e0 + 0.0300, e0 + 0.0400}, 17));
    auto r = run_hinf(base + epoch);
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK(est("t").size() == 5u);
    expect_one_line_error(base + epoch + " --time-tolerance 0.001", "more than --time-tolerance 0.001");
    expect_one_line_error(base + epoch + " --time-tolerance 2", "--time-tolerance must be a number in [0, 1)");
    expect_one_line_error(base + epoch + " --resample cubic", "--resample 'cubic' is not one of: linear, zoh");

    // a gap, put on the uniform grid 0, 0.015, 0.03 (the mean step of 0, 0.01, 0.03): linear or zero-order hold
    const std::string gap = write_file(d, "gap.csv", rows({0, 0.01, 0.03}, 17));
    expect_one_line_error(base + gap, "pass --resample linear or --resample zoh");
    auto lin = run_hinf(base + gap + " --resample linear");
    INFO(lin.output);
    REQUIRE(lin.status == 0);
    CHECK(lin.output.find("resampled, linear") != std::string::npos);
    std::vector<double> t = est("t"), y = est("y");
    REQUIRE(t.size() == 3u);
    CHECK(t[1] == Approx(0.015));
    CHECK(y[6] == Approx(1.5));  // 100 t, halfway between the rows at 0.01 and 0.03
    REQUIRE(run_hinf(base + gap + " --resample zoh").status == 0);
    y = est("y");
    CHECK(y[6] == Approx(1.0));  // the sample at 0.01 s held
    CHECK(y[12] == Approx(3.0));

    // a UTF-8 byte-order mark and no header: the first row is data, not a header
    const std::string bom = write_file(d, "bom.csv", "\xEF\xBB\xBF" + rows({0, 0.01, 0.02}, 17));
    REQUIRE(run_hinf(base + bom).status == 0);
    CHECK(est("t").size() == 3u);

    // HDF5 from another tool: an integer time column (here in ms, so the step is far from the config's dt:
    // one warning line naming both) and gzip-compressed outputs
    {
        hinf::h5::Handle f = hinf::h5::create_file(d / "ms.h5");
        std::vector<std::int64_t> tms = {0, 10, 20, 30};
        hinf::h5::write_int64s(f.get(), "t", tms.data(), {4});
        std::vector<double> yv(4 * 6, 1.0);
        hsize_t dims[2] = {4, 6}, chunk[2] = {2, 6};
        hid_t space = H5Screate_simple(2, dims, nullptr), dcpl = H5Pcreate(H5P_DATASET_CREATE);
        H5Pset_chunk(dcpl, 2, chunk);
        H5Pset_deflate(dcpl, 6);
        hid_t ds = H5Dcreate2(f.get(), "y", H5T_IEEE_F32LE, space, H5P_DEFAULT, dcpl, H5P_DEFAULT);
        REQUIRE(H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, yv.data()) >= 0);
        H5Dclose(ds);
        H5Pclose(dcpl);
        H5Sclose(space);
    }
    auto h = run_hinf(base + (d / "ms.h5"));
    INFO(h.output);
    CHECK(h.status == 0);
    CHECK(h.output.find("warning: the record's time step 10 s is far from the config's dt 0.01 s") != std::string::npos);
    CHECK(est("t") == std::vector<double>{0, 10, 20, 30});
    CHECK(est("y") == std::vector<double>(24, 1.0));
}

// Dropouts: an empty or NaN cell marks the row's measurement as missing; every filter predicts only there.
TEST_CASE("hinf filter predicts only where a measurement is missing", "[cli][filter][records]") {
    TempDir d("cli-filter-dropout");
    const std::string cfg = write_file(d, "tiny.toml", hinf::test::tiny_missile_config());
    const std::string row = ",1000,2000,3000,4000,5000,6000\n";
    // every row but the last missing (an empty cell, a NaN, both): EKF's estimates before the last row are the
    // open-loop prediction, bit for bit
    const std::string rec = write_file(d, "drop.csv", "t,a,b,c,d,e,f\n0,,2000,3000,4000,5000,6000\n0.01,nan,2,3,4,5,6\n"
                                                      "0.02,1,,3,4,5,nan\n0.03" + row);
    auto r = run_hinf("filter " + cfg + " --filters ekf,ukf,pf,open_loop --particles 50 --quiet --out " + (d / "o") +
                      " --measurements " + rec);
    INFO(r.output);
    REQUIRE(r.status == 0);
    CHECK(r.output.find("3 row(s) without a measurement") != std::string::npos);
    const std::string est = d / "o/estimates.h5";
    {
        hinf::h5::Handle f = hinf::h5::open_file(est, false);
        CHECK(hinf::h5::get_attr_int(f.get(), "missing_rows") == 3);
    }
    std::vector<double> ekf = read_group_doubles(est, "ekf", "xhat"), ol = read_group_doubles(est, "open_loop", "xhat");
    REQUIRE(ekf.size() == 24u);
    CHECK(hinf::test::bitwise_equal(ekf, ol));  // rows 0..3: estimates before the one measurement at t = 0.03
    std::vector<double> fin_ekf = read_group_doubles(est, "ekf", "xhat_final"),
                        fin_ol = read_group_doubles(est, "open_loop", "xhat_final");
    CHECK_FALSE(hinf::test::bitwise_equal(fin_ekf, fin_ol));  // ... which the EKF then uses
    for (const char* g : {"ukf", "pf"})
        for (double v : read_group_doubles(est, g, "xhat")) CHECK(std::isfinite(v));
    std::vector<double> innov = read_group_doubles(est, "ekf", "innovation");
    CHECK(std::isnan(innov[0]));   // no measurement, no innovation
    CHECK(std::isfinite(innov[18]));
    // infinity is not a dropout
    expect_one_line_error("filter " + cfg + " --filters ekf --quiet --out " + (d / "o2") + " --measurements " +
                              write_file(d, "inf.csv", "0" + row + "0.01,inf,2,3,4,5,6\n"),
                          "line 2: output 1 is infinite");
}

TEST_CASE("hinf filter over an earlier run's outputs leaves no old file beside the new ones and a user's own files in place", "[cli][filter][records]") {
    TempDir d("cli-filter-rerun");
    const std::string cfg = write_file(d, "tiny.toml", hinf::test::tiny_missile_config());
    const std::string rec = write_file(d, "r.csv", "t,a,b,c,d,e,f\n0,1,2,3,4,5,6\n0.01,1,2,3,4,5,6\n0.02,1,2,3,4,5,6\n");
    auto first = run_hinf("filter " + cfg + " --filters ekf,ukf --quiet --out " + (d / "o") + " --measurements " + rec);
    INFO(first.output);
    REQUIRE(first.status == 0);
    REQUIRE(std::ifstream(d / "o/estimates_ukf.csv").good());
    // a user's own files of that name beside them, not written by hinf: they stay
    write_file(d, "o/estimates_notes.csv", "run,comment\n1,EKF looked fine\n");
    write_file(d, "o/estimates_x.csv", "t,x_hat,extra\n0,1,2\n");
    auto second = run_hinf("filter " + cfg + " --filters ekf --quiet --out " + (d / "o") + " --measurements " + rec);
    INFO(second.output);
    REQUIRE(second.status == 0);
    // the earlier run's ukf CSV is gone: estimates.h5 (written last) lists exactly the CSVs of its run
    CHECK_FALSE(std::ifstream(d / "o/estimates_ukf.csv").good());
    CHECK(std::ifstream(d / "o/estimates_ekf.csv").good());
    CHECK(std::ifstream(d / "o/estimates_notes.csv").good());
    CHECK(std::ifstream(d / "o/estimates_x.csv").good());
    hinf::h5::Handle f = hinf::h5::open_file(d / "o/estimates.h5", false);
    CHECK(hinf::h5::get_attr_string(f.get(), "csv_files") == "estimates_ekf.csv");
}

TEST_CASE("hinf filter says when the config's start makes the Bayesian filters certain of a state", "[cli][filter]") {
    TempDir d("cli-filter-p0");
    const std::string text =
        "[system]\nkind = \"expr\"\nstates = [\"w1\", \"w2\"]\ndisturbances = 1\nmeasurements = 1\n"
        "f = [\"-w1*w2\", \"w1\"]\ng = [[\"1\"], [\"0\"]]\nh = [\"w1\"]\n"
        "[filter]\nrho = 2\nx0 = [1.0, 0.5]\nxhat0 = [0.8, 0.5]\ndt = 0.01\nt_final = 1\n"
        "[online]\ndisturbance_std = 0.1\nnoise_std = 0.1\n";
    const std::string cfg = write_file(d, "two.toml", text);
    const std::string rec = write_file(d, "y.csv", "t,y\n0,0.9\n0.01,0.95\n0.02,0.97\n");
    const std::string base = "filter " + cfg + " --filters ekf,ukf --measurements " + rec + " --out ";
    // x0 = x^0 in w2: P0 = diag(0.04, 0), and the user is told so (a record's start may not be that certain)
    auto r = run_hinf(base + (d / "a"));
    INFO(r.output);
    REQUIRE(r.status == 0);
    CHECK(r.output.find("start certain of w2 ") != std::string::npos);
    CHECK(r.output.find("certain of w1") == std::string::npos);
    auto ol = run_hinf("filter " + cfg + " --filters open_loop --measurements " + rec + " --out " + (d / "ol"));
    REQUIRE(ol.status == 0);
    CHECK(ol.output.find("start certain") == std::string::npos);  // no filter that starts from P0
    auto told = run_hinf(base + (d / "b") + " --initial-std 0.2,0.3");
    INFO(told.output);
    REQUIRE(told.status == 0);
    CHECK(told.output.find("start certain") == std::string::npos);
    // the note is a note: the estimates are those of P0 = diag(0.04, 0) told explicitly through the config
    auto same = run_hinf("filter " + write_file(d, "two_told.toml",
                                                 text + "[baseline]\ninitial_std = [0.2, 0.0]\n") +
                         " --filters ekf,ukf --measurements " + rec + " --out " + (d / "c"));
    REQUIRE(same.status == 0);
    CHECK(same.output.find("start certain") == std::string::npos);  // the user chose it
    // ... and through --initial-std, where 0 is a known state as in the config
    auto flag = run_hinf(base + (d / "e") + " --initial-std 0.2,0");
    INFO(flag.output);
    REQUIRE(flag.status == 0);
    for (const char* g : {"ekf", "ukf"}) {
        const std::vector<double> a = read_group_doubles(d / "a/estimates.h5", g, "xhat");
        CHECK(hinf::test::bitwise_equal(a, read_group_doubles(d / "c/estimates.h5", g, "xhat")));
        CHECK(hinf::test::bitwise_equal(a, read_group_doubles(d / "e/estimates.h5", g, "xhat")));
        CHECK_FALSE(hinf::test::bitwise_equal(a, read_group_doubles(d / "b/estimates.h5", g, "xhat")));  // told more
    }
}

TEST_CASE("hinf filter checks each Bayesian filter's innovations against what it expects", "[cli][filter][nis]") {
    TempDir d("cli-filter-nis");
    // a damped oscillator seen through its position; the record is a compare run of the same model
    const std::string cfg = write_file(
        d, "osc.toml",
        "[system]\nkind = \"expr\"\nstates = [\"p\", \"v\"]\ndisturbances = 1\nmeasurements = 1\n"
        "f = [\"v\", \"-p - 0.5*v\"]\ng = [[\"0\"], [\"1\"]]\nh = [\"p\"]\n"
        "[filter]\nrho = 2\nx0 = [1.0, 0.0]\nxhat0 = [0.8, 0.2]\ndt = 0.01\nt_final = 20\n"
        "[online]\ndisturbance_std = 1\nnoise_std = 0.1\nruns = 1\nsettle_time = 2\n");
    auto c = run_hinf("compare " + cfg + " --filters ekf --quiet --out " + (d / "c"));
    INFO(c.output);
    REQUIRE(c.status == 0);
    const std::string rec = d / "c/compare.h5";
    auto r = run_hinf("filter " + cfg + " --filters ekf,ukf,pf,open_loop --particles 500 --quiet --out " + (d / "o") +
                      " --measurements " + rec);
    INFO(r.output);
    REQUIRE(r.status == 0);
    CHECK(r.output.find("NIS/m") != std::string::npos);
    CHECK(r.output.find("its innovations are about") == std::string::npos);  // told the record's statistics
    const std::string est = d / "o/estimates.h5";
    hinf::h5::Handle f = hinf::h5::open_file(est, false);
    const std::vector<double> t = hinf::h5::read_doubles(f.get(), "t");
    REQUIRE(t.size() == 2000u);
    for (const char* name : {"ekf", "ukf", "pf"}) {
        hinf::h5::Handle g = hinf::h5::open_group(f.get(), name);
        const double per_output = hinf::h5::get_attr_double(g.get(), "nis_per_output");
        const double from = hinf::h5::get_attr_double(g.get(), "nis_from");
        CHECK(from == Approx(2.0));
        // the attribute is the mean of the per-step dataset over the window (m = 1)
        const std::vector<double> nis = hinf::h5::read_doubles(g.get(), "nis");
        REQUIRE(nis.size() == t.size());
        double sum = 0, count = 0;
        for (std::size_t k = 0; k < t.size(); ++k)
            if (t[k] >= from) {
                REQUIRE(std::isfinite(nis[k]));
                sum += nis[k];
                count += 1;
            }
        INFO(name << ": NIS per output " << per_output);
        CHECK(per_output == Approx(sum / count).epsilon(1e-12));
        CHECK(per_output > 0.8);
        CHECK(per_output < 1.25);
    }
    hinf::h5::Handle g_ol = hinf::h5::open_group(f.get(), "open_loop");
    CHECK_FALSE(hinf::h5::has_attr(g_ol.get(), "nis_per_output"));
    std::string head_ekf, head_ol;
    std::getline(std::ifstream(d / "o/estimates_ekf.csv") >> std::ws, head_ekf);
    std::getline(std::ifstream(d / "o/estimates_open_loop.csv") >> std::ws, head_ol);
    CHECK(head_ekf.size() > 4);
    CHECK(head_ekf.compare(head_ekf.size() - 4, 4, ",nis") == 0);
    CHECK(head_ol.find("nis") == std::string::npos);

    // told a tenth of the record's noise: overconfident; ten times: it expects far more than it meets
    auto over = run_hinf("filter " + cfg + " --filters ekf --quiet --out " + (d / "over") + " --measurements " + rec +
                         " --set online.noise_std=0.01");
    INFO(over.output);
    REQUIRE(over.status == 0);
    CHECK(over.output.find("note: ekf: its innovations are about ") != std::string::npos);
    CHECK(over.output.find("it is overconfident here") != std::string::npos);
    auto under = run_hinf("filter " + cfg + " --filters ekf --quiet --out " + (d / "under") + " --measurements " + rec +
                          " --set online.noise_std=1");
    INFO(under.output);
    REQUIRE(under.status == 0);
    CHECK(under.output.find("smaller than it expects") != std::string::npos);
}
