// Irradiance-cache benchmarks: the cache's parts (octree look-up, record interpolation, a
// gather's reduction) and the whole renderer on a small Cornell box next to the path tracer at
// the same size, so that their ratio can be read from one run.
#include <benchmark/benchmark.h>

#include <random>

#include "denoisers/method.h"
#include "irradiance_cache/cache.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace {

using dnb::ic::Vec3;

// n records with random radii on the plane z = `z` of the unit cube (z = 0: on the scene's
// bounds, as the walls of a Cornell box are).
dnb::ic::IrradianceCache random_cache(int n, float z = 0.5f) {
  dnb::ic::IrradianceCache cache(Vec3(0.0f), Vec3(1.0f), {});
  std::mt19937 gen(5);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int i = 0; i < n; ++i) {
    dnb::ic::GatherResult g;
    g.irradiance = Vec3(1.0f);
    g.harmonic_mean_distance = 0.01f + 0.05f * u(gen);
    cache.insert(Vec3(u(gen), u(gen), z), Vec3(0, 0, 1), g, {0.0f, 1e30f});
  }
  return cache;
}

// Look-ups at random points of the records' plane z.
void interpolate_loop(benchmark::State& state, float z) {
  auto cache = random_cache(int(state.range(0)), z);
  std::mt19937 gen(9);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (auto _ : state) {
    Vec3 e;
    benchmark::DoNotOptimize(cache.interpolate(Vec3(u(gen), u(gen), z), Vec3(0, 0, 1), e));
  }
}
void BM_CacheInterpolate(benchmark::State& state) { interpolate_loop(state, 0.5f); }
BENCHMARK(BM_CacheInterpolate)->Arg(1000)->Arg(100000);
void BM_CacheInterpolateOnBounds(benchmark::State& state) { interpolate_loop(state, 0.0f); }
BENCHMARK(BM_CacheInterpolateOnBounds)->Arg(1000)->Arg(100000);

void BM_GatherReduction(benchmark::State& state) {
  // The gather's arithmetic alone (radiance from a closed-form callback): M x N = 16 x 48.
  auto fn = [](Vec3 d, int) { return dnb::ic::GatherSample{Vec3(d.x > 0 ? 1.0f : 0.2f), 1.0f / d.z}; };
  for (auto _ : state) benchmark::DoNotOptimize(dnb::ic::gather(Vec3(0, 0, 1), 16, 48, fn));
}
BENCHMARK(BM_GatherReduction);

void BM_IrradianceCacheCornell(benchmark::State& state) {
  auto scene = dnb::load_scene("cornell-box");
  auto m = dnb::MethodRegistry::global().create("irradiance_cache");
  for (auto _ : state) {
    auto r = dnb::run_method(*m, dnb::MethodInput{.scene = scene.get(), .sample_budget = 256, .width = 128,
                                                  .height = 96, .seed = 1});
    state.counters["records"] = r.stats.counters["records"];
  }
}
BENCHMARK(BM_IrradianceCacheCornell)->Unit(benchmark::kMillisecond)->Iterations(2);

void BM_PathTracer256Cornell(benchmark::State& state) {
  auto scene = dnb::load_scene("cornell-box");
  dnb::RenderSettings s;
  s.width = 128;
  s.height = 96;
  s.spp = 256;
  for (auto _ : state) benchmark::DoNotOptimize(dnb::render_frame(*scene, s));
}
BENCHMARK(BM_PathTracer256Cornell)->Unit(benchmark::kMillisecond)->Iterations(2);

}  // namespace
