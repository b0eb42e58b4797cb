// Scoring at the paper's 1024x768 (metrics/metrics.h): what every cell of a run pays after its
// method has run, metric by metric. The image is the built-in cornell-box at 16 spp, the
// reference the same scene at 64 spp (both from the render cache, prepared outside the timed
// loop; a real reference has more samples, which changes none of these costs).
//
//   metrics/<metric>/1024x768            one metric against a reference it has scored against
//                                        before: a run's case, where every cell of a scene is
//                                        scored against one reference and FLIP keeps the
//                                        reference's prepared images (flip.cpp, ReferenceMemo)
//   metrics/<metric>_new_reference/...   flip and hdrflip against a reference not seen before
//                                        (the first cell of a scene): two references alternate
//   metrics/all/1024x768                 every metric, as a run's cell scores them
//
//   build/bench/denoisebench_bench --benchmark_filter='metrics/'
#include <benchmark/benchmark.h>

#include "bench/bench_util.h"
#include "metrics/metrics.h"

namespace dnb {
namespace {

const Image& image() { return bench::rendered_frame("cornell-box", 1024, 768, 16).layer(layer::kColor); }
const AovFrame& reference_frame() { return bench::rendered_frame("cornell-box", 1024, 768, 64); }
const Image& reference() { return reference_frame().layer(layer::kColor); }
// Its per-pixel variance of the mean, as a run's reference has it (mse_converged's mask).
const Image* variance() { return &reference_frame().layer(layer::kVariance); }

// The reference with one pixel changed: another reference to FLIP's memo.
const Image& other_reference() {
  static const Image other = [] {
    Image r = reference();
    r.data()[0] += 1.0f;
    return r;
  }();
  return other;
}

void metric_case(benchmark::State& state, const metrics::MetricInfo& m, bool new_reference) {
  m.compute(image(), reference(), variance());  // warm-up: thread pool, first-touch, the memo
  bool flip_side = false;
  for (auto _ : state) {
    const Image& ref = new_reference && (flip_side = !flip_side) ? other_reference() : reference();
    benchmark::DoNotOptimize(m.compute(image(), ref, variance()).value);
  }
}

void all_case(benchmark::State& state) {
  const auto run = [] {
    double sum = 0;
    for (const auto& m : metrics::all_metrics()) sum += m.compute(image(), reference(), variance()).value;
    return sum;
  };
  run();  // warm-up
  for (auto _ : state) benchmark::DoNotOptimize(run());
}

const bool registered = [] {
  for (const auto& m : metrics::all_metrics()) {
    for (bool fresh : {false, true}) {
      if (fresh && !m.memoises_reference) continue;
      const std::string name = "metrics/" + m.name + (fresh ? "_new_reference" : "") + "/1024x768";
      benchmark::RegisterBenchmark(name.c_str(), [&m, fresh](benchmark::State& s) { metric_case(s, m, fresh); })
          ->Unit(benchmark::kMillisecond)->UseRealTime()->Repetitions(5)->ReportAggregatesOnly(true);
    }
  }
  benchmark::RegisterBenchmark("metrics/all/1024x768", all_case)
      ->Unit(benchmark::kMillisecond)->UseRealTime()->Repetitions(5)->ReportAggregatesOnly(true);
  return true;
}();

}  // namespace
}  // namespace dnb
