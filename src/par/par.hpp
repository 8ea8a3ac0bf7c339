// The processes of one MPI job (issue 16): init and finalize, rank and size, a clean abort, and the few
// collectives hinf needs, all taken in rank order so that results never depend on the number of processes.
// Not a transport of its own (OpenMPI does that) and not the split of any particular work (eval/engine and
// train/trainer decide which process computes what). Without MPI (built with -DHINF_MPI=OFF, or a binary not
// started by mpirun) there is one process of rank 0 and every collective is a copy.
#pragma once
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "hinf/error.hpp"

namespace hinf {

/// True when this build has MPI (find_package(MPI) found it and HINF_MPI is ON).
bool par_built();
/// MPI_Init_thread (funneled: only the main thread talks to MPI) when started by mpirun; else nothing.
void par_init(int* argc, char*** argv);
/// MPI_Finalize when par_init started MPI.
void par_finalize();
/// Ends every process of the job with `code` (MPI_Abort); without MPI std::exit(code).
[[noreturn]] void par_abort(int code);

/// This process's place in the work communicator (all processes, or its group after par_split).
int par_rank();
int par_size();
inline bool par_root() { return par_rank() == 0; }
/// Its place among all processes of the job (rank 0 of the world prints).
int par_world_rank();
int par_world_size();

/// Splits the processes into `groups` groups of consecutive world ranks (world rank w joins group
/// w * groups / world size); par_rank/par_size then refer to the group. Returns this process's group.
int par_split(int groups);
/// Back to one work communicator of all processes.
void par_unsplit();

/// Every process's bytes, in rank order, on every process of the work communicator.
std::vector<std::vector<char>> par_allgather(const std::vector<char>& mine);
/// In place: base holds items [begin[r], begin[r + 1]) of item_bytes bytes each from rank r (begin has
/// par_size() + 1 entries); on return every rank holds all items [begin[0], begin[size]).
void par_allgather_items(void* base, std::int64_t item_bytes, const std::int64_t* begin);
/// One double per rank, in rank order, on every rank.
std::vector<double> par_allgather_double(double mine);
/// The root's bytes on every rank of the work communicator.
void par_broadcast(std::vector<char>& bytes);
void par_barrier();

/// A result packed as bytes for par_allgather: plain values and vectors of doubles, read back in the order
/// they were put (par_bytes_in). The packing is memcpy of the host's representation: every rank of a job
/// runs the same binary on the same kind of machine.
struct ParBytesOut {
    std::vector<char> bytes;
    void put(const void* p, std::size_t n) { bytes.insert(bytes.end(), static_cast<const char*>(p), static_cast<const char*>(p) + n); }
    void put(double v) { put(&v, sizeof v); }
    void put(std::uint64_t v) { put(&v, sizeof v); }
    void put(const std::vector<double>& v) {
        put(std::uint64_t(v.size()));
        put(v.data(), sizeof(double) * v.size());
    }
    void put(const std::string& s) {
        put(std::uint64_t(s.size()));
        put(s.data(), s.size());
    }
};

struct ParBytesIn {
    const char* p;
    const char* end;
    explicit ParBytesIn(const std::vector<char>& b) : p(b.data()), end(b.data() + b.size()) {}
    void get(void* dst, std::size_t n) {
        HINF_CHECK(std::size_t(end - p) >= n, "a process sent a truncated result (bug)");
        if (n == 0) return;  // an empty vector's data() may be null, which memcpy must not see
        std::memcpy(dst, p, n);
        p += n;
    }
    double get_double() { double v; get(&v, sizeof v); return v; }
    std::uint64_t get_u64() { std::uint64_t v; get(&v, sizeof v); return v; }
    std::vector<double> get_vector() {
        std::vector<double> v(get_u64());
        get(v.data(), sizeof(double) * v.size());
        return v;
    }
    std::string get_string() {
        std::string s(get_u64(), '\0');
        get(s.data(), s.size());
        return s;
    }
    bool at_end() const { return p == end; }
};

/// [begin, end) of `count` items for rank r of `size`: consecutive blocks, sizes differing by at most one.
inline std::int64_t par_block_begin(std::int64_t count, int r, int size) { return count * r / size; }

}  // namespace hinf
