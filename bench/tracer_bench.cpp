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
// seconds); it reports no ray count, so only its paths per second are given.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <string>

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
  dnb::RenderSettings s;
  s.width = kWidth;
  s.height = kHeight;
  s.spp = spp;
  s.max_depth = kPathLength;
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

void BM_EmbreeTutorial(benchmark::State& state) {
  const std::string obj = mcguire_cornell_obj();
  if (obj.empty() || std::system("command -v pathtracer > /dev/null 2>&1") != 0) {
    state.SkipWithError("needs `pathtracer` (embree-tools) and CornellBox-Original.obj");
    return;
  }
  const int spp = int(state.range(0));
  const fs::path out = fs::temp_directory_path() / "dnb-bench-pathtracer.ppm";
  // Camera and light as in mcguire-cornell-box.toml: Cornell's camera, a point light at the
  // centre of the ceiling light.
  const std::string cmd = "pathtracer -i '" + obj +
                          "' --vp 0 1 3.9 --vi 0 1 0 --vu 0 1 0 --fov 39.3 --size " + std::to_string(kWidth) + " " +
                          std::to_string(kHeight) + " --spp " + std::to_string(spp) + " --max-path-length " +
                          std::to_string(kPathLength) + " --pointlight 0 1.9 -0.03 3 3 3 -o '" + out.string() +
                          "' > /dev/null 2>&1";
  for (auto _ : state)
    if (std::system(cmd.c_str()) != 0) {
      state.SkipWithError("pathtracer failed");
      return;
    }
  fs::remove(out);
  const double paths = double(kWidth) * kHeight * spp * double(state.iterations());
  state.counters["paths/s"] = benchmark::Counter(paths, benchmark::Counter::kIsRate);
}

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
BENCHMARK(BM_EmbreeTutorial)->Arg(4)->Arg(16)->Unit(benchmark::kSecond)->UseRealTime();

}  // namespace
