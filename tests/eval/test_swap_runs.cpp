// swap_runs (src/eval/acceptance.cpp), the step that keeps a second training in DIR and puts the first in
// DIR/alternative: only a run's own entries change places. Until 2026-12-05 every entry of DIR but acceptance/
// moved, so a log redirected into DIR (`hinf train ... --out D > D/train.log`) ended in D/alternative, and D's lock
// file -- the one this process holds -- went there too, leaving D unlocked for the acceptance check that follows.
#include <catch2/catch.hpp>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "eval/acceptance.hpp"
#include "helpers.hpp"

namespace {

// the entries both runs have (the first run alone has start/, its Riccati start's check)
const char* const kBoth[] = {"checkpoint.h5", "checkpoint.prev.h5", "trajectory.h5", "trajectory.ckpt.h5",
                             "best.h5",       "select.csv",         "select/run.h5"};

void write(const std::string& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

std::string read(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

ino_t inode(const std::string& path) {
    struct stat st {};
    REQUIRE(::stat(path.c_str(), &st) == 0);
    return st.st_ino;
}

}  // namespace

TEST_CASE("swap_runs moves a run's own files and leaves the user's files, the lock and the check in place",
          "[acceptance][io]") {
    namespace fs = std::filesystem;
    hinf::test::TempDir d("swap-runs");
    const std::string dir = d / "run", alt = dir + "/alternative";
    fs::create_directories(dir + "/select");
    fs::create_directories(dir + "/start");
    fs::create_directories(dir + "/acceptance");
    fs::create_directories(alt + "/select");
    for (const char* f : kBoth) {
        write(dir + "/" + f, std::string("first ") + f);
        write(alt + "/" + f, std::string("second ") + f);
    }
    write(dir + "/start/riccati.h5", "first start/riccati.h5");
    write(dir + "/.hinf.lock", "pid 1: hinf train (DIR)\n");
    write(alt + "/.hinf.lock", "pid 1: hinf train (alternative)\n");
    write(dir + "/train.log", "the user's log");
    write(dir + "/acceptance/compare.h5", "the first run's check");
    const ino_t lock = inode(dir + "/.hinf.lock"), log = inode(dir + "/train.log");

    hinf::swap_runs(dir, alt);

    for (const char* f : kBoth) {
        INFO(f);
        CHECK(read(dir + "/" + f) == std::string("second ") + f);
        CHECK(read(alt + "/" + f) == std::string("first ") + f);
    }
    // the start check belongs to the first run: it goes with it, and the second had none
    CHECK(read(alt + "/start/riccati.h5") == "first start/riccati.h5");
    CHECK_FALSE(fs::exists(dir + "/start"));
    // what is not a run's stays where it was, the same file
    CHECK(inode(dir + "/.hinf.lock") == lock);
    CHECK(read(alt + "/.hinf.lock") == "pid 1: hinf train (alternative)\n");
    CHECK(inode(dir + "/train.log") == log);
    CHECK(read(dir + "/train.log") == "the user's log");
    CHECK_FALSE(fs::exists(alt + "/train.log"));
    CHECK(read(dir + "/acceptance/compare.h5") == "the first run's check");
    CHECK_FALSE(fs::exists(alt + "/acceptance"));
    CHECK_FALSE(fs::exists(dir + "/alternative.swap"));

    // and back: the same bits as before the first swap
    hinf::swap_runs(dir, alt);
    CHECK(read(dir + "/checkpoint.h5") == "first checkpoint.h5");
    CHECK(read(dir + "/start/riccati.h5") == "first start/riccati.h5");
    CHECK(read(alt + "/best.h5") == "second best.h5");
    CHECK(inode(dir + "/.hinf.lock") == lock);
}
