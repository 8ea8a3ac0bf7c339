// The MPI layer (src/par) and what runs over it: one process without mpirun; under `mpirun -np R` (when
// built with MPI) compare.h5 holds the same bits for R = 1, 2, 3 as a plain single-process run.
#include <catch2/catch.hpp>

#include "eval/engine.hpp"
#include "helpers.hpp"
#include "hinf/error.hpp"
#include "par/h5_same.hpp"
#include "par/par.hpp"

using hinf::test::CommandResult;
using hinf::test::TempDir;

namespace {

// mpirun as root on a 2-core CI box: oversubscription allowed, root allowed, no network probing needed
std::string mpirun(int np) {
    return "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1 " +
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
