// The processes of one MPI job (issue 16): init and finalize, rank and size, a clean abort, and the few
// collectives hinf needs, all taken in rank order so that results never depend on the number of processes.
// Not a transport of its own (OpenMPI does that) and not the split of any particular work (eval/engine and
// train/trainer decide which process computes what). Without MPI (built with -DHINF_MPI=OFF, or a binary not
// started by mpirun) there is one process of rank 0 and every collective is a copy.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

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

/// [begin, end) of `count` items for rank r of `size`: consecutive blocks, sizes differing by at most one.
inline std::int64_t par_block_begin(std::int64_t count, int r, int size) { return count * r / size; }

}  // namespace hinf
