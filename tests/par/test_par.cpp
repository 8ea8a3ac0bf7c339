// The MPI layer (src/par) and what runs over it: one process without mpirun; under `mpirun -np R` (when
// built with MPI) compare.h5 holds the same bits for R = 1, 2, 3 as a plain single-process run.
#include <catch2/catch.hpp>
#include <cstdlib>
#include <filesystem>

#include "eval/engine.hpp"
#include "helpers.hpp"
#include "hinf/error.hpp"
#include "par/h5_same.hpp"
#include "par/par.hpp"

using hinf::test::CommandResult;
using hinf::test::TempDir;

namespace {

// mpirun as root on a 2-core CI box: oversubscription allowed, root allowed, no network probing needed.
// Under the sanitizer stage (ASAN_OPTIONS set by scripts/sanitize) leak checking is off for the processes mpirun
// starts: OpenMPI's plugins (dlopened MCA components) leak at exit and are unloaded before LeakSanitizer can name
// them, so no suppression can match them; every other sanitizer check stays on, and hinf's own leaks are checked
// by the rest of the suite, which runs the same code without mpirun.
std::string mpirun(int np) {
    const char* asan = std::getenv("ASAN_OPTIONS");
    const std::string leaks = asan != nullptr ? "ASAN_OPTIONS=" + std::string(asan) + ":detect_leaks=0 " : "";
    return "env OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1 " + leaks +
           std::string(HINF_MPIEXEC) + " --oversubscribe -np " + std::to_string(np) + " ";
}

bool have_mpi() { return std::string(HINF_MPIEXEC).size() > 0 && hinf::par_built(); }

}  // namespace

TEST_CASE("without mpirun hinf is one process of rank 0 and every collective is a copy", "[par]") {
    CHECK(hinf::par_rank() == 0);
    CHECK(hinf::par_size() == 1);
    CHECK(hinf::par_world_size() == 1);
    const std::vector<char> mine{'a', 'b', 'c'};
    auto all = hinf::par_allgather(mine);
    REQUIRE(all.size() == 1);
    CHECK(all[0] == mine);
    double items[4] = {1, 2, 3, 4};
    const std::int64_t begin[2] = {0, 4};
    hinf::par_allgather_items(items, sizeof(double), begin);
    CHECK(items[3] == 4);
    CHECK(hinf::par_allgather_double(2.5) == std::vector<double>{2.5});
    CHECK(hinf::par_split(1) == 0);
    CHECK(hinf::par_size() == 1);
    CHECK_THROWS_AS(hinf::par_split(2), hinf::Error);
    hinf::par_unsplit();
}

TEST_CASE("Monte Carlo runs are dealt out over the processes, every run to exactly one", "[par][eval]") {
    for (int ranks : {1, 2, 3, 7}) {
        std::vector<int> count(ranks, 0);
        for (std::int64_t r = 0; r < 50; ++r) {
            const std::int64_t q = hinf::engine_rank_of(r, ranks);
            REQUIRE(q >= 0);
            REQUIRE(q < ranks);
            ++count[q];
        }
        for (int c : count) CHECK(std::abs(c - 50 / ranks) <= 1);
        CHECK(hinf::engine_rank_of(0, ranks) == 0);  // run 0 (written in full to the files) is rank 0's
    }
}

TEST_CASE("compare.h5 holds the same bits for mpirun -np 1, 2, 3 as for one plain process", "[par][mpi][compare]") {
    if (!have_mpi()) {
        WARN("built without MPI (HINF_MPI=OFF or no libopenmpi-dev): nothing to launch");
        return;
    }
    TempDir d("par-compare");
    // a built-in system: expression systems (runs/vanderpol.toml) differ in the last bits with the heap
    // layout already in one process (docs/scaling.md), and mpirun's threads make the layout vary
    const std::string args = " compare " + hinf::test::source_path("runs/missile_hinf.toml") +
                             " --filters ekf,ukf,pf,open_loop --particles 100 --runs 5 --until 2 --threads 1 --quiet --out ";
    CommandResult one = hinf::test::run_hinf(args + d / "plain");
    INFO(one.output);
    REQUIRE(one.status == 0);
    const std::set<std::string> timings{"us_per_step"};
    for (int np : {1, 2, 3}) {
        const std::string out = d / ("np" + std::to_string(np));
        CommandResult r = hinf::test::run_command(mpirun(np) + HINF_CLI_PATH + args + out);
        INFO("mpirun -np " << np << "\n" << r.output);
        REQUIRE(r.status == 0);
        if (np > 1) CHECK(r.output.find("load balance over " + std::to_string(np) + " processes") != std::string::npos);
        // rank 0 alone prints: the table once
        CHECK(r.output.find("measurement streams identical") == r.output.rfind("measurement streams identical"));
        const auto diff = hinf::test::h5_differences(d / "plain/compare.h5", out + "/compare.h5", timings);
        for (const auto& p : diff) UNSCOPED_INFO("differs: " << p);
        CHECK(diff.empty());
        CHECK(hinf::test::h5_contents(out + "/compare.h5", timings).size() > 40);
    }
}

TEST_CASE("more processes than Monte Carlo runs: one line from rank 0 and a non-zero exit, no hang", "[par][mpi]") {
    if (!have_mpi()) {
        WARN("built without MPI: nothing to launch");
        return;
    }
    TempDir d("par-bad");
    CommandResult r = hinf::test::run_command(mpirun(3) + HINF_CLI_PATH + " compare " +
                                              hinf::test::source_path("runs/vanderpol.toml") +
                                              " --filters ekf --runs 2 --until 1 --threads 1 --quiet --out " + d / "o");
    INFO(r.output);
    CHECK(r.status == 2);
    CHECK(r.output.rfind("hinf: error: 3 MPI processes for 2 run(s)", 0) == 0);
    // the line is printed once (by rank 0), whatever mpirun adds after it
    CHECK(r.output.find("MPI processes for") == r.output.rfind("MPI processes for"));
}

TEST_CASE("worst-case search: restarts dealt out over the processes, worst.h5 and a replay the same bits for "
          "mpirun -np 1, 2, 3 as for one plain process", "[par][mpi][worst]") {
    if (!have_mpi()) {
        WARN("built without MPI: nothing to launch");
        return;
    }
    TempDir d("par-worst");
    // 4 filters x (2 random + 1 scenario + the linear start) = 16 restarts; the PF's restarts are dealt to every process;
    // every process computes the linear starts (2 pieces a channel here), the same bits
    const std::string cfg = hinf::test::source_path("runs/missile_hinf.toml");
    const std::string args = " worst " + cfg + " --filters ekf,ukf,pf,open_loop --particles 100 --until 2 --evals 10 "
                             "--random-starts 2 --scenario-starts nominal --linear-pieces 2 --linear-steps 0 --threads 1 --quiet --out ";
    CommandResult one = hinf::test::run_hinf(args + d / "plain");
    INFO(one.output);
    REQUIRE(one.status == 0);
    const std::set<std::string> timings{"wall_seconds"};
    for (int np : {1, 2, 3}) {
        const std::string out = d / ("np" + std::to_string(np));
        CommandResult r = hinf::test::run_command(mpirun(np) + HINF_CLI_PATH + args + out);
        INFO("mpirun -np " << np << "\n" << r.output);
        REQUIRE(r.status == 0);
        CHECK(r.output.find("worst ratio") == r.output.rfind("worst ratio"));  // rank 0 alone prints the table
        const auto diff = hinf::test::h5_differences(d / "plain/worst.h5", out + "/worst.h5", timings);
        for (const auto& p : diff) UNSCOPED_INFO("differs: " << p);
        CHECK(diff.empty());
        CHECK(hinf::test::h5_contents(out + "/worst.h5", timings).size() > 40);
    }
    // the replay of the 4 saved sets split over 3 processes (one of them replays two)
    const std::string replay = " worst " + cfg + " --replay " + d / "plain/worst.h5" +
                               " --filters ekf,pf --particles 100 --threads 1 --quiet --out ";
    CommandResult p1 = hinf::test::run_hinf(replay + d / "replay1");
    INFO(p1.output);
    REQUIRE(p1.status == 0);
    CommandResult p3 = hinf::test::run_command(mpirun(3) + HINF_CLI_PATH + replay + d / "replay3");
    INFO(p3.output);
    REQUIRE(p3.status == 0);
    const auto diff = hinf::test::h5_differences(d / "replay1/replay.h5", d / "replay3/replay.h5", {});
    for (const auto& p : diff) UNSCOPED_INFO("differs: " << p);
    CHECK(diff.empty());
    // more processes than restarts: one line from rank 0, non-zero exit, no hang
    CommandResult bad = hinf::test::run_command(mpirun(3) + HINF_CLI_PATH + " worst " + cfg +
                                                " --filters ekf --until 1 --evals 4 --random-starts 1 "
                                                "--scenario-starts nominal --linear-pieces 0 --threads 1 --quiet --out " + d / "bad");
    INFO(bad.output);
    CHECK(bad.status == 2);
    CHECK(bad.output.rfind("hinf: error: 3 MPI processes for 2 restart(s)", 0) == 0);
    CHECK(bad.output.find("MPI processes for") == bad.output.rfind("MPI processes for"));
}

TEST_CASE("a process that dies takes the job down, with one line from rank 0 and no hang", "[par][mpi]") {
    if (!have_mpi()) {
        WARN("built without MPI: nothing to launch");
        return;
    }
    TempDir d("par-die");
    // rank 1 kills itself (kill -9, as the kernel's OOM killer would) once rank 0 has taken the run directory's lock,
    // which it does after par_init has set its SIGTERM handler, in a run that takes far longer (14 s on 2 processes,
    // Release). A fixed second's wait raced rank 0's start under the sanitizers on a loaded CI machine: rank 0 was
    // ended before par_init, and so without its line. `timeout` turns a hang into status 124.
    const std::string out = d / "o";
    const std::string job = std::string(HINF_CLI_PATH) + " compare " + hinf::test::source_path("runs/missile_hinf.toml") +
                            " --filters pf --particles 4000 --runs 4 --threads 1 --quiet --out " + out;
    CommandResult r = hinf::test::run_command(
        "timeout 60 " + mpirun(2) + "bash -c 'if [ \"$OMPI_COMM_WORLD_RANK\" = 1 ]; then (for i in $(seq 400); do [ -e " +
        out + "/.hinf.lock ] && break; sleep 0.1; done; sleep 0.2; kill -9 $$) & fi; exec " + job + "'");
    INFO(r.output);
    CHECK(r.status != 0);
    CHECK(r.status != 124);
    const std::string line = "hinf: error: this MPI job was stopped while running";
    CHECK(r.output.find(line) != std::string::npos);
    CHECK(r.output.find(line) == r.output.rfind(line));  // rank 0's, once
    CHECK(r.output.find("exited on signal 9") != std::string::npos);  // mpirun's own line names the dead rank
    CHECK(!std::filesystem::exists(d / "o/compare.h5"));
}

namespace {

// 6 chunks of 50 samples per minibatch: split 6/3/2 over 1/2/3 processes
std::string data_parallel_config(const std::string& t_final, const std::string& variant = "dissipative") {
    return "[system]\nkind = \"missile\"\n[filter]\nvariant = \"" + variant + "\"\nt_final = " + t_final +
           "\n[network]\nhidden = [16]\nchunk = 50\n[training]\nsamples = 400\nbatch = 300\nadam_steps = 3\n"
           "checkpoint_every = 2\nacceptance_runs = 0\n";  // the plain runs compared with sweeps: no acceptance attributes
}

void check_same_run(const std::string& a, const std::string& b) {
    for (const char* f : {"/checkpoint.h5", "/trajectory.h5"}) {
        const auto diff = hinf::test::h5_differences(a + f, b + f, {});
        for (const auto& p : diff) UNSCOPED_INFO("differs: " << f << " " << p);
        CHECK(diff.empty());
    }
}

}  // namespace

TEST_CASE("data-parallel training: the weights after a few steps are the same bits for mpirun -np 1, 2, 3 as for "
          "one plain process", "[par][mpi][train]") {
    if (!have_mpi()) {
        WARN("built without MPI: nothing to launch");
        return;
    }
    TempDir d("par-train");
    // gain: four errors per estimate (400, 300), 6 chunks of 13 estimates, S(t) knots gathered per estimate
    for (const char* variant : {"dissipative", "gain"}) {
        INFO("variant " << variant);
        const std::string v = variant;
        const std::string cfg = hinf::test::write_file(d, v + ".toml", data_parallel_config("0.04", v));
        CommandResult one = hinf::test::run_hinf("train " + cfg + " --threads 1 --quiet --out " + d / (v + "_plain"));
        INFO(one.output);
        REQUIRE(one.status == 0);
        for (int np : {2, 3}) {
            const std::string out = d / (v + "_np" + std::to_string(np));
            CommandResult r =
                hinf::test::run_command(mpirun(np) + HINF_CLI_PATH + " train " + cfg + " --threads 1 --quiet --out " + out);
            INFO("mpirun -np " << np << "\n" << r.output);
            REQUIRE(r.status == 0);
            check_same_run(d / (v + "_plain"), out);
        }
    }
    const std::string cfg = d / "dissipative.toml";
    // more processes than chunks: one line, non-zero exit
    CommandResult bad = hinf::test::run_command(mpirun(7) + HINF_CLI_PATH + " train " + cfg + " --threads 1 --quiet --out " + d / "bad");
    INFO(bad.output);
    CHECK(bad.status == 2);
    CHECK(bad.output.rfind("hinf: error: 7 MPI processes for a minibatch of 6 chunk(s)", 0) == 0);
}

TEST_CASE("kill -9 of an MPI training run, resume under another process count: the same bits as an uninterrupted "
          "run", "[par][mpi][train][resume]") {
    if (!have_mpi()) {
        WARN("built without MPI: nothing to launch");
        return;
    }
    TempDir d("par-kill");
    const std::string cfg = hinf::test::write_file(d, "dp.toml", data_parallel_config("0.5"));
    CommandResult one = hinf::test::run_hinf("train " + cfg + " --threads 1 --quiet --out " + d / "plain");
    INFO(one.output);
    REQUIRE(one.status == 0);
    // the whole job (mpirun and its ranks, which OpenMPI puts in process groups of their own, all in one
    // session) is killed once the first checkpoint is there
    const std::string out = d / "killed";
    CommandResult killed = hinf::test::run_command(
        "bash -c 'setsid " + mpirun(2) + HINF_CLI_PATH + " train " + cfg + " --threads 1 --quiet --out " + out +
        " >/dev/null 2>&1 & p=$!; for i in $(seq 500); do [ -f " + out + "/checkpoint.h5 ] && break; sleep 0.01; done; "
        "pkill -KILL -s $p; wait $p; echo killed $?'");
    INFO(killed.output);
    CHECK(killed.output.find("killed 137") != std::string::npos);
    CommandResult resumed = hinf::test::run_command(mpirun(3) + HINF_CLI_PATH + " resume " + out +
                                                    "/checkpoint.h5 --threads 1 --quiet");
    INFO(resumed.output);
    REQUIRE(resumed.status == 0);
    // it continued from a checkpoint before the end: the kill came mid-run
    CHECK(resumed.output.find("trained time steps 0..") == std::string::npos);
    CHECK(resumed.output.find("trained time steps 50..50") == std::string::npos);
    check_same_run(d / "plain", out);
}

TEST_CASE("hinf sweep: one training per value and process group, each as its own run, and a second job resumes what "
          "a killed one left and skips what it finished", "[par][mpi][sweep]") {
    TempDir d("par-sweep");
    // with the checkpoint selection ([training] is the config's last section): a sweep's values validate as
    // `hinf train` does, in their groups
    const std::string cfg = hinf::test::write_file(d, "dp.toml", data_parallel_config("0.04") + "select_every = 2\n");
    // seed 2 as a killed job leaves it: a checkpoint part of the way, no summary
    CommandResult part = hinf::test::run_hinf("train " + cfg + " --set training.seed=2 --until 0.02 --threads 1 --quiet --out " +
                                              d / "sweep/training.seed=2");
    INFO(part.output);
    REQUIRE(part.status == 0);
    const std::string launch = have_mpi() ? mpirun(2) + HINF_CLI_PATH : std::string(HINF_CLI_PATH);
    CommandResult r = hinf::test::run_command(launch + " sweep " + cfg + " --vary training.seed=1,2,3 --threads 1 --quiet --out " + d / "sweep");
    INFO(r.output);
    REQUIRE(r.status == 0);
    CHECK(r.output.find("resumed") != std::string::npos);
    CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 6);  // header line, table of 3, files line: rank 0 alone
    const auto rows = hinf::test::read_csv_rows(d / "sweep/sweep.csv");
    CHECK(rows.size() == 3);
    for (const auto& row : rows) {
        CHECK(row.at("key") == "training.seed");
        // as `hinf train`: best.h5 validated at steps 2 and 4 (the acceptance check is off in this config)
        CHECK((row.at("best_step") == "2" || row.at("best_step") == "4"));
        CHECK(std::filesystem::exists(row.at("dir") + "/best.h5"));
        CHECK(row.at("acceptance") == "-");
    }
    // each value's run is the run `hinf train --set training.seed=V` gives
    for (const char* seed : {"2", "3"}) {
        const std::string plain = d / (std::string("plain") + seed);
        REQUIRE(hinf::test::run_hinf("train " + cfg + " --set training.seed=" + seed + " --threads 1 --quiet --out " + plain).status == 0);
        check_same_run(plain, d / (std::string("sweep/training.seed=") + seed));
    }
    CommandResult again = hinf::test::run_command(launch + " sweep " + cfg + " --vary training.seed=1,2,3 --threads 1 --out " + d / "sweep");
    INFO(again.output);
    CHECK(again.status == 0);
    // without --quiet: a line after each value of rank 0's group (values 1 and 3 of two groups; all three of one)
    CHECK(std::count(again.output.begin(), again.output.end(), '\n') == 6 + (have_mpi() ? 2 : 3));
    CHECK(again.output.find("sweep: training.seed=1 done before: status 0, training ") != std::string::npos);
    CHECK(again.output.find(have_mpi() ? "2/2 values of this process group done" : "3/3 values done") !=
          std::string::npos);
    CHECK(again.output.find("done before") != std::string::npos);
    CHECK(again.output.find("trained ") == std::string::npos);
    hinf::test::expect_one_line_error("sweep " + cfg + " --vary training.seed= --out " + d / "bad", "a sweep needs at least one value");
}
