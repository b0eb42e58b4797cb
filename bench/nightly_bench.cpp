// The cases the nightly performance gate reads (.ci/nightly, experiment/nightly.h): every
// method on a rendered frame, timed as a multiple of a fixed reference workload run in the
// same process, interleaved with it, so that the machine's speed and its momentary load
// cancel out of the ratio: the gate compares ratios, not absolute times.
//
//   scripts/nightly_bench bench.json      # what the nightly runs: each case in its own process,
//                                         # --benchmark_repetitions=5 --benchmark_min_time=0.2
//   build/bench/denoisebench_bench --benchmark_filter='^nightly/guided/' --benchmark_repetitions=5
//
// Cases are named nightly/<method>/<W>x<H>/threads:<1|all>, and nightly/proposed:opencl/...
// for the OpenCL path of `proposed` (PoCL's CPU device here, one PoCL thread for threads:1). The frame is the built-in cornell-box at 16 spp (renderer-type methods
// render that scene with a 16-spp budget, at half the width and height: they take seconds
// where filters take milliseconds); --dnb_nightly_size=WxH (main.cpp) picks another size, for
// CI's short run. Preparing the frame, creating the method and one warm-up run of
// the method and of the workload happen outside the timed loop.
//
// Each iteration times the reference workload (repeated so that it lasts about as long as the
// method) and the method, in alternating order; the iteration's ratio is method time / workload
// time. A repetition reports the median ratio of its iterations as the counter `ratio`, and
// the method and workload times (ms) beside it; the gate takes the median over repetitions.
// threads:1 cases limit TBB and OpenCV to one thread and measure process CPU time (which
// another job on the machine disturbs far less than wall time); threads:all cases measure
// wall time with every core, so they also see a loss of parallelism.
#include <benchmark/benchmark.h>
#include <valgrind/callgrind.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <cstdlib>
#include <mutex>

#include "bench/bench_util.h"
#include "core/stats.h"
#include "denoisers/method.h"
#include "methods/inputs.h"

namespace dnb::bench {

namespace {

constexpr const char* kNightlyScene = "cornell-box";
constexpr int kNightlySpp = 16;

struct NightlyCase {
  std::string method;                         // registry name
  std::map<std::string, std::string> params;  // e.g. device=opencl
  int threads = 0;                            // 1, or 0 for all cores
  int width = 256, height = 192;
  bool count_instructions = false;            // main.cpp's --dnb_count_instructions
};

// How many runs of the workload last about as long as one run of the method, found at the
// case's first call (the warm-up) and kept for the rest of the process, so that every
// repetition of a case times the same amount of reference work.
int& workload_units(const std::string& case_name) {
  static std::map<std::string, int> units;
  return units[case_name];
}

void run_nightly_case(benchmark::State& state, const std::string& case_name, const NightlyCase& c) {
  ThreadLimit limit(c.threads);
  const auto& registry = MethodRegistry::global();
  const MethodInfo& info = registry.info(c.method);
  const MethodInput in = info.kind == MethodKind::Renderer
                             ? scene_input(*scene(kNightlyScene), kNightlySpp, c.width, c.height)
                             : frame_input(rendered_frame(kNightlyScene, c.width, c.height, kNightlySpp));
  if (c.params.count("device") && c.params.at("device") == "opencl") {
    // PoCL reads its thread count once, when OpenCL starts: a process times OpenCL cases of one
    // thread setting only (scripts/nightly_bench gives every case a process of its own).
    static int opencl_threads = -1;
    if (opencl_threads == -1) {
      opencl_threads = c.threads;
      if (c.threads == 1) setenv("POCL_MAX_PTHREAD_COUNT", "1", 1);
    } else if (opencl_threads != c.threads) {
      state.SkipWithError("OpenCL already started with another thread count: run this case in a process of its own");
      return;
    }
  }
  std::unique_ptr<Method> method;
  try {
    method = registry.create(c.method, c.params);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  auto run = [&] { benchmark::DoNotOptimize(run_method(*method, in).image.data()); };
  if (c.count_instructions) {  // no reference workload: nothing is timed
    // Warm-up outside the count (first-use initialisation in OpenCV, TBB, the allocator), then
    // one run with callgrind collecting (the macros do nothing outside valgrind).
    run();
    CALLGRIND_TOGGLE_COLLECT;
    run();
    CALLGRIND_TOGGLE_COLLECT;
    for (auto _ : state) state.SetIterationTime(1.0);
    state.counters["counted_runs"] = 1;
    state.counters["under_valgrind"] = RUNNING_ON_VALGRIND ? 1 : 0;
    return;
  }

  const ReferenceWorkload workload(c.threads);
  auto clock = c.threads == 1 ? process_cpu_seconds : wall_seconds;
  auto time_of = [&](auto&& f) {
    const double t0 = clock();
    f();
    return clock() - t0;
  };

  int& units = workload_units(case_name);
  if (units == 0) {  // first call: warm-up of both, and the workload's repeat count
    run();
    workload.run();
    const double tm = time_of(run);
    double tw = time_of([&] { workload.run(); });
    tw = std::min(tw, time_of([&] { workload.run(); }));
    units = int(std::clamp(std::round(tm / std::max(tw, 1e-6)), 1.0, 10000.0));
  }

  std::vector<double> ratios, method_s, workload_s;
  bool workload_first = true;
  for (auto _ : state) {
    double tw = 0, tm = 0;
    auto work = [&] { tw = time_of([&] { for (int i = 0; i < units; ++i) workload.run(); }) / units; };
    if (workload_first) {
      work();
      tm = time_of(run);
    } else {
      tm = time_of(run);
      work();
    }
    workload_first = !workload_first;
    state.SetIterationTime(tm);
    ratios.push_back(tm / std::max(tw, 1e-9));
    method_s.push_back(tm);
    workload_s.push_back(tw);
  }
  state.counters["ratio"] = stats::median(ratios);
  state.counters["method_ms"] = 1e3 * stats::median(method_s);
  state.counters["reference_ms"] = 1e3 * stats::median(workload_s);
  state.counters["reference_units"] = units;
  state.SetLabel(std::string(kNightlyScene) + " " + std::to_string(c.width) + "x" + std::to_string(c.height) + " " +
                 std::to_string(kNightlySpp) + "spp");
}

}  // namespace

void register_nightly_cases(int width, int height, bool count_instructions) {
  const auto& registry = MethodRegistry::global();
  std::vector<std::pair<std::string, NightlyCase>> cases;
  auto size = [](int w, int h) { return std::to_string(w) + "x" + std::to_string(h); };
  for (const MethodInfo* m : registry.all()) {
    // A renderer takes seconds where a filter takes milliseconds: half the size each way.
    const bool renderer = m->kind == MethodKind::Renderer;
    const int w = renderer ? std::max(8, width / 2) : width, h = renderer ? std::max(8, height / 2) : height;
    for (int threads : {1, 0})
      cases.push_back({"nightly/" + m->name + "/" + size(w, h) + "/threads:" + (threads ? "1" : "all"),
                       NightlyCase{m->name, {}, threads, w, h, count_instructions}});
  }
  // The OpenCL path of `proposed`: PoCL's CPU device runs its own threads, limited to one with
  // POCL_MAX_PTHREAD_COUNT for threads:1 (read when OpenCL starts in the process).
  const auto& params = registry.info("proposed").params;
  if (std::any_of(params.begin(), params.end(), [](const ParamSpec& p) { return p.name == "device"; }))
    for (int threads : {1, 0})
      cases.push_back({"nightly/proposed:opencl/" + size(width, height) + "/threads:" + (threads ? "1" : "all"),
                       NightlyCase{"proposed", {{"device", "opencl"}}, threads, width, height, count_instructions}});
  for (const auto& [name, c] : cases)
    benchmark::RegisterBenchmark(name.c_str(), [name = name, c = c](benchmark::State& s) { run_nightly_case(s, name, c); })
        ->Unit(benchmark::kMillisecond)
        ->UseManualTime();
}

}  // namespace dnb::bench
