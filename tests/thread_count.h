// Running code on an explicit number of threads, and checking that it really had them.
//
// tbb::global_control(max_allowed_parallelism, 1) against "the default" compares one thread with
// one thread on a one-core runner. A tbb::task_arena(n) alone does not help: TBB limits its
// workers to hardware concurrency - 1 (measured on oneTBB 2021.8: an arena of 4 got 2 threads on 2
// cores, 1 on one core). Raising max_allowed_parallelism to n as well lifts that limit (4 threads
// even on one core), so run_on_threads sets both.
#pragma once

#include <chrono>
#include <mutex>
#include <set>
#include <thread>

#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

namespace dnb::test {

// Runs f() in an arena of `threads` slots and returns how many distinct threads a probe saw
// working in that arena just before f ran (each probe task waits, up to 2 s, until every slot has
// a thread, so the workers are in the arena when f starts). A result of 1 with threads > 1 means
// the comparison would be one thread against one: callers assert it is larger.
template <class F>
int run_on_threads(int threads, F&& f) {
  tbb::global_control allow(tbb::global_control::max_allowed_parallelism, threads);
  tbb::task_arena arena(threads);
  std::mutex m;
  std::set<std::thread::id> ids;
  arena.execute([&] {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    tbb::parallel_for(tbb::blocked_range<int>(0, threads * 8, 1), [&](const tbb::blocked_range<int>&) {
      {
        std::lock_guard lock(m);
        ids.insert(std::this_thread::get_id());
      }
      for (;;) {
        {
          std::lock_guard lock(m);
          if (int(ids.size()) >= threads) break;
        }
        if (std::chrono::steady_clock::now() > deadline) break;
        std::this_thread::yield();
      }
    });
    f();
  });
  return int(ids.size());
}

}  // namespace dnb::test
