// The ThreadSanitizer run's canary (scripts/test-sanitizers --thread): a deliberate data race
// between two tasks of a tbb::parallel_for, which TSan must report. If it does not, something
// hides races (a suppression that matches the harness's frames, a broken instrumentation), and
// the run fails instead of passing by seeing nothing.
//
// Before it, the pattern every filter uses (workers write disjoint parts of a buffer, the caller
// reads it after the join) must not be reported: with Debian's uninstrumented libtbb it is, as a
// false race, on every join; the script then fails on the canary's extra reports.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <thread>
#include <vector>

int main() {
  tbb::task_arena arena(2);
  std::vector<float> v(1 << 14, 0.0f);
  double sum = 0;
  arena.execute([&] { tbb::parallel_for(0, int(v.size()), [&](int i) { v[std::size_t(i)] = float(i); }); });
  for (float x : v) sum += x;  // after the join: no race
  // Two tasks that wait (at most a second) until both have started, so that two threads run
  // them, then both write `racy` without synchronisation.
  std::atomic<int> started{0};
  int racy = 0;
  arena.execute([&] {
    tbb::parallel_for(tbb::blocked_range<int>(0, 2, 1), [&](const tbb::blocked_range<int>&) {
      started.fetch_add(1);
      const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(1);
      while (started.load() < 2 && std::chrono::steady_clock::now() < until) std::this_thread::yield();
      racy += 1;  // the deliberate race
    }, tbb::simple_partitioner());
  });
  std::printf("sum %.0f racy %d threads %d\n", sum, racy, started.load());
  return 0;
}
