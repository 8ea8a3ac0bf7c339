// MPI behind src/par/par.hpp: the world, an optional split into groups, rank-ordered all-gathers.
// Rank and size are cached at init and at each split: OpenMP threads ask for them (progress lines) and, with
// MPI_THREAD_FUNNELED, only the main thread may call MPI.
#include "par/par.hpp"

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <unistd.h>

#include "hinf/error.hpp"

#ifdef HINF_HAVE_MPI
#include <mpi.h>
#endif

namespace hinf {

namespace {
int g_rank = 0, g_size = 1, g_world_rank = 0, g_world_size = 1;
bool g_started = false;  // par_init called MPI_Init
#ifdef HINF_HAVE_MPI
MPI_Comm g_comm = MPI_COMM_NULL;  // the work communicator (world or a group)

MPI_Comm comm() { return g_comm; }

void check(int rc, const char* what) {
    if (rc == MPI_SUCCESS) return;
    char msg[MPI_MAX_ERROR_STRING];
    int len = 0;
    MPI_Error_string(rc, msg, &len);
    std::fprintf(stderr, "hinf: error on rank %d: %s failed: %.*s\n", g_world_rank, what, len, msg);
    MPI_Abort(MPI_COMM_WORLD, 2);
}

// When one process of a job dies (killed, out of memory, a crash), mpirun ends the others with SIGTERM, and its
// own message names only the dead rank's PID and signal. Rank 0, which prints everything else, then says in
// one line what happened to the run and what is safe (only write(2): async-signal-safe), and dies of the signal.
void on_terminate(int sig) {
    static const char line[] =
        "hinf: error: this MPI job was stopped while running (another process died or mpirun was interrupted: "
        "see mpirun's message); result files are written whole or not at all, and a training continues from its "
        "last checkpoint with `hinf resume DIR/checkpoint.h5` under any process count\n";
    ssize_t ignored = write(STDERR_FILENO, line, sizeof line - 1);
    (void)ignored;
    std::signal(sig, SIG_DFL);
    std::raise(sig);
}

// mpirun (OpenMPI, MPICH, Slurm's PMI) leaves one of these in the environment of every process it starts
bool launched_by_mpi() {
    for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK", "PMI_RANK", "MPI_LOCALNRANKS"})
        if (std::getenv(v) != nullptr) return true;
    return false;
}
#endif
}  // namespace

bool par_built() {
#ifdef HINF_HAVE_MPI
    return true;
#else
    return false;
#endif
}

void par_init(int* argc, char*** argv) {
#ifdef HINF_HAVE_MPI
    // a plain `hinf ...` stays one process and never touches MPI (no PMIx daemon, no network probing)
    if (!launched_by_mpi()) return;
    int provided = 0;
    MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
    g_started = true;
    // a failed call returns its code to check(), which prints one line and aborts the job
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    MPI_Comm_rank(MPI_COMM_WORLD, &g_world_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &g_world_size);
    g_comm = MPI_COMM_WORLD;
    g_rank = g_world_rank;
    g_size = g_world_size;
    if (g_world_rank == 0 && g_world_size > 1) {
        struct sigaction sa {};
        sa.sa_handler = on_terminate;
        sigemptyset(&sa.sa_mask);
        sigaction(SIGTERM, &sa, nullptr);
    }
#else
    (void)argc;
    (void)argv;
#endif
}

void par_finalize() {
#ifdef HINF_HAVE_MPI
    if (!g_started) return;
    par_unsplit();
    MPI_Finalize();
    g_started = false;
#endif
}

void par_abort(int code) {
#ifdef HINF_HAVE_MPI
    if (g_started) MPI_Abort(MPI_COMM_WORLD, code);
#endif
    std::fflush(stdout);
    std::exit(code);
}

int par_rank() { return g_rank; }
int par_size() { return g_size; }
int par_world_rank() { return g_world_rank; }
int par_world_size() { return g_world_size; }

int par_split(int groups) {
    HINF_CHECK(groups >= 1 && groups <= g_world_size,
               std::to_string(groups) + " group(s) for " + std::to_string(g_world_size) + " process(es)");
    const int group = int(std::int64_t(g_world_rank) * groups / g_world_size);
#ifdef HINF_HAVE_MPI
    if (g_started) {
        par_unsplit();
        MPI_Comm c;
        check(MPI_Comm_split(MPI_COMM_WORLD, group, g_world_rank, &c), "MPI_Comm_split");
        MPI_Comm_set_errhandler(c, MPI_ERRORS_RETURN);
        g_comm = c;
        MPI_Comm_rank(c, &g_rank);
        MPI_Comm_size(c, &g_size);
    }
#endif
    return group;
}

void par_unsplit() {
#ifdef HINF_HAVE_MPI
    if (g_started && g_comm != MPI_COMM_WORLD) {
        MPI_Comm_free(&g_comm);
        g_comm = MPI_COMM_WORLD;
        g_rank = g_world_rank;
        g_size = g_world_size;
    }
#endif
}

std::vector<std::vector<char>> par_allgather(const std::vector<char>& mine) {
    std::vector<std::vector<char>> all(g_size);
    if (g_size == 1) {
        all[0] = mine;
        return all;
    }
#ifdef HINF_HAVE_MPI
    HINF_CHECK(mine.size() <= std::size_t(std::numeric_limits<int>::max()), "par_allgather: more than 2 GiB from one rank");
    int n = int(mine.size());
    std::vector<int> counts(g_size), displs(g_size);
    check(MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, comm()), "MPI_Allgather");
    std::int64_t total = 0;
    for (int r = 0; r < g_size; ++r) {
        HINF_CHECK(total <= std::numeric_limits<int>::max(), "par_allgather: more than 2 GiB in all");
        displs[r] = int(total);
        total += counts[r];
    }
    std::vector<char> buf(std::size_t(total) + 1);
    check(MPI_Allgatherv(mine.data(), n, MPI_BYTE, buf.data(), counts.data(), displs.data(), MPI_BYTE, comm()),
          "MPI_Allgatherv");
    for (int r = 0; r < g_size; ++r) all[r].assign(buf.data() + displs[r], buf.data() + displs[r] + counts[r]);
#endif
    return all;
}

void par_allgather_items(void* base, std::int64_t item_bytes, const std::int64_t* begin) {
    if (g_size == 1) return;
#ifdef HINF_HAVE_MPI
    // counted in items of a contiguous type, so that a gradient of many MB stays below int's range
    HINF_CHECK(item_bytes > 0 && item_bytes <= std::numeric_limits<int>::max(), "par_allgather_items: item size");
    MPI_Datatype item;
    check(MPI_Type_contiguous(int(item_bytes), MPI_BYTE, &item), "MPI_Type_contiguous");
    MPI_Type_commit(&item);
    std::vector<int> counts(g_size), displs(g_size);
    for (int r = 0; r < g_size; ++r) {
        HINF_CHECK(begin[r + 1] - begin[0] <= std::numeric_limits<int>::max(), "par_allgather_items: too many items");
        counts[r] = int(begin[r + 1] - begin[r]);
        displs[r] = int(begin[r] - begin[0]);
    }
    char* first = static_cast<char*>(base) + begin[0] * item_bytes;
    check(MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, first, counts.data(), displs.data(), item, comm()),
          "MPI_Allgatherv");
    MPI_Type_free(&item);
#else
    (void)base;
    (void)item_bytes;
    (void)begin;
#endif
}

std::vector<double> par_allgather_double(double mine) {
    std::vector<double> all(g_size, mine);
#ifdef HINF_HAVE_MPI
    if (g_size > 1) check(MPI_Allgather(&mine, 1, MPI_DOUBLE, all.data(), 1, MPI_DOUBLE, comm()), "MPI_Allgather");
#endif
    return all;
}

void par_broadcast(std::vector<char>& bytes) {
    if (g_size == 1) return;
#ifdef HINF_HAVE_MPI
    long long n = static_cast<long long>(bytes.size());
    check(MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, comm()), "MPI_Bcast");
    HINF_CHECK(n <= std::numeric_limits<int>::max(), "par_broadcast: more than 2 GiB");
    bytes.resize(std::size_t(n));
    check(MPI_Bcast(bytes.data(), int(n), MPI_BYTE, 0, comm()), "MPI_Bcast");
#endif
}

void par_barrier() {
#ifdef HINF_HAVE_MPI
    if (g_size > 1) check(MPI_Barrier(comm()), "MPI_Barrier");
#endif
}

}  // namespace hinf
