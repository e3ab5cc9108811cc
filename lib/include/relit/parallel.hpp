// Data parallelism over MPI ranks: one process (rank) per OpenCL device, on one machine or several
// (docs/scaling.md).
//
//   mpirun -np 4 relit train data/cloud --out runs/cloud     # the global batch split over 4 ranks
//   mpirun -np 4 relit generate --scene cloud --out data/c   # views shared out, files as from one process
//
// relit starts MPI only when an MPI launcher started the process (mpirun/mpiexec of Open MPI or MPICH, srun with
// PMI-2); otherwise, or when relit was built without MPI, there is one rank, every collective below returns at once
// and relit behaves exactly as a single process. Every collective waits at most timeout() seconds for the other ranks
// (RELIT_MPI_TIMEOUT), then ends the whole job with an error naming the rank and the operation: a rank that dies
// or hangs never leaves the others waiting for ever.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace relit::parallel {

/// True when librelit was built with MPI (RELIT_WITH_MPI).
bool built_with_mpi();

/// Starts MPI when an MPI launcher started this process and relit was built with MPI; otherwise does nothing.
/// Idempotent; the relit program and the Python module call it. Throws InvalidArgument when a launcher started
/// several processes but relit was built without MPI (each would run the whole job on its own).
void init();
/// Ends MPI after a run in which every rank succeeded (all ranks call it). No-op without MPI.
void finalize();
/// Ends the whole job now with exit code `code` (MPI_Abort) when several ranks run; returns otherwise.
void abort_job(int code) noexcept;

/// This process's rank and the number of ranks (0 and 1 without MPI).
int rank();
int size();
/// The rank among the ranks of this machine and their number (from MPI, else the launcher's environment).
int local_rank();
int local_size();
/// size() > 1.
bool distributed();
/// "rank 1 of 4: " when distributed, "" otherwise: the prefix of every error and warning a rank prints.
std::string rank_prefix();

/// Seconds a collective waits for the other ranks before it ends the job: RELIT_MPI_TIMEOUT, default 600.
double timeout();

/// Sums `n` values over the ranks in place: every rank receives the same sums, added in rank order (0, 1, ...)
/// in double precision, so the result is reproducible for a given number of ranks. `what` names the operation
/// in errors. A reduce-scatter + all-gather: each rank sends and receives about 2 (N-1)/N of the data.
void sum(float* values, std::size_t n, const char* what);
/// Rank 0's value, on every rank.
bool broadcast(bool value, const char* what);
/// Every rank's string in rank order, on every rank.
std::vector<std::string> all_gather(const std::string& value, const char* what);
/// Throws InvalidArgument (on every rank) when the ranks disagree on `value`, naming `what` and the first rank
/// that differs from rank 0 (a mismatched build, dataset or config).
void check_same(const std::string& what, const std::string& value);

/// Items [0, n) shared out round-robin: rank r produces items r, r + N, r + 2N, ...; rank 0 then consumes every
/// item in order 0, 1, ..., n - 1, its own and those the other ranks send it. `consume` runs on rank 0 only,
/// so output files are written by one process in one order, byte-identical to a 1-rank run. Items are float
/// vectors (an image) of item_size(i) values, checked on arrival (ParallelError: ranks of different builds or data);
/// they cross the network once.
void share_out(std::size_t n, const std::function<std::size_t(std::size_t)>& item_size,
               const std::function<std::vector<float>(std::size_t)>& produce,
               const std::function<void(std::size_t, std::vector<float>&&)>& consume);

/// The part of a batch of consecutive items that one rank takes: the items `first`, `first + stride`, ... of the
/// global batch (rank r of N: first r, stride N). Strided, so that any prefix of the global batch (the rays
/// the visibility net trains on) is shared evenly too.
struct Share {
  std::uint32_t first = 0;
  std::uint32_t stride = 1;
  /// How many of the global items [0, n) are this rank's.
  std::uint32_t count(std::uint32_t n) const { return n > first ? (n - first + stride - 1) / stride : 0; }
  bool whole() const { return first == 0 && stride == 1; }
};
/// This rank's share: {rank(), size()}.
Share share();

}  // namespace relit::parallel
