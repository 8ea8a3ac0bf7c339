// The bad-input corpus (tests/corpus/bad/cases.txt): every hostile config, checkpoint-shaped file
// or network file gives its own message on one line and a non-zero exit, never a crash or a hang;
// plus inputs that cannot live in git: /dev/zero, a directory, a sparse 2 GiB file, a missing file.
#include <sys/stat.h>
#include <unistd.h>

#include <catch2/catch.hpp>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include "helpers.hpp"

using hinf::test::run_command;
using hinf::test::TempDir;
namespace fs = std::filesystem;

namespace {

std::string trim(const std::string& s) {
    std::size_t a = s.find_first_not_of(' '), b = s.find_last_not_of(' ');
    return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

void replace_all(std::string& s, const std::string& from, const std::string& to) {
    for (std::size_t at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size()))
        s.replace(at, from.size(), to);
}

using hinf::test::count_lines;

// One bad input: exit 2 (a hinf::Error, not a crash: signals give -1, internal errors 3), one line
// "hinf: error: ..." holding the fragment (or one of the alternatives "A || B"), within 60 s.
void expect_rejected(const std::string& label, const std::string& args, const std::string& fragment) {
    auto r = run_command("timeout 60 " + std::string(HINF_CLI_PATH) + " " + args);
    INFO(label << ": hinf " << args << "\n" << r.output);
    CHECK(r.status == 2);
    CHECK(r.output.rfind("hinf: error: ", 0) == 0);
    CHECK(count_lines(r.output) == 1);
    bool found = false;
    std::string rest = fragment;
    for (std::size_t bar; !found && !rest.empty(); rest = bar == std::string::npos ? "" : rest.substr(bar + 4)) {
        bar = rest.find(" || ");
        found = r.output.find(trim(rest.substr(0, bar))) != std::string::npos;
    }
    CHECK(found);
}

}  // namespace

TEST_CASE("the bad-input corpus: each file its own message, exit 2, one line", "[cli][errors][corpus]") {
    TempDir d("corpus");
    const std::string good = d / "good.toml";
    std::ofstream(good) << hinf::test::tiny_missile_config("0.02");
    auto t = run_command(std::string(HINF_CLI_PATH) + " train " + good + " --out " + (d / "run") + " --quiet");
    REQUIRE(t.status == 0);
    const std::string ckpt = d / "run/checkpoint.h5";

    const std::string corpus = hinf::test::source_path("tests/corpus/bad");
    std::ifstream list(corpus + "/cases.txt");
    REQUIRE(list.good());
    int cases = 0;
    for (std::string line; std::getline(list, line);) {
        if (line.empty() || line[0] == '#') continue;
        std::stringstream ss(line);
        std::string file, args, fragment;
        std::getline(ss, file, '|');
        std::getline(ss, args, '|');
        std::getline(ss, fragment);
        file = trim(file);
        args = trim(args);
        fragment = trim(fragment);
        REQUIRE(!fragment.empty());
        REQUIRE(fs::exists(corpus + "/" + file));
        TempDir tmp("case");
        replace_all(args, "{f}", corpus + "/" + file);
        replace_all(args, "{tmp}", tmp.path.string());
        replace_all(args, "{ckpt}", ckpt);
        replace_all(args, "{good}", good);
        expect_rejected(file, args, fragment);
        ++cases;
    }
    CHECK(cases >= 40);

    SECTION("inputs that cannot live in git") {
        expect_rejected("/dev/zero", "train /dev/zero --out " + (d / "z"), "is a character device");
        // a FIFO in every place a file is read: one line at once, never a read that waits for a writer
        const std::string fifo = d / "fifo";
        for (const std::string& f : {fifo, fifo + ".csv", fifo + ".h5"}) REQUIRE(::mkfifo(f.c_str(), 0600) == 0);
        expect_rejected("FIFO config", "train " + fifo + " --out " + (d / "z"), "is a FIFO");
        expect_rejected("FIFO checkpoint", "resume " + fifo, "is a FIFO");
        expect_rejected("FIFO network", "operate " + good + " --network " + fifo, "is a FIFO");
        expect_rejected("FIFO network (compare)", "compare " + good + " --network " + fifo + " --out " + (d / "c"),
                        "is a FIFO");
        expect_rejected("FIFO record", "filter " + good + " --measurements " + fifo + ".csv --filters ekf --out " +
                                           (d / "f"), "is a FIFO");
        expect_rejected("FIFO HDF5 record", "filter " + good + " --measurements " + fifo + ".h5 --filters ekf --out " +
                                                (d / "f"), "is a FIFO");
        expect_rejected("a directory", "train " + corpus + " --out " + (d / "z"), "is a directory");
        expect_rejected("missing config", "train " + (d / "missing.toml"), "cannot open config file");
        expect_rejected("missing checkpoint", "resume " + (d / "missing.h5"), "cannot open");
        expect_rejected("/dev/null as checkpoint", "resume /dev/null", "is a character device");
        expect_rejected("directory as checkpoint", "resume " + corpus, "is a directory");
        const std::string huge = d / "huge.toml";
        {
            std::ofstream(huge) << "[training]\n";
            REQUIRE(::truncate(huge.c_str(), off_t(2) << 30) == 0);  // sparse: no disk used
        }
        expect_rejected("a 2 GiB config", "train " + huge, "larger than 1 MiB");
        if (::geteuid() != 0) {  // root reads anything
            const std::string locked = d / "locked.toml";
            std::ofstream(locked) << hinf::test::tiny_missile_config("0.02");
            ::chmod(locked.c_str(), 0);
            expect_rejected("unreadable config", "train " + locked, "cannot open config file");
        }
    }
}

// The good-input corpus (tests/corpus/good/cases.txt): inputs hinf once refused or crashed on and must accept.
// One case per line, `file | shell command`: {hinf} is the binary, {f} the file, {tmp} a fresh directory,
// {corpus} the good corpus; each must exit 0 within 60 s with no "hinf: error" line.
TEST_CASE("the good-input corpus: each case exits 0", "[cli][corpus][good]") {
    const std::string corpus = hinf::test::source_path("tests/corpus/good");
    std::ifstream list(corpus + "/cases.txt");
    REQUIRE(list.good());
    int cases = 0;
    for (std::string line; std::getline(list, line);) {
        if (line.empty() || line[0] == '#') continue;
        const std::size_t bar = line.find('|');
        REQUIRE(bar != std::string::npos);
        const std::string file = trim(line.substr(0, bar));
        std::string cmd = trim(line.substr(bar + 1));
        REQUIRE(fs::exists(corpus + "/" + file));
        TempDir tmp("good");
        replace_all(cmd, "{hinf}", std::string("timeout 60 ") + HINF_CLI_PATH);
        replace_all(cmd, "{f}", corpus + "/" + file);
        replace_all(cmd, "{tmp}", tmp.path.string());
        replace_all(cmd, "{corpus}", corpus);
        auto r = run_command(cmd);
        INFO(file << ": " << cmd << "\n" << r.output);
        CHECK(r.status == 0);
        CHECK(r.output.find("hinf: error") == std::string::npos);
        ++cases;
    }
    CHECK(cases >= 1);
}

// scripts/plot on a file that is missing, a directory or not HDF5: one line and exit 2, never a traceback
TEST_CASE("scripts/plot refuses bad files in one line", "[cli][corpus][plot]") {
    TempDir d("plot-bad");
    const std::string not_h5 = d / "config.toml";
    std::ofstream(not_h5) << "[system]\n";
    for (const std::string& f : {std::string(d / "missing.h5"), d.path.string(), not_h5}) {
        auto r = run_command("/usr/bin/python3 " + hinf::test::source_path("scripts/plot") + " " + f);
        INFO(f << "\n" << r.output);
        CHECK(r.status == 2);
        CHECK(r.output.rfind("scripts/plot: error: ", 0) == 0);
        CHECK(count_lines(r.output) == 1);
        CHECK(r.output.find("Traceback") == std::string::npos);
    }
}
