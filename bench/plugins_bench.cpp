// The harness's own cost per frame for a "worker" plug-in at 1024x768 (issue: plug-ins): writing
// IN.exr with the layers a guided filter reads, the JSON round trip, and reading OUT.exr, against
// `proposed`'s filter time on the same frame, alternated in the same process.
//
//   build/bench/denoisebench_bench --benchmark_filter='plugins/' --benchmark_out=plugins.json
//
// The plug-in (bench/plugins/copy_worker) answers with a copy of a prepared R, G, B image, so its
// own work is a file copy: the case's time is the harness and protocol overhead. Counters: overhead_ratio =
// median plug-in frame (write_input + round trip + read_output) / median `proposed` execute();
// write_ms, roundtrip_ms, read_ms and proposed_ms are the medians of the parts.
#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <vector>

#include <benchmark/benchmark.h>

#include "bench/bench_util.h"
#include "core/exr_io.h"
#include "core/stats.h"
#include "denoisers/method.h"
#include "methods/inputs.h"
#include "methods/plugins.h"

namespace dnb {
namespace {

double phase(const MethodStats& s, const std::string& name) {
  for (const auto& [n, sec] : s.phases)
    if (n == name) return sec;
  return 0;
}

void worker_overhead(benchmark::State& state) {
  register_plugins({DNB_BENCH_PLUGINS_DIR});
  const MethodInput in = frame_input(bench::rendered_frame("cornell-box", 1024, 768, 16));
  // The plug-in's answer: an R, G, B image of the frame's size, as a real plug-in writes.
  const std::string answer = (std::filesystem::temp_directory_path() / "denoisebench-bench-output.exr").string();
  // Uncompressed, as python/denoisebench_plugin.py writes it.
  write_frame(*in.frame, answer, {.compress = false, .edges = false, .layers = {layer::kColor}, .durable = false});
  ::setenv("BENCH_OUTPUT_EXR", answer.c_str(), 1);
  auto plugin = MethodRegistry::global().create("bench_copy_worker");
  auto proposed = MethodRegistry::global().create("proposed");
  run_method(*plugin, in);    // warm-up: starts the worker
  run_method(*proposed, in);  // warm-up: first-touch allocations, thread pool
  std::vector<double> frame, write, trip, read, filter;
  for (auto _ : state) {
    const MethodResult p = run_method(*plugin, in);
    const double w = phase(p.stats, "write_input"), r = phase(p.stats, "read_output");
    write.push_back(w);
    read.push_back(r);
    trip.push_back(p.stats.total_seconds);
    frame.push_back(w + p.stats.total_seconds + r);
    state.SetIterationTime(frame.back());
    state.PauseTiming();
    filter.push_back(run_method(*proposed, in).stats.total_seconds);
    state.ResumeTiming();
  }
  shutdown_plugin_workers();
  state.counters["overhead_ratio"] = stats::median(frame) / stats::median(filter);
  state.counters["write_ms"] = 1e3 * stats::median(write);
  state.counters["roundtrip_ms"] = 1e3 * stats::median(trip);
  state.counters["read_ms"] = 1e3 * stats::median(read);
  state.counters["proposed_ms"] = 1e3 * stats::median(filter);
}
BENCHMARK(worker_overhead)->Name("plugins/worker_overhead/1024x768")->Unit(benchmark::kMillisecond)->UseManualTime()
    ->Iterations(15);

}  // namespace
}  // namespace dnb
