// Timing of every registered method at its defaults, at 256x192 and 1024x768 (the paper's
// size). Filters run on a rendered 16-spp frame of the built-in cornell-box (edges, sub-pixels,
// reflection levels: what the methods see in an experiment), taken from the render cache and
// prepared once, outside the timed loop; renderer-type methods (the irradiance cache) render
// that scene with a 16-spp budget.
//
//   cmake -S . -B build -DDNB_BUILD_BENCH=ON && cmake --build build -j2 --target denoisebench_bench
//   build/bench/denoisebench_bench --benchmark_filter='methods/'
//
// Cases are named methods/<method>/<W>x<H>; each reports wall-clock ms per image (median of the
// repetitions) after one untimed warm-up run. Renderers, which take seconds (256x192) to a
// minute (1024x768) a run, get no warm-up and one iteration per repetition (3 at 256x192, 1 at
// 1024x768); so do the slowest filters at 1024x768 (slow_filter below; their warm-up is kept). A method added to the registry is timed without a new line here.
#include <benchmark/benchmark.h>

#include "bench/bench_util.h"
#include "denoisers/method.h"
#include "methods/inputs.h"

namespace dnb {
namespace {

constexpr const char* kScene = "cornell-box";
constexpr int kSpp = 16;

void run_case(benchmark::State& state, const std::string& name, int w, int h) {
  const auto& registry = MethodRegistry::global();
  const bool renderer = registry.info(name).kind == MethodKind::Renderer;
  const MethodInput in = renderer ? scene_input(*bench::scene(kScene), kSpp, w, h)
                                  : frame_input(bench::rendered_frame(kScene, w, h, kSpp));
  auto method = registry.create(name);
  if (!renderer) run_method(*method, in);  // warm-up: first-touch allocations, thread pool start
  for (auto _ : state) {
    MethodResult r = run_method(*method, in);
    benchmark::DoNotOptimize(r.image.data());
  }
  state.counters["Mpixel/s"] =
      benchmark::Counter(double(w) * h * state.iterations() / 1e6, benchmark::Counter::kIsRate);
}

// Filters that take about a minute a run at 1024x768 (nfor: 62 s on 2 cores) are timed like the
// renderers there, or this bench alone would take several minutes per such method.
bool slow_filter(const std::string& name) { return name == "nfor"; }

const bool registered = [] {
  for (const MethodInfo* m : MethodRegistry::global().all()) {
    for (auto [w, h] : {std::pair{256, 192}, std::pair{1024, 768}}) {
      const std::string name = m->name;
      auto* b = benchmark::RegisterBenchmark(
          ("methods/" + name + "/" + std::to_string(w) + "x" + std::to_string(h)).c_str(),
          [name, w = w, h = h](benchmark::State& s) { run_case(s, name, w, h); });
      b->Unit(benchmark::kMillisecond)->UseRealTime()->ReportAggregatesOnly(true);
      if (m->kind == MethodKind::Renderer || (slow_filter(name) && w > 256))
        b->Iterations(1)->Repetitions(w > 256 ? 1 : 3);
      else
        b->MinTime(0.5)->Repetitions(5);
    }
  }
  return true;
}();

}  // namespace
}  // namespace dnb
