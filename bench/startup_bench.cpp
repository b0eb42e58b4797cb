// What starting `denoisebench` costs before it does any work: `denoisebench --version`, spawned
// and waited for, against the floor of spawning a program that loads nothing (/bin/true), the two
// alternated in one case so that a load on the machine weighs on both alike. Every test of the
// suite and every command a user runs pays it. Most of it is the dynamic loader resolving the
// relocations of the 280-odd libraries OpenImageIO and OpenCV load (dnb_load_order in
// CMakeLists.txt; docs/speed.md, "Process start-up").
//
//   build/bench/denoisebench_bench --benchmark_filter='startup/'
//
// Reported: the program's median start in ms (manual time), the floor's median (floor_ms) and
// their difference (start_ms_above_floor), medians of 21 alternated pairs after 3 of warm-up.
#include <benchmark/benchmark.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench/bench_util.h"

extern char** environ;

namespace dnb {
namespace {

// Seconds to spawn `argv` (stdout and stderr to /dev/null) and wait for it; throws unless it exits 0.
double spawn_seconds(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
  const double t0 = bench::wall_seconds();
  pid_t pid = 0;
  const int err = posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (err != 0) throw std::runtime_error("cannot start " + args[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) throw std::runtime_error("cannot wait for " + args[0]);
  const double t = bench::wall_seconds() - t0;
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) throw std::runtime_error(args[0] + " failed");
  return t;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

void BM_ProcessStart(benchmark::State& state) {
  constexpr int kWarmup = 3, kPairs = 21;
  const std::vector<std::string> program{DNB_BENCH_PROGRAM, "--version"}, floor{"/bin/true"};
  for (auto _ : state) {
    std::vector<double> p, f;
    try {
      for (int i = 0; i < kWarmup; ++i) spawn_seconds(program), spawn_seconds(floor);
      for (int i = 0; i < kPairs; ++i) p.push_back(spawn_seconds(program)), f.push_back(spawn_seconds(floor));
    } catch (const std::exception& e) {
      state.SkipWithError(e.what());
      return;
    }
    state.SetIterationTime(median(p));
    state.counters["floor_ms"] = 1e3 * median(f);
    state.counters["start_ms_above_floor"] = 1e3 * (median(p) - median(f));
  }
}
BENCHMARK(BM_ProcessStart)->Name("startup/denoisebench_version")->Iterations(1)->UseManualTime()->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace dnb
