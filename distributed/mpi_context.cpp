#include "distributed/mpi_context.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <mutex>

#include <fmt/format.h>

#include "core/errors.h"

#ifdef DNB_WITH_MPI
#include <mpi.h>
#endif

namespace dnb::mpi {

namespace {
std::mutex g_mutex;
int g_sessions = 0;
bool g_active = false;
int g_rank = 0;
int g_size = 1;

// Set by OpenMPI's mpirun, by PMI/PMIx launchers (MPICH, Slurm's srun). Without one of them
// MPI_Init would start a "singleton" job, which is slow and useless for one process.
bool launched_by_mpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"})
    if (std::getenv(v)) return true;
  return false;
}

#ifdef DNB_WITH_MPI
void check(int rc, const char* what) {
  if (rc == MPI_SUCCESS) return;
  char msg[MPI_MAX_ERROR_STRING];
  int len = 0;
  MPI_Error_string(rc, msg, &len);
  throw WorkError(fmt::format("MPI {} failed on rank {}: {}", what, g_rank, std::string(msg, std::size_t(len))));
}
// MPI counts are int: send large buffers in pieces of at most this many elements.
constexpr std::size_t kChunk = std::size_t(1) << 27;
#endif
}  // namespace

Session::Session() {
  std::lock_guard lock(g_mutex);
  if (g_sessions++ > 0) return;
#ifdef DNB_WITH_MPI
  int initialised = 0;
  MPI_Initialized(&initialised);
  if (!initialised && launched_by_mpi()) {
    int provided = 0;
    // Funnelled: only the main thread calls MPI; the tracer's worker threads never do.
    check(MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided), "init");
    MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &g_size);
    // Errors come back as codes (turned into exceptions by check) instead of aborting silently.
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    g_active = true;
  }
#else
  (void)launched_by_mpi;
#endif
}

Session::~Session() {
  std::lock_guard lock(g_mutex);
  if (--g_sessions > 0) return;
#ifdef DNB_WITH_MPI
  if (g_active) MPI_Finalize();
#endif
  g_active = false;
  g_rank = 0;
  g_size = 1;
}

bool built_with_mpi() {
#ifdef DNB_WITH_MPI
  return true;
#else
  return false;
#endif
}

bool active() { return g_active; }
int rank() { return g_rank; }
int size() { return g_size; }

std::vector<std::size_t> my_share(std::size_t n) {
  std::vector<std::size_t> mine;
  for (std::size_t i = std::size_t(rank()); i < n; i += std::size_t(size())) mine.push_back(i);
  return mine;
}

void barrier() {
#ifdef DNB_WITH_MPI
  if (g_active) check(MPI_Barrier(MPI_COMM_WORLD), "barrier");
#endif
}

std::int64_t broadcast_int(std::int64_t value) {
#ifdef DNB_WITH_MPI
  if (g_active) check(MPI_Bcast(&value, 1, MPI_INT64_T, 0, MPI_COMM_WORLD), "broadcast");
#endif
  return value;
}

std::string broadcast_string(const std::string& value) {
#ifdef DNB_WITH_MPI
  if (g_active) {
    std::int64_t n = broadcast_int(std::int64_t(value.size()));
    std::string s = is_root() ? value : std::string(std::size_t(n), '\0');
    for (std::size_t off = 0; off < s.size(); off += kChunk)
      check(MPI_Bcast(s.data() + off, int(std::min(kChunk, s.size() - off)), MPI_CHAR, 0, MPI_COMM_WORLD),
            "broadcast");
    return s;
  }
#endif
  return value;
}

std::vector<std::string> gather_strings(const std::string& mine) {
#ifdef DNB_WITH_MPI
  if (g_active) {
    // Point-to-point instead of MPI_Gatherv: strings may exceed an int's worth of bytes in all.
    constexpr int kTag = 7001;
    if (!is_root()) {
      std::int64_t n = std::int64_t(mine.size());
      check(MPI_Send(&n, 1, MPI_INT64_T, 0, kTag, MPI_COMM_WORLD), "send");
      for (std::size_t off = 0; off < mine.size(); off += kChunk)
        check(MPI_Send(mine.data() + off, int(std::min(kChunk, mine.size() - off)), MPI_CHAR, 0, kTag,
                       MPI_COMM_WORLD),
              "send");
      return {};
    }
    std::vector<std::string> all(static_cast<std::size_t>(g_size));
    all[0] = mine;
    for (int r = 1; r < g_size; ++r) {
      std::int64_t n = 0;
      check(MPI_Recv(&n, 1, MPI_INT64_T, r, kTag, MPI_COMM_WORLD, MPI_STATUS_IGNORE), "receive");
      std::string& s = all[std::size_t(r)];
      s.resize(std::size_t(n));
      for (std::size_t off = 0; off < s.size(); off += kChunk)
        check(MPI_Recv(s.data() + off, int(std::min(kChunk, s.size() - off)), MPI_CHAR, r, kTag, MPI_COMM_WORLD,
                       MPI_STATUS_IGNORE),
              "receive");
    }
    return all;
  }
#endif
  return {mine};
}

void send_doubles(int dest, int tag, const double* data, std::size_t count) {
#ifdef DNB_WITH_MPI
  if (g_active) {
    for (std::size_t off = 0; off < count; off += kChunk)
      check(MPI_Send(data + off, int(std::min(kChunk, count - off)), MPI_DOUBLE, dest, tag, MPI_COMM_WORLD), "send");
    return;
  }
#endif
  (void)dest, (void)tag, (void)data, (void)count;
  throw WorkError("mpi::send_doubles called without an MPI job");
}

void recv_doubles(int source, int tag, double* data, std::size_t count) {
#ifdef DNB_WITH_MPI
  if (g_active) {
    for (std::size_t off = 0; off < count; off += kChunk)
      check(MPI_Recv(data + off, int(std::min(kChunk, count - off)), MPI_DOUBLE, source, tag, MPI_COMM_WORLD,
                     MPI_STATUS_IGNORE),
            "receive");
    return;
  }
#endif
  (void)source, (void)tag, (void)data, (void)count;
  throw WorkError("mpi::recv_doubles called without an MPI job");
}

void abort_job(int exit_code) {
#ifdef DNB_WITH_MPI
  if (g_active) MPI_Abort(MPI_COMM_WORLD, exit_code);
#endif
  std::exit(exit_code);
}

}  // namespace dnb::mpi
