// `hinf lmi` end to end: Designs 1 and 2 write lmi.h5 as docs/formats_lmi.md says, --operate writes
// operate.h5, Jacobian vertices work from a config, and bad input gives one line and a non-zero exit.
#include <catch2/catch.hpp>

#include <fstream>
#include <sstream>

#include "helpers.hpp"
#include "hinf/h5.hpp"

using hinf::test::run_hinf;
using hinf::test::source_path;
using hinf::test::TempDir;

namespace {

using hinf::test::read_text;

void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

// lines of output, a last one without its newline included
int line_count(const std::string& s) {
    int n = 0;
    for (char ch : s) n += ch == '\n';
    return n + (!s.empty() && s.back() != '\n');
}

// The Design 1 config with `from` replaced by `to` (must occur).
std::string edited(const std::string& from, const std::string& to) {
    std::string t = read_text(source_path("runs/delay_hinf.toml"));
    const auto at = t.find(from);
    REQUIRE(at != std::string::npos);
    return t.replace(at, from.size(), to);
}

}  // namespace

TEST_CASE("hinf lmi: Design 1 writes a verified lmi.h5", "[lmi][cli]") {
    TempDir dir("lmi1");
    auto r = run_hinf("lmi " + source_path("runs/delay_hinf.toml") + " --out " + dir.path.string());
    INFO(r.output);
    REQUIRE(r.status == 0);
    CHECK(r.output.find("status optimal") != std::string::npos);
    CHECK(r.output.find("\nL1 = ") != std::string::npos);
    auto f = hinf::h5::open_file(dir / "lmi.h5", false);
    CHECK(hinf::h5::get_attr_string(f.get(), "status") == "optimal");
    CHECK(hinf::h5::get_attr_string(f.get(), "design") == "hinf");
    CHECK(hinf::h5::get_attr_double(f.get(), "gamma2") > 0);
    CHECK_FALSE(hinf::h5::has_attr(f.get(), "j2"));
    std::vector<hsize_t> dims;
    auto gains = hinf::h5::read_doubles(f.get(), "gains", &dims);
    CHECK(dims == std::vector<hsize_t>{3, 2, 1});
    auto ev = hinf::h5::read_doubles(f.get(), "block_max_eigenvalue", &dims);
    REQUIRE(ev.size() == 36);
    for (double e : ev) CHECK(e < 0);
    for (const char* m : {"decision/P1", "decision/P2", "decision/Q1", "decision/Q2", "decision/Q3", "decision/R1",
                          "decision/R2", "decision/R3", "decision/Y", "decision/beta"})
        CHECK(hinf::h5::exists(f.get(), m));
    CHECK(hinf::h5::exists(f.get(), "paper_check/block_max_eigenvalue"));
}

TEST_CASE("hinf lmi: Design 2 writes j2 and the prescribed gamma^2", "[lmi][cli]") {
    TempDir dir("lmi2");
    auto r = run_hinf("lmi " + source_path("runs/delay_h2hinf.toml") + " --out " + dir.path.string());
    INFO(r.output);
    REQUIRE(r.status == 0);
    auto f = hinf::h5::open_file(dir / "lmi.h5", false);
    CHECK(hinf::h5::get_attr_string(f.get(), "design") == "h2hinf");
    CHECK(hinf::h5::get_attr_double(f.get(), "gamma2") == Approx(4.16 * 4.16));
    CHECK(hinf::h5::get_attr_double(f.get(), "j2") > 0);
}

TEST_CASE("hinf lmi: an infeasible design prints no gains and exits non-zero", "[lmi][cli]") {
    TempDir dir("lmi3");
    // gamma^2 = 1e-4 is far below what the mixed design can reach
    auto r = run_hinf("lmi " + source_path("runs/delay_h2hinf.toml") + " --out " + dir.path.string() +
                      " --set design.gamma=0.01");
    INFO(r.output);
    CHECK(r.status == 4);
    CHECK(r.output.find("status infeasible") != std::string::npos);
    CHECK(r.output.find("\nL1 = ") == std::string::npos);
    auto f = hinf::h5::open_file(dir / "lmi.h5", false);
    CHECK(hinf::h5::get_attr_string(f.get(), "status") != "optimal");
    CHECK_FALSE(hinf::h5::exists(f.get(), "gains"));
    CHECK_FALSE(hinf::h5::has_attr(f.get(), "gamma2"));
}

TEST_CASE("hinf lmi --operate: Monte Carlo writes operate.h5 with a confidence interval", "[lmi][cli]") {
    TempDir dir("lmiop");
    auto r = run_hinf("lmi " + source_path("runs/delay_hinf.toml") + " --out " + dir.path.string() +
                      " --operate --runs 8 --threads 2 --set simulation.final_time=2");
    INFO(r.output);
    REQUIRE(r.status == 0);
    auto f = hinf::h5::open_file(dir / "operate.h5", false);
    const double mean = hinf::h5::get_attr_double(f.get(), "mean_error_energy");
    CHECK(hinf::h5::get_attr_double(f.get(), "ci95_low") < mean);
    CHECK(mean < hinf::h5::get_attr_double(f.get(), "ci95_high"));
    CHECK(hinf::h5::get_attr_int(f.get(), "runs") == 8);
    auto e = hinf::h5::read_doubles(f.get(), "error_energy");
    REQUIRE(e.size() == 8);
    double s = 0;
    for (double v : e) s += v;
    CHECK(mean == Approx(s / 8));
}

TEST_CASE("hinf lmi: vertices from the Jacobians of (47) give the same design as Appendix A", "[lmi][cli]") {
    TempDir dir("lmijac");
    std::string t = read_text(source_path("runs/delay_hinf.toml"));
    t = t.substr(0, t.find("# Appendix A\n"));  // drop [vertex1..3], [bounds] etc. below
    const std::string rest = read_text(source_path("runs/delay_hinf.toml"));
    t += rest.substr(rest.find("[bounds]"), rest.find("# Appendix B") - rest.find("[bounds]"));
    const auto at = t.find("source = \"config\"");
    REQUIRE(at != std::string::npos);
    t.replace(at, 17, "source = \"jacobian\"");
    write_text(dir / "jac.toml", t);
    auto a = run_hinf("lmi " + dir / "jac.toml" + " --out " + dir / "a");
    auto b = run_hinf("lmi " + source_path("runs/delay_hinf.toml") + " --out " + dir / "b");
    INFO(a.output);
    REQUIRE(a.status == 0);
    REQUIRE(b.status == 0);
    auto fa = hinf::h5::open_file(dir / "a/lmi.h5", false);
    auto fb = hinf::h5::open_file(dir / "b/lmi.h5", false);
    // Appendix A rounds B to 4 decimals; the optimum moves by about that much
    CHECK(hinf::h5::get_attr_double(fa.get(), "gamma2") ==
          Approx(hinf::h5::get_attr_double(fb.get(), "gamma2")).epsilon(1e-3));
}

TEST_CASE("hinf lmi: bad input gives one line and a non-zero exit", "[lmi][cli]") {
    TempDir dir("lmibad");
    struct Case {
        std::string name, text, expect;
    };
    const std::vector<Case> cases = {
        {"unknown key", edited("margin = 1e-6", "margn = 1e-6"), "did you mean 'margin'"},
        {"wrong kind", edited("kind = \"ito_delay\"", "kind = \"missile\""), "kind"},
        {"gamma with hinf", edited("kind = \"hinf\"", "kind = \"hinf\"\ngamma = 3.0"), "gamma"},
        {"h2hinf without gamma", edited("kind = \"hinf\"", "kind = \"h2hinf\""), "gamma"},
        {"missing vertex", edited("[vertex3]", "[vertexx]"), "vertex"},
        {"matrix size", edited("A0 = [[-5.5, 5.0], [-4.0, -10.0]]", "A0 = [[-5.5, 5.0, 1.0], [-4.0, -10.0, 1.0]]"),
         "A0"},
        {"operating points", edited("[1.5, 0.0, 0.0, 0.0]]", "[1.5, 0.0]]"), "operating_points"},
        {"bad covariance", edited("initial_covariance = [1.0, 1.0]", "initial_covariance = [1.0, -1.0]"),
         "initial_covariance"},
        {"negative bound", edited("alpha = 0.4751", "alpha = -0.4751"), "alpha"},
        {"bounds source", edited("source = \"paper\"", "source = \"matlab\""), "source"},
        {"sigma placement", edited("sigma_placement = \"theorem\"", "sigma_placement = \"both\""), "sigma_placement"},
        {"dt", edited("dt = 0.001", "dt = 0.0"), "dt"},
        {"paper solution Y", edited("Y = [[-11.3778, 10.6131], [-6.8297, 1.5799], [-6.3267, 2.6685]]", "Y = [[1.0]]"),
         "Y"},
    };
    for (const auto& c : cases) {
        INFO(c.name);
        write_text(dir / "bad.toml", c.text);
        auto r = run_hinf("lmi " + dir / "bad.toml" + " --out " + dir / "out");
        INFO(r.output);
        CHECK(r.status != 0);
        CHECK(line_count(r.output) == 1);
        CHECK(r.output.find(c.expect) != std::string::npos);
    }
    auto r = run_hinf("lmi " + dir / "missing.toml");
    CHECK(r.status != 0);
    CHECK(line_count(r.output) == 1);
    r = run_hinf("lmi " + source_path("runs/delay_hinf.toml") + " --out " + dir / "o" + " --operate --runs 1");
    CHECK(r.status != 0);
}
