// The `hinf` command line: dispatches subcommands; turns hinf::Error into one line on stderr + exit 2.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <unistd.h>
#include <iostream>
#include <thread>

#include "cli/commands.hpp"
#include "hinf/error.hpp"
#include "par/par.hpp"

int run(int argc, char** argv);

namespace {

// The one line of an error, then the exit. Under mpirun a rank that fails alone would leave the others waiting
// in a collective, so every failing rank ends the whole job (MPI_Abort). An error every rank meets (a bad
// argument, a bad config) is printed by rank 0 only: the others wait a moment, in which rank 0's abort ends
// them; a rank that fails alone still prints its line, with its rank, after that moment. The moment is 2 s: with
// 500 ms a rank printed its copy of a shared error in a fresh-clone CI run, where ctest -j2 ran 3 ranks and another
// test on 2 cores and rank 0 reached the error late.
int fail(const std::string& line, int code) {
    if (hinf::par_world_size() == 1) {
        std::cerr << line << "\n";
        return code;
    }
    if (hinf::par_world_rank() != 0) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2000));
        std::cerr << line << " (rank " << hinf::par_world_rank() << ")\n";
    } else {
        std::cerr << line << "\n";
        std::cerr.flush();
        // let mpirun forward the line before MPI_Abort makes it print its own banner (seen in CI: the banner first)
        std::this_thread::sleep_for(std::chrono::milliseconds(200));
    }
    std::cerr.flush();
    hinf::par_abort(code);
}

}  // namespace

int main(int argc, char** argv) {
    // OpenMP threads that spin long at barriers are disastrous when the cores are shared (measured: 1060 vs
    // 138 ms per training time step at load 8 with libgomp's default spin of 300000), and threads that
    // sleep at once (OMP_WAIT_POLICY=PASSIVE) pay a futex wake-up at each of a training step's parallel
    // regions (measured: 0.81 -> 1.1-1.6 ms per step on two cores). So, unless the user has chosen, spin
    // briefly and then sleep: GOMP_SPINCOUNT for libgomp, KMP_BLOCKTIME (ms) for LLVM's libomp. The
    // runtime reads these when it loads, so set them and re-execute once. docs/method.md section 11.
    if (std::getenv("OMP_WAIT_POLICY") == nullptr && std::getenv("GOMP_SPINCOUNT") == nullptr &&
        std::getenv("KMP_BLOCKTIME") == nullptr) {
        setenv("GOMP_SPINCOUNT", "1000", 1);
        setenv("KMP_BLOCKTIME", "1", 1);
        execv("/proc/self/exe", argv);  // returns only on failure: then carry on with the runtime's default
    }
    hinf::par_init(&argc, &argv);
    // only rank 0 prints results (every rank computes them); errors still reach stderr from any rank
    if (hinf::par_world_rank() != 0 && std::freopen("/dev/null", "w", stdout) == nullptr) return 3;
    // a status every rank returns alike (e.g. 4: diverged) ends the job normally; errors abort it in fail()
    const int rc = run(argc, argv);
    hinf::par_finalize();
    // after an error (its line is printed) end without libhdf5's exit handler: on a full file system it flushes
    // files a failed write left open and crashed (exit 139 after the error line); every result file is written
    // atomically, so nothing complete depends on that flush
    if (rc != 0) {
        std::fflush(nullptr);
        std::_Exit(rc);
    }
    return rc;
}

int run(int argc, char** argv) {
    CLI::App app{"hinf: robust nonlinear filters by deep-network solutions of the Hamilton-Jacobi-Isaacs equation"};
    app.set_version_flag("--version", "hinf 0.1.0");
    app.footer("Seed 000, 001 and 002 in the help and notes are the three papers hinf implements: the H-infinity DNN "
               "filter (Chen, Wu, Lee, IEEE Access 2021), the mixed H2/H-infinity DNN filter (Chen, Ma, Wu, AI Advances "
               "2024) and the global-linearization LMI filter (Mao, Deng, Wan, Sci China Inf Sci 2016): README.md, "
               "docs/method.md.");
    app.require_subcommand(1);
    // argument errors follow the same one-line contract as every other error
    const std::string sub = argc > 1 && argv[1][0] != '-' ? std::string(" ") + argv[1] : "";
    app.failure_message([sub](const CLI::App*, const CLI::Error& e) {
        std::string what = e.what();
        // CLI11's "--filters: At Most 1 required but received 2": an option given twice
        const std::string twice = "At Most 1 required but received ";
        const std::size_t at = what.find(twice);
        if (at != std::string::npos)
            what = what.substr(0, at) + "given " + what.substr(at + twice.size()) +
                   " times, but it takes one value (join several with commas, e.g. --filters ekf,ukf)";
        return "hinf: error: " + what + " (see `hinf" + sub + " --help`)\n";
    });
    hinf::cli::add_train_commands(app);
    hinf::cli::add_operate_command(app);
    hinf::cli::add_bench_command(app);
    hinf::cli::add_lmi_command(app);
    hinf::cli::add_compare_command(app);
    hinf::cli::add_filter_command(app);
    hinf::cli::add_worst_command(app);
    hinf::cli::add_export_command(app);
    hinf::cli::add_rho_command(app);
    try {
        app.parse(argc, argv);
    } catch (const CLI::RuntimeError& e) {
        return e.get_exit_code();  // a subcommand's own status (e.g. 4: design failed, diverged)
    } catch (const CLI::ParseError& e) {
        int code = app.exit(e);
        return code == 0 ? 0 : 2;
    } catch (const hinf::Error& e) {
        return fail(std::string("hinf: error: ") + e.what(), 2);
    } catch (const std::filesystem::filesystem_error& e) {
        // a path the user gave that cannot be created or written (read-only, a file where a directory is
        // expected, no space): the user's to fix, one line like every other input error
        std::string where = e.path1().string();
        return fail("hinf: error: cannot use '" + where + "': " + e.code().message() +
                        " (check that the output path is a directory you can write, or pass another --out)",
                    2);
    } catch (const std::exception& e) {
        return fail(std::string("hinf: internal error: ") + e.what() + " (please report this with the command you ran)", 3);
    } catch (...) {  // a library's own exception type (e.g. muParser's) that escaped a conversion: still one line
        return fail("hinf: internal error: an unexpected exception (please report this with the command you ran)", 3);
    }
    return 0;
}
