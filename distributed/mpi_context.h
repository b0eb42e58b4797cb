// Distribution over MPI processes (OpenMPI), optional at build time (DNB_WITH_MPI) and at run
// time: a program not started by mpirun/srun, or built with -DDNB_WITH_MPI=OFF, is one process
// of rank 0 in a world of size 1, and every call below still works (collectives become copies).
//
// How `denoisebench` uses it:
//   - `reference`: sample blocks are dealt to ranks; rank 0 receives them and adds them in block
//     order (bit-identical to one process), writes checkpoints and output, reports progress.
//   - `run` (experiment runner): split the experiment matrix with `my_share`, run this rank's
//     items, serialise each result (e.g. a JSON string), `gather_strings` on rank 0, which
//     alone writes results files. Every rank must call the collectives in the same order.
//
//   int main-ish() {
//     dnb::mpi::Session mpi;                       // MPI_Init when launched by mpirun
//     for (std::size_t i : dnb::mpi::my_share(items.size())) mine.push_back(run(items[i]));
//     auto all = dnb::mpi::gather_strings(serialise(mine));   // rank 0: size() strings
//     if (dnb::mpi::is_root()) write_results(all);
//   }
//
// Errors: an exception on one rank while others wait in a collective would hang the job; catch
// it at the top of the command and call `abort_job` when size() > 1 (see tracer/jobs.cpp, reference_file).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace dnb::mpi {

// Initialises MPI (MPI_Init_thread, funnelled) when the build has MPI and the process was
// launched by an MPI launcher; finalises when the last Session ends. Nested Sessions are fine.
// MPI cannot be restarted once finalised: create one Session for the life of a command.
class Session {
 public:
  Session();
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;
};

bool built_with_mpi();  // DNB_WITH_MPI
bool active();          // MPI is initialised (launched by mpirun, inside a Session)
int rank();             // 0 when not active
int size();             // 1 when not active
inline bool is_root() { return rank() == 0; }

// Indices of [0, n) this rank works on: i with i % size() == rank(), ascending. Round-robin so
// that neighbouring (often similar-cost) items go to different ranks.
std::vector<std::size_t> my_share(std::size_t n);

void barrier();
// Rank 0's value on every rank.
std::string broadcast_string(const std::string& value);
std::int64_t broadcast_int(std::int64_t value);
// Gathers one string per rank on rank 0, in rank order; other ranks get an empty vector.
std::vector<std::string> gather_strings(const std::string& mine);
// Point-to-point transfer of doubles (exact, bit for bit); `tag` tells messages apart.
void send_doubles(int dest, int tag, const double* data, std::size_t count);
void recv_doubles(int source, int tag, double* data, std::size_t count);
// Ends every process of the job with this exit status (MPI_Abort); plain exit when not active.
[[noreturn]] void abort_job(int exit_code);

}  // namespace dnb::mpi
