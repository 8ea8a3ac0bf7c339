// The journalled exchange of two runs' files (io/run_swap.hpp): a process killed at any point of an exchange leaves
// a state that the next lock of DIR finishes, so DIR ends with the kept run and DIR/alternative with the other, and
// `hinf resume DIR/checkpoint.h5` works even where the kill left that checkpoint inside DIR/alternative.swap.
// Each state a kill can leave is built here as the journal describes it: the phases before P done, the first J
// entries of phase P moved, the journal at P.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "helpers.hpp"
#include "hinf/error.hpp"
#include "io/run_lock.hpp"
#include "io/run_swap.hpp"

namespace fs = std::filesystem;

namespace {

// a file in both runs, a folder in both, one only the first run has, one only the second
const std::vector<std::string> kNames = {"checkpoint.h5", "select", "start", "best_average.h5", "trajectory.h5"};

void write(const fs::path& path, const std::string& text) { std::ofstream(path, std::ios::binary) << text; }

std::string read(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// DIR holds the first run, DIR/alternative the second
void two_runs(const fs::path& dir, const fs::path& alt) {
    fs::create_directories(dir / "select");
    fs::create_directories(dir / "start");
    fs::create_directories(alt / "select");
    write(dir / "checkpoint.h5", "first");
    write(dir / "trajectory.h5", "first");
    write(dir / "select/run.h5", "first");
    write(dir / "start/riccati.h5", "first");
    write(alt / "checkpoint.h5", "second");
    write(alt / "trajectory.h5", "second");
    write(alt / "select/run.h5", "second");
    write(alt / "best_average.h5", "second");
}

void moves(const fs::path& from, const fs::path& to, std::size_t count) {
    for (std::size_t i = 0; i < count; ++i)
        if (fs::exists(from / kNames[i])) fs::rename(from / kNames[i], to / kNames[i]);
}

void require_swapped(const fs::path& dir, const fs::path& alt) {
    CHECK(read(dir / "checkpoint.h5") == "second");
    CHECK(read(dir / "trajectory.h5") == "second");
    CHECK(read(dir / "select/run.h5") == "second");
    CHECK(read(dir / "best_average.h5") == "second");
    CHECK_FALSE(fs::exists(dir / "start"));
    CHECK(read(alt / "checkpoint.h5") == "first");
    CHECK(read(alt / "trajectory.h5") == "first");
    CHECK(read(alt / "select/run.h5") == "first");
    CHECK(read(alt / "start/riccati.h5") == "first");
    CHECK_FALSE(fs::exists(alt / "best_average.h5"));
    CHECK_FALSE(fs::exists(dir / hinf::kSwapFolder));
}

// a copy of the trained run in DIR/alternative, and an exchange killed in phase 1 after moving DIR's checkpoint.h5 into
// the folder: DIR has no checkpoint.h5
void kill_in_exchange(const fs::path& dir) {
    const fs::path alt = dir / "alternative", folder = dir / hinf::kSwapFolder;
    fs::create_directories(alt);
    for (const char* f : {"checkpoint.h5", "checkpoint.prev.h5", "trajectory.h5", "trajectory.ckpt.h5"})
        if (fs::exists(dir / f)) fs::copy_file(dir / f, alt / f);
    fs::create_directories(folder);
    fs::rename(dir / "checkpoint.h5", folder / "checkpoint.h5");
    std::ofstream(folder / hinf::kSwapJournal) << "phase 1\n" << fs::absolute(alt).string() << "\ncheckpoint.h5\n"
                                               << "checkpoint.prev.h5\ntrajectory.h5\ntrajectory.ckpt.h5\n";
}

}  // namespace

TEST_CASE("an exchange of two runs killed at any point is finished by the next lock of the directory", "[io][swap]") {
    hinf::test::TempDir d("run-swap");
    SECTION("uninterrupted") {
        const fs::path dir = d / "run", alt = dir / "alternative";
        two_runs(dir, alt);
        hinf::swap_entries(dir.string(), alt.string(), kNames);
        require_swapped(dir, alt);
    }
    SECTION("killed in phase P after J moves") {
        for (int phase = 1; phase <= 3; ++phase) {
            for (std::size_t moved = 0; moved <= kNames.size(); ++moved) {
                INFO("phase " << phase << ", " << moved << " entries moved");
                const fs::path dir = d / ("run" + std::to_string(phase) + "_" + std::to_string(moved));
                const fs::path alt = dir / "alternative", folder = dir / hinf::kSwapFolder;
                two_runs(dir, alt);
                fs::create_directories(folder);
                if (phase > 1) moves(dir, folder, kNames.size());
                if (phase > 2) moves(alt, dir, kNames.size());
                const fs::path from = phase == 1 ? dir : phase == 2 ? alt : folder;
                const fs::path to = phase == 1 ? folder : phase == 2 ? dir : alt;
                moves(from, to, moved);
                std::ofstream journal(folder / hinf::kSwapJournal);
                journal << "phase " << phase << "\n" << fs::absolute(alt).string() << "\n";
                for (const auto& n : kNames) journal << n << "\n";
                journal.close();
                if (phase == 2) write(folder / "journal.tmp", "phase 3\n");  // killed while writing the next one
                { const hinf::RunDirLock lock(dir.string(), "test"); }
                require_swapped(dir, alt);
            }
        }
    }
    SECTION("killed before the first move: the folder goes, the runs stay") {
        const fs::path dir = d / "run", alt = dir / "alternative";
        two_runs(dir, alt);
        fs::create_directories(dir / hinf::kSwapFolder);
        write(dir / hinf::kSwapFolder / "journal.tmp", "pha");
        CHECK(hinf::finish_interrupted_swap(dir.string()).empty());
        CHECK_FALSE(fs::exists(dir / hinf::kSwapFolder));
        CHECK(read(dir / "checkpoint.h5") == "first");
        CHECK(read(alt / "checkpoint.h5") == "second");
    }
    SECTION("a damaged journal: one line naming the folder, nothing moved") {
        const fs::path dir = d / "run", alt = dir / "alternative";
        two_runs(dir, alt);
        fs::create_directories(dir / hinf::kSwapFolder);
        write(dir / hinf::kSwapFolder / hinf::kSwapJournal, "phase 7\n");
        CHECK_THROWS_WITH(hinf::finish_interrupted_swap(dir.string()),
                          Catch::Contains("is damaged") && Catch::Contains("by hand"));
        CHECK(read(dir / "checkpoint.h5") == "first");
        // the lock refuses with that line, and is not left held: once the journal is fixed, the next lock finishes
        CHECK_THROWS_WITH(hinf::RunDirLock(dir.string(), "test"), Catch::Contains("is damaged"));
        std::ofstream(dir / hinf::kSwapFolder / hinf::kSwapJournal) << "phase 1\n" << fs::absolute(alt).string() << "\n"
                                                                    << "checkpoint.h5\n";
        { const hinf::RunDirLock lock(dir.string(), "test"); }
        CHECK(read(dir / "checkpoint.h5") == "second");
        CHECK(read(alt / "checkpoint.h5") == "first");
    }
}

TEST_CASE("hinf resume after a kill that left the run's checkpoint inside an unfinished exchange", "[io][swap][cli]") {
    hinf::test::TempDir d("run-swap-resume");
    const std::string cfg = d / "tiny.toml";
    std::ofstream(cfg) << hinf::test::tiny_missile_config();
    const fs::path dir = d / "run", alt = dir / "alternative", folder = dir / hinf::kSwapFolder;
    REQUIRE(hinf::test::run_hinf("train " + cfg + " --out " + dir.string() + " --until 0.02 --quiet").status == 0);
    kill_in_exchange(dir);
    auto r = hinf::test::run_hinf("resume " + (dir / "checkpoint.h5").string() + " --quiet");
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK(r.output.find("the exchange is finished") != std::string::npos);
    CHECK(r.output.find("trained time steps 2..5") != std::string::npos);
    CHECK_FALSE(fs::exists(folder));
    CHECK(fs::exists(alt / "checkpoint.h5"));
}

TEST_CASE("hinf sweep after a kill that left a value's checkpoint inside an unfinished exchange", "[io][swap][cli]") {
    // a value's runs are exchanged since its values end as hinf train does (another storage or game kept)
    hinf::test::TempDir d("run-swap-sweep");
    const std::string cfg = d / "tiny.toml";
    std::ofstream(cfg) << hinf::test::tiny_missile_config();
    const std::string sweep = "sweep " + cfg + " --vary training.seed=1 --out " + (d / "sweep");
    REQUIRE(hinf::test::run_hinf(sweep + " --until 0.02").status == 0);
    const fs::path dir = fs::path(d / "sweep") / "training.seed=1", alt = dir / "alternative",
                   folder = dir / hinf::kSwapFolder;
    fs::remove(dir / "summary.csv");  // a value killed before its end has none
    kill_in_exchange(dir);
    auto r = hinf::test::run_hinf(sweep);
    INFO(r.output);
    CHECK(r.status == 0);
    CHECK(r.output.find("the exchange is finished") != std::string::npos);
    CHECK(r.output.find("training.seed=1") != std::string::npos);
    CHECK(r.output.find(" resumed ") != std::string::npos);  // not trained afresh
    CHECK_FALSE(fs::exists(folder));
    CHECK(fs::exists(alt / "checkpoint.h5"));
}
