// Config reading: types, ranges, unknown keys with suggestions, --set overrides.
#include <catch2/catch.hpp>

#include "hinf/config.hpp"
#include "hinf/error.hpp"

using hinf::ConfigDoc;
using hinf::ConfigSection;

TEST_CASE("config reads typed values and rejects unknown keys", "[io][config]") {
    ConfigDoc doc = ConfigDoc::from_text("[training]\nK = 30\nrate = 0.001\nname = \"x\"\n", "t.toml");
    ConfigSection s(doc, "training");
    CHECK(s.get_int("K", 1, 1, 100) == 30);
    CHECK(s.get_double("rate", 1.0, 0.0, 1.0) == Approx(0.001));
    CHECK(s.get_double("missing", 7.0, 0.0, 10.0) == 7.0);
    CHECK_THROWS_WITH(s.finish(), Catch::Contains("unknown key 'name'"));
}

TEST_CASE("config suggests the nearest key", "[io][config]") {
    ConfigDoc doc = ConfigDoc::from_text("[training]\nKK = 30\n", "t.toml");
    ConfigSection s(doc, "training");
    s.get_int("K", 1, 1, 100);
    s.get_int("M", 1, 1, 100);
    CHECK_THROWS_WITH(s.finish(), Catch::Contains("did you mean 'K'"));
}

TEST_CASE("config rejects wrong types, ranges and syntax with the line", "[io][config]") {
    ConfigDoc doc = ConfigDoc::from_text("[a]\nx = \"text\"\ny = -1\n", "t.toml");
    ConfigSection s(doc, "a");
    CHECK_THROWS_WITH(s.get_double("x", 0, 0, 1), Catch::Contains("t.toml:2") && Catch::Contains("must be a number"));
    CHECK_THROWS_WITH(s.get_int("y", 0, 0, 1), Catch::Contains("out of range"));
    CHECK_THROWS_WITH(ConfigDoc::from_text("[a\nx=1", "bad.toml"), Catch::Contains("bad.toml:1") && Catch::Contains("not valid TOML"));
}

TEST_CASE("config set() overrides and creates keys", "[io][config]") {
    ConfigDoc doc = ConfigDoc::from_text("[training]\nK = 30\n", "t.toml");
    doc.set("training.K=5");
    doc.set("network.precision=double");
    ConfigSection s(doc, "training");
    CHECK(s.get_int("K", 1, 1, 100) == 5);
    ConfigSection n(doc, "network");
    CHECK(n.get_string("precision", "float", {"float", "double"}) == "double");
    CHECK_THROWS_AS(doc.set("noequals"), hinf::Error);
    ConfigDoc round = ConfigDoc::from_text(doc.text(), "round");
    ConfigSection r(round, "training");
    CHECK(r.get_int("K", 1, 1, 100) == 5);
}

TEST_CASE("ConfigDoc::unset removes a dotted key and ignores one that is not there", "[config]") {
    ConfigDoc doc = ConfigDoc::from_text("[filter]\nrho = 2.0\nQ = [1.0]\n", "t.toml");
    doc.unset("filter.rho");
    doc.unset("filter.missing");
    doc.unset("nosection.key");
    CHECK(doc.text().find("rho") == std::string::npos);
    CHECK(doc.text().find("Q = ") != std::string::npos);
    doc.set("filter.rho=3");
    CHECK(doc.text().find("rho = 3") != std::string::npos);
}
