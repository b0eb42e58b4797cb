// Timing of every registered filter-type method at its defaults, at 256x192 and 1024x768 (the
// paper's size), on a synthetic noisy AOV frame built once outside the timed loop.
//
//   cmake -S . -B build -DDNB_BUILD_BENCH=ON && cmake --build build -j2 --target denoisebench_bench
//   build/bench/denoisebench_bench --benchmark_filter='methods/'
//
// Cases are named methods/<method>/<W>x<H>; each reports wall-clock ms per image (median of the
// repetitions) after one untimed warm-up run. A method added to the registry is timed without a
// new line here.
#include <benchmark/benchmark.h>

#include <cmath>
#include <map>
#include <random>
#include <set>

#include "denoisers/method.h"

namespace dnb {
namespace {

// Two planes meeting at a vertical crease, a checkerboard albedo, smooth lighting with 30%
// relative Gaussian noise on direct and indirect (roughly a low-spp render of a simple room).
AovFrame noisy_frame(int w, int h) {
  AovFrame f(w, h);
  Image& color = f.add(layer::kColor, 3);
  Image& direct = f.add(layer::kDirect, 3);
  Image& indirect = f.add(layer::kIndirect, 3);
  Image& albedo = f.add(layer::kAlbedo, 3);
  Image& normal = f.add(layer::kNormal, 3);
  Image& depth = f.add(layer::kDepth, 1);
  f.add(layer::kReflection, 3);
  f.add(layer::kEmission, 3);
  f.add(layer::kEdge, 1);
  for (const char* v : {layer::kVariance, layer::kDirectVariance, layer::kIndirectVariance}) f.add(v, 3);
  std::mt19937 rng(12345);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const bool left = x < w / 2;
      const float u = float(x) / float(w), v = float(y) / float(h);
      normal.at(x, y, 0) = left ? -0.7071f : 0.7071f;
      normal.at(x, y, 2) = 0.7071f;
      depth.at(x, y, 0) = left ? 3.0f + u : 4.0f - 0.5f * u;
      const float tex = ((x / 16 + y / 16) % 2) ? 0.75f : 0.25f;
      for (int c = 0; c < 3; ++c) {
        const float d = std::max(0.0f, (left ? 0.8f : 0.3f) * (0.6f + 0.4f * v) * (1.0f + 0.3f * gauss(rng)));
        const float i = std::max(0.0f, (0.2f + 0.1f * u) * (1.0f + 0.3f * gauss(rng)));
        direct.at(x, y, c) = d;
        indirect.at(x, y, c) = i;
        albedo.at(x, y, c) = tex;
        color.at(x, y, c) = (d + i) * tex;
      }
    }
  f.meta.scene = "bench-planes";
  return f;
}

const AovFrame& frame_of(int w, int h) {
  static std::map<std::pair<int, int>, AovFrame> frames;
  auto it = frames.find({w, h});
  if (it == frames.end()) it = frames.emplace(std::pair{w, h}, noisy_frame(w, h)).first;
  return it->second;
}

void run_case(benchmark::State& state, const std::string& name, int w, int h) {
  const AovFrame& frame = frame_of(w, h);
  auto method = MethodRegistry::global().create(name);
  run_method(*method, {.frame = &frame});  // warm-up: first-touch allocations, thread pool start
  for (auto _ : state) {
    MethodResult r = run_method(*method, {.frame = &frame});
    benchmark::DoNotOptimize(r.image.data());
  }
  state.counters["Mpixel/s"] =
      benchmark::Counter(double(w) * h * state.iterations() / 1e6, benchmark::Counter::kIsRate);
}

const bool registered = [] {
  for (const MethodInfo* m : MethodRegistry::global().all()) {
    if (m->kind != MethodKind::Filter) continue;
    for (auto [w, h] : {std::pair{256, 192}, std::pair{1024, 768}}) {
      const std::string name = m->name;
      benchmark::RegisterBenchmark(("methods/" + name + "/" + std::to_string(w) + "x" + std::to_string(h)).c_str(),
                                   [name, w = w, h = h](benchmark::State& s) { run_case(s, name, w, h); })
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime()
          ->MinTime(0.5)
          ->Repetitions(5)
          ->ReportAggregatesOnly(true);
    }
  }
  return true;
}();

}  // namespace
}  // namespace dnb
