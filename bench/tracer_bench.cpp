// Tracer throughput: paths per second and rays per second of render_frame (every AOV layer,
// edge sub-pixels and two reflection levels) at 1024x768 with path length 8 on every built-in
// scene (cornell-box, conference, bedroom, sponza) and McGuire's Cornell box, and, run in the
// same session, the Embree tutorial path tracer (`pathtracer` from Debian's embree-tools) on a
// Cornell box at the same size, samples per pixel and path length.
//
//   build/bench/denoisebench_bench --benchmark_filter='BM_Tracer|EmbreeTutorial'
//       --benchmark_repetitions=3 --benchmark_enable_random_interleaving=true
//
// The tutorial reads no emitters from OBJ files, so it renders McGuire's CornellBox-Original.obj
// (../shared/scenes or $DENOISEBENCH_SCENES) with a point light where the ceiling light is; our
// tracer renders the same OBJ (mcguire-cornell-box, with its area light) and the built-in
// cornell-box (area light, mirror sphere, coated block). The tutorial is timed as a whole
// process (start-up, BVH build and writing its image add about 0.1 s to a run of a few
// seconds); it reports no ray count, so only its paths per second are given. BM_EmbreeTutorial
// times our tracer on mcguire-cornell-box in the same case and reports the ratio,
// tracer/embree, against the faster of the tutorial's two runs (Embree's default kernels, and
// capped at AVX2 as the tracer's are) (2026-12-07, tracer 7, 2 cores: 1.03 at 4 spp, 1.21 at 16).
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <random>
#include <filesystem>
#include <string>
#include <vector>

#include "bench_util.h"
#include "core/stats.h"
#include "core/timer.h"
#include "tracer/math.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"

namespace {

namespace fs = std::filesystem;
constexpr int kWidth = 1024, kHeight = 768, kPathLength = 8;  // spp: the case's argument

void BM_Tracer(benchmark::State& state, const char* scene_name) {
  std::shared_ptr<const dnb::Scene> scene;
  try {
    scene = dnb::load_scene(scene_name);
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  const int spp = int(state.range(0));
  const dnb::RenderSettings s = dnb::bench::render_settings(kWidth, kHeight, spp, kPathLength);
  double rays = 0;
  for (auto _ : state) {
    dnb::AovFrame f = dnb::render_frame(*scene, s);
    rays += std::stod(f.meta.extra.at("rays"));
    benchmark::DoNotOptimize(f);
  }
  const double paths = double(kWidth) * kHeight * spp * double(state.iterations());
  state.counters["paths/s"] = benchmark::Counter(paths, benchmark::Counter::kIsRate);
  state.counters["rays/s"] = benchmark::Counter(rays, benchmark::Counter::kIsRate);
  state.counters["rays/path"] = rays / paths;
}

// The OBJ file mcguire-cornell-box reads (found as the tracer finds the McGuire scenes).
std::string mcguire_cornell_obj() {
  try {
    auto scene = dnb::load_scene("mcguire-cornell-box");
    for (const auto& f : scene->files)
      if (fs::path(f).extension() == ".obj") return f;
  } catch (const std::exception&) {
  }
  return {};
}

// The tutorial and the tracer (render_frame on mcguire-cornell-box: its area light, every AOV)
// at the same size, spp and path length, alternately in one case after a warm-up of each, the
// median of kRepeats each: counters embree_paths/s, tracer_paths/s and tracer/embree.
void BM_EmbreeTutorial(benchmark::State& state) {
  constexpr int kRepeats = 3;
  const std::string obj = mcguire_cornell_obj();
  if (obj.empty() || std::system("command -v pathtracer > /dev/null 2>&1") != 0) {
    state.SkipWithError("needs `pathtracer` (embree-tools) and CornellBox-Original.obj");
    return;
  }
  const int spp = int(state.range(0));
  const fs::path out = fs::temp_directory_path() / "dnb-bench-pathtracer.ppm";
  // Camera and light as in mcguire-cornell-box.toml: Cornell's camera, a point light at the
  // centre of the ceiling light.
  // The tutorial twice: with Embree's default kernels (AVX-512 where the processor has it) and
  // capped at AVX2 as the tracer's Embree device is (Scene::kEmbreeConfig); the ratio is taken
  // against the faster of the two, so the cap cannot flatter the tracer.
  auto tutorial_cmd = [&](const std::string& rtcore) {
    return "pathtracer -i '" + obj + "' --vp 0 1 3.9 --vi 0 1 0 --vu 0 1 0 --fov 39.3 --size " +
           std::to_string(kWidth) + " " + std::to_string(kHeight) + " --spp " + std::to_string(spp) +
           " --max-path-length " + std::to_string(kPathLength) + " --pointlight 0 1.9 -0.03 3 3 3" +
           (rtcore.empty() ? "" : " --rtcore " + rtcore) + " -o '" + out.string() + "' > /dev/null 2>&1";
  };
  const std::string cmds[2] = {tutorial_cmd(""), tutorial_cmd(dnb::Scene::kEmbreeConfig)};
  const auto scene = dnb::load_scene("mcguire-cornell-box");
  const dnb::RenderSettings s = dnb::bench::render_settings(kWidth, kHeight, spp, kPathLength);
  for (auto _ : state) {
    std::vector<double> tutorial[2], tracer;
    for (int k = -1; k < kRepeats; ++k) {  // k = -1: the warm-ups
      for (int c = 0; c < 2; ++c) {
        dnb::Stopwatch clock;
        if (std::system(cmds[c].c_str()) != 0) {
          state.SkipWithError("pathtracer failed");
          return;
        }
        if (k >= 0) tutorial[c].push_back(clock.seconds());
      }
      dnb::Stopwatch clock;
      dnb::AovFrame f = dnb::render_frame(*scene, s);
      if (k >= 0) tracer.push_back(clock.seconds());
      benchmark::DoNotOptimize(f);
    }
    const double paths = double(kWidth) * kHeight * spp;
    const double embree_default = paths / dnb::stats::median(tutorial[0]);
    const double embree_avx2 = paths / dnb::stats::median(tutorial[1]);
    const double embree = std::max(embree_default, embree_avx2), ours = paths / dnb::stats::median(tracer);
    state.SetIterationTime(paths / embree);
    state.counters["embree_paths/s"] = embree_default;
    state.counters["embree_avx2_paths/s"] = embree_avx2;
    state.counters["tracer_paths/s"] = ours;
    state.counters["tracer/embree"] = ours / embree;
  }
  fs::remove(out);
}

// What Embree's packets would gain the tracer on its bounce rays (docs/speed.md): on
// mcguire-cornell-box at 256x192, 16 camera rays per pixel, and from each hit one cosine-
// distributed bounce ray, kept in pixel order (the 16 bounce rays of a pixel's samples are one
// packet, as a wavefront integrator over a pixel's samples would trace them). Both ways trace
// the same rays through Scene::intersect, hits filled in full: one by one, and 16 at a time; a
// warm-up of each, then kRepeats of each alternately. Counters single_rays/s, packet_rays/s and
// packet/single; range(0) = 1 shuffles the rays first (packets of unrelated rays).
void BM_BounceRays(benchmark::State& state) {
  constexpr int kRepeats = 5, kW = 256, kH = 192, kSpp = 16;
  std::shared_ptr<const dnb::Scene> scene;
  try {
    scene = dnb::load_scene("mcguire-cornell-box");
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  std::vector<dnb::rt::Ray> rays;
  dnb::rt::Sampler rng(5, 0, 0);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      for (int s = 0; s < kSpp; ++s) {
        dnb::rt::SurfaceHit h;
        const dnb::rt::Ray cam = scene->camera.generate_ray(x + rng.next(), y + rng.next(), kW, kH);
        if (!scene->intersect(cam, h)) continue;
        const dnb::rt::Frame f(h.ns);
        rays.push_back(h.spawn_ray(f.to_world(dnb::rt::sample_cosine_hemisphere(rng.next(), rng.next()))));
      }
  if (state.range(0)) std::shuffle(rays.begin(), rays.end(), std::mt19937(1));
  std::vector<dnb::rt::SurfaceHit> hits(rays.size());
  std::vector<std::uint8_t> found(rays.size());
  auto single = [&] {
    dnb::Stopwatch clock;
    for (std::size_t i = 0; i < rays.size(); ++i) found[i] = scene->intersect(rays[i], hits[i]) ? 1 : 0;
    benchmark::DoNotOptimize(found.data());
    return clock.seconds();
  };
  auto packets = [&] {
    dnb::Stopwatch clock;
    scene->intersect(rays.data(), int(rays.size()), hits.data(), found.data());
    benchmark::DoNotOptimize(found.data());
    return clock.seconds();
  };
  for (auto _ : state) {
    single();
    packets();
    std::vector<double> a, b;
    for (int k = 0; k < kRepeats; ++k) {
      a.push_back(single());
      b.push_back(packets());
    }
    const double n = double(rays.size());
    state.SetIterationTime(dnb::stats::median(b));
    state.counters["single_rays/s"] = n / dnb::stats::median(a);
    state.counters["packet_rays/s"] = n / dnb::stats::median(b);
    state.counters["packet/single"] = dnb::stats::median(a) / dnb::stats::median(b);
  }
}
BENCHMARK(BM_BounceRays)->Arg(0)->Arg(1)->Iterations(1)->UseManualTime()->Unit(benchmark::kMillisecond);

// Samples per pixel per iteration: 4 and 16 (fixed per-frame costs, such as allocating and
// zeroing the ~260 MB of AOV layers, weigh more at 4). Every built-in scene at 4 spp, the
// Cornell boxes (compared with the tutorial) at 16 as well.
BENCHMARK_CAPTURE(BM_Tracer, cornell_box, "cornell-box")->Arg(4)->Arg(16)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Tracer, conference, "conference")->Arg(4)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Tracer, bedroom, "bedroom")->Arg(4)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Tracer, sponza, "sponza")->Arg(4)->Unit(benchmark::kSecond)->UseRealTime();
BENCHMARK_CAPTURE(BM_Tracer, mcguire_cornell_box, "mcguire-cornell-box")
    ->Arg(4)
    ->Arg(16)
    ->Unit(benchmark::kSecond)
    ->UseRealTime();
BENCHMARK(BM_EmbreeTutorial)->Arg(4)->Arg(16)->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);

}  // namespace
