// MPI data parallelism (relit/parallel.hpp). Every collective is non-blocking underneath and waited for with a
// deadline, so that a rank that died or hung ends the job with an error instead of a hang.
#include "cl/kernel_sources.hpp"

#include <relit/error.hpp>
#include <relit/log.hpp>
#include <relit/parallel.hpp>
#include <relit/version.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#ifdef RELIT_WITH_MPI
#include <mpi.h>
#endif

namespace relit::parallel {

namespace {

// The launcher's view, for processes in which MPI is not (or cannot be) started.
int env_int(const char* name, int fallback) {
  const char* v = std::getenv(name);
  if (!v || !*v) return fallback;
  char* end = nullptr;
  const long x = std::strtol(v, &end, 10);
  return end && *end == '\0' && x >= 0 && x < (1L << 30) ? static_cast<int>(x) : fallback;
}

int launcher_size() {
  // Open MPI's mpirun, MPICH/Hydra and Slurm's srun (PMI), MVAPICH. A Slurm batch script without srun is one process.
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "MV2_COMM_WORLD_SIZE"})
    if (const int n = env_int(name, 0); n > 0) return n;
  return 0;
}

int launcher_local(bool size) {
  const char* names[] = {size ? "OMPI_COMM_WORLD_LOCAL_SIZE" : "OMPI_COMM_WORLD_LOCAL_RANK",
                         size ? "MPI_LOCALNRANKS" : "MPI_LOCALRANKID",
                         size ? "MV2_COMM_WORLD_LOCAL_SIZE" : "MV2_COMM_WORLD_LOCAL_RANK"};
  for (const char* name : names)
    if (const int n = env_int(name, -1); n >= 0) return n;
  return size ? 1 : 0;
}

struct State {
  bool started = false;   // MPI_Init by relit
  bool finished = false;  // MPI_Finalize or abort
  int rank = 0, size = 1, local_rank = 0, local_size = 1;
#ifdef RELIT_WITH_MPI
  MPI_Comm world = MPI_COMM_NULL;
#endif
};

State& state() {
  static State s;
  return s;
}

double clamp_timeout() {
  const char* v = std::getenv("RELIT_MPI_TIMEOUT");
  if (!v || !*v) return 600.0;
  char* end = nullptr;
  const double t = std::strtod(v, &end);
  if (!end || *end != '\0' || !std::isfinite(t) || t <= 0 || t > 1e7)
    throw InvalidArgument(std::string("RELIT_MPI_TIMEOUT='") + v +
                          "': give the seconds a rank waits for the others, a number in (0, 1e7]");
  return t;
}

#ifdef RELIT_WITH_MPI
// Waits for `request` until the deadline; then throws a ParallelError naming the operation (the caller's error
// boundary ends the job).
void wait(MPI_Request& request, const char* what) {
  const double limit = timeout();
  const auto start = std::chrono::steady_clock::now();
  int done = 0;
  for (unsigned spin = 0;; ++spin) {
    MPI_Test(&request, &done, MPI_STATUS_IGNORE);
    if (done) return;
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (waited > limit)
      throw ParallelError("no answer from the other ranks within " + std::to_string(int(limit)) + " s in " + what +
                          ": a rank died, hung or lost its device (RELIT_MPI_TIMEOUT sets the limit); ending the job");
    // Spin briefly (a reduction of a step answers within milliseconds), then poll politely.
    if (spin < 2000)
      std::this_thread::yield();
    else
      std::this_thread::sleep_for(std::chrono::microseconds(spin < 20000 ? 50 : 2000));
  }
}

void check(int code, const char* call, const char* what) {
  if (code == MPI_SUCCESS) return;
  char text[MPI_MAX_ERROR_STRING];
  int length = 0;
  MPI_Error_string(code, text, &length);
  throw ParallelError(std::string(call) + " failed in " + what + ": " + std::string(text, std::size_t(length)));
}

MPI_Comm comm() { return state().world; }
#endif

}  // namespace

bool built_with_mpi() {
#ifdef RELIT_WITH_MPI
  return true;
#else
  return false;
#endif
}

void init() {
  State& s = state();
  if (s.started || s.finished) return;
  const int launched = launcher_size();
#ifdef RELIT_WITH_MPI
  int already = 0;
  MPI_Initialized(&already);
  if (!already && launched == 0) return;  // a plain process: one rank, no MPI
  if (!already) {
    int provided = 0;
    if (MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
      throw ParallelError("MPI_Init failed (started by an MPI launcher, " + std::to_string(launched) + " ranks)");
  }
  MPI_Comm_dup(MPI_COMM_WORLD, &s.world);
  MPI_Comm_set_errhandler(s.world, MPI_ERRORS_RETURN);
  MPI_Comm_rank(s.world, &s.rank);
  MPI_Comm_size(s.world, &s.size);
  MPI_Comm node;
  MPI_Comm_split_type(s.world, MPI_COMM_TYPE_SHARED, s.rank, MPI_INFO_NULL, &node);
  MPI_Comm_rank(node, &s.local_rank);
  MPI_Comm_size(node, &s.local_size);
  MPI_Comm_free(&node);
  if (!already) s.started = true;
  timeout();  // a bad RELIT_MPI_TIMEOUT is an error now, not at the first collective
  if (s.size > 1) {
    // Ranks of different builds would compute different steps: the version and the kernels must agree.
    std::string kernels;
    for (const auto& file : detail::program_files()) kernels += detail::resolve_kernel_source(file);
    char hash[32];
    std::snprintf(hash, sizeof hash, "%016llx", static_cast<unsigned long long>(detail::fnv1a(kernels)));
    check_same("the relit build (version, kernel sources)", std::string("relit ") + version() + ", kernels " + hash);
  }
#else
  if (launched > 1)
    throw InvalidArgument("an MPI launcher started " + std::to_string(launched) +
                          " relit processes, but this relit was built without MPI: each would run the whole job on its "
                          "own. Install Open MPI (libopenmpi-dev) and rebuild, or run one process");
#endif
}

void finalize() {
  State& s = state();
#ifdef RELIT_WITH_MPI
  if (s.world != MPI_COMM_NULL) MPI_Comm_free(&s.world);
  if (s.started && !s.finished) MPI_Finalize();
#endif
  s.finished = true;
}

void abort_job(int code) noexcept {
#ifdef RELIT_WITH_MPI
  State& s = state();
  if (s.size > 1 && !s.finished) MPI_Abort(s.world != MPI_COMM_NULL ? s.world : MPI_COMM_WORLD, code ? code : 1);
#else
  (void)code;
#endif
}

int rank() { return state().rank; }
int size() { return state().size; }
int local_rank() {
  const State& s = state();
  return s.size > 1 ? s.local_rank : launcher_size() > 1 ? launcher_local(false) : 0;
}
int local_size() {
  const State& s = state();
  return s.size > 1 ? s.local_size : launcher_size() > 1 ? std::max(1, launcher_local(true)) : 1;
}
bool distributed() { return state().size > 1; }

std::string rank_prefix() {
  return distributed() ? "rank " + std::to_string(rank()) + " of " + std::to_string(size()) + ": " : std::string();
}

double timeout() {
  static const double t = clamp_timeout();
  return t;
}

Share share() { return {static_cast<std::uint32_t>(rank()), static_cast<std::uint32_t>(size())}; }

void sum([[maybe_unused]] float* values, std::size_t count, [[maybe_unused]] const char* what) {
  if (!distributed() || count == 0) return;
#ifdef RELIT_WITH_MPI
  const int n = size(), me = rank();
  // Rank c owns the chunk [offset[c], offset[c] + counts[c]): it receives that chunk from every rank, adds them
  // in rank order, and the sums are gathered back. MPI counts are ints: chunks stay below 2^31 values.
  if (count / std::size_t(n) >= (std::size_t(1) << 31))
    throw InvalidArgument(std::string(what) + ": too many values to reduce (" + std::to_string(count) + ")");
  std::vector<int> counts(n), offsets(n);
  for (int c = 0; c < n; ++c) {
    const std::size_t lo = count * std::size_t(c) / std::size_t(n), hi = count * std::size_t(c + 1) / std::size_t(n);
    offsets[c] = int(lo);
    counts[c] = int(hi - lo);
  }
  const int mine = counts[me];
  std::vector<float> gathered(std::size_t(mine) * std::size_t(n));
  std::vector<int> recv_counts(n, mine), recv_offsets(n);
  for (int r = 0; r < n; ++r) recv_offsets[r] = r * mine;
  MPI_Request request;
  check(MPI_Ialltoallv(values, counts.data(), offsets.data(), MPI_FLOAT, gathered.data(), recv_counts.data(),
                       recv_offsets.data(), MPI_FLOAT, comm(), &request),
        "MPI_Ialltoallv", what);
  wait(request, what);
  std::vector<float> reduced(static_cast<std::size_t>(mine));
  for (int i = 0; i < mine; ++i) {
    double acc = 0;
    for (int r = 0; r < n; ++r) acc += double(gathered[std::size_t(r) * mine + i]);  // rank order
    reduced[i] = float(acc);
  }
  check(MPI_Iallgatherv(reduced.data(), mine, MPI_FLOAT, values, counts.data(), offsets.data(), MPI_FLOAT, comm(),
                        &request),
        "MPI_Iallgatherv", what);
  wait(request, what);
#endif
}

std::vector<std::string> all_gather(const std::string& value, [[maybe_unused]] const char* what) {
  if (!distributed()) return {value};
  std::vector<std::string> out;
#ifdef RELIT_WITH_MPI
  const int n = size();
  int length = int(value.size());
  std::vector<int> lengths(n), offsets(n);
  MPI_Request request;
  check(MPI_Iallgather(&length, 1, MPI_INT, lengths.data(), 1, MPI_INT, comm(), &request), "MPI_Iallgather", what);
  wait(request, what);
  std::size_t total = 0;
  for (int r = 0; r < n; ++r) {
    offsets[r] = int(total);
    total += std::size_t(lengths[r]);
  }
  std::string all(total, '\0');
  check(MPI_Iallgatherv(value.data(), length, MPI_CHAR, all.data(), lengths.data(), offsets.data(), MPI_CHAR, comm(),
                        &request),
        "MPI_Iallgatherv", what);
  wait(request, what);
  for (int r = 0; r < n; ++r) out.push_back(all.substr(std::size_t(offsets[r]), std::size_t(lengths[r])));
#endif
  return out;
}

bool broadcast(bool value, [[maybe_unused]] const char* what) {
  if (!distributed()) return value;
  int v = value ? 1 : 0;
#ifdef RELIT_WITH_MPI
  MPI_Request request;
  check(MPI_Ibcast(&v, 1, MPI_INT, 0, comm(), &request), "MPI_Ibcast", what);
  wait(request, what);
#endif
  return v != 0;
}

void check_same(const std::string& what, const std::string& value) {
  if (!distributed()) return;
  const auto all = all_gather(value, what.c_str());
  for (std::size_t r = 1; r < all.size(); ++r)
    if (all[r] != all[0])
      throw InvalidArgument("the ranks disagree on " + what + ": rank 0 has '" + all[0] + "', rank " +
                            std::to_string(r) + " has '" + all[r] +
                            "'. Every rank must run the same relit build with the same arguments and data");
}

void share_out(std::size_t n, const std::function<std::size_t(std::size_t)>& item_size,
               const std::function<std::vector<float>(std::size_t)>& produce,
               const std::function<void(std::size_t, std::vector<float>&&)>& consume) {
  const auto checked = [&](std::size_t i, std::vector<float>&& item) {
    if (item.size() != item_size(i))
      throw ParallelError("item " + std::to_string(i) + " of a shared-out job has " + std::to_string(item.size()) +
                          " values, " + std::to_string(item_size(i)) + " expected: ranks of different builds or data?");
    consume(i, std::move(item));
  };
  if (!distributed()) {
    for (std::size_t i = 0; i < n; ++i) checked(i, produce(i));
    return;
  }
#ifdef RELIT_WITH_MPI
  const std::size_t ranks = std::size_t(size()), me = std::size_t(rank());
  const int tag = 7;
  if (me != 0) {
    for (std::size_t i = me; i < n; i += ranks) {
      std::vector<float> item = produce(i);
      long long length = static_cast<long long>(item.size());
      if (item.size() >= (std::size_t(1) << 31)) throw InvalidArgument("share_out: an item of over 2^31 values");
      MPI_Request request;
      check(MPI_Isend(&length, 1, MPI_LONG_LONG, 0, tag, comm(), &request), "MPI_Isend", "sending a view to rank 0");
      wait(request, "sending a view to rank 0");
      check(MPI_Isend(item.data(), int(length), MPI_FLOAT, 0, tag, comm(), &request), "MPI_Isend",
            "sending a view to rank 0");
      wait(request, "sending a view to rank 0");
    }
    return;
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t owner = i % ranks;
    if (owner == 0) {
      checked(i, produce(i));
      continue;
    }
    long long length = 0;
    MPI_Request request;
    const std::string what = "receiving view " + std::to_string(i) + " from rank " + std::to_string(owner);
    check(MPI_Irecv(&length, 1, MPI_LONG_LONG, int(owner), tag, comm(), &request), "MPI_Irecv", what.c_str());
    wait(request, what.c_str());
    std::vector<float> item(static_cast<std::size_t>(length));
    check(MPI_Irecv(item.data(), int(length), MPI_FLOAT, int(owner), tag, comm(), &request), "MPI_Irecv", what.c_str());
    wait(request, what.c_str());
    checked(i, std::move(item));
  }
#endif
}

}  // namespace relit::parallel
