// The tracer against Mitsuba 3 on the same scene: McGuire's Cornell box (mcguire-cornell-box:
// diffuse walls and blocks, its one-sided area light) exported by `export-mitsuba`
// (tracer/mitsuba_export.h) at the tracer bench's size (1024x768), samples per pixel (the case's
// argument) and path length (8), rendered by Mitsuba 3 (python/mitsuba_speed.py in the project's
// .venv; llvm_ad_rgb, Dr.Jit's LLVM back-end on every core, kernels compiled in a warm-up render
// first) and, in the same case and session, by the tracer (render_frame: every AOV, edge
// sub-pixels, two reflection levels), each the median of 3 renders after a warm-up.
//
//   build/bench/denoisebench_bench --benchmark_filter=BM_Mitsuba --benchmark_out=mitsuba.json
//
// Two spp: 4, and 64, nearer the harness's own frames (256-spp inputs, 4096-spp references),
// where the tracer's fixed cost per pixel (allocating and finishing about 127 AOV channels, the
// edge set) weighs less. Both play Russian roulette from the same vertex (the export's rr_depth).
// 2026-12-07, tracer 7, 2 cores, one session: tracer/mitsuba 0.67 at 4 spp and 0.76 at 64
// (Mitsuba 5.80 M and 6.07 M paths/s; the tracer 3.90 M and 4.62 M; docs/speed.md).
//
// Counters: mitsuba_paths/s, tracer_paths/s and tracer/mitsuba (their ratio). The llvm variant
// needs Debian's libLLVM (libllvm15, scripts/setup): DRJIT_LIBLLVM_PATH is set to it here unless
// the environment sets it. Skipped with the reason where .venv has no Mitsuba or the variant
// cannot start.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench_util.h"
#include "tracer/colour_core.h"
#include "core/stats.h"
#include "core/timer.h"
#include "core/aov_frame.h"
#include "tracer/math.h"
#include "tracer/mitsuba_export.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace {

namespace fs = std::filesystem;
constexpr int kWidth = 1024, kHeight = 768, kPathLength = 8, kRepeats = 3;

// The first line of a command's standard output (its stderr dropped), and its exit status.
int run_capture(const std::string& cmd, std::string& out) {
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return -1;
  char buf[4096];
  out.clear();
  while (fgets(buf, sizeof buf, p)) out += buf;
  return pclose(p);
}

// Debian's libLLVM for Dr.Jit's LLVM back-end, newest first; empty when none is installed.
std::string find_libllvm() {
  for (const char* v : {"16", "15", "14", "13"}) {
    const std::string p = std::string("/usr/lib/x86_64-linux-gnu/libLLVM-") + v + ".so.1";
    if (fs::exists(p)) return p;
  }
  return {};
}

// Renders McGuire's box with Mitsuba (`variant`) at the case's size, `spp` and path length;
// returns its paths/s (the median of kRepeats renders after a warm-up) and sets `label` to its
// version, or returns 0 after skipping the case with the reason. `scene` receives the tracer's.
double mitsuba_paths_per_second(benchmark::State& state, const char* variant, int spp,
                                std::shared_ptr<const dnb::Scene>& scene, std::string& label) {
  const std::string src = DNB_BENCH_SOURCE_DIR, py = src + "/.venv/bin/python";
  std::string out;
  if (run_capture(py + " -c 'import mitsuba' 2>/dev/null", out) != 0) {
    state.SkipWithError("needs Mitsuba 3 in .venv (scripts/setup)");
    return 0;
  }
  const fs::path dir = fs::temp_directory_path() / ("dnb-bench-mitsuba-" + std::to_string(spp));
  try {
    scene = dnb::load_scene("mcguire-cornell-box");
    fs::remove_all(dir);
    dnb::export_mitsuba(*scene, {.width = kWidth, .height = kHeight, .spp = spp, .max_depth = kPathLength}, dir.string());
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return 0;
  }
  std::string env;
  if (!std::getenv("DRJIT_LIBLLVM_PATH"))
    if (const std::string llvm = find_libllvm(); !llvm.empty()) env = "DRJIT_LIBLLVM_PATH=" + llvm + " ";
  const std::string cmd = env + py + " " + src + "/python/mitsuba_speed.py " + (dir / "scene.xml").string() +
                          " --variant " + variant + " --repeats " + std::to_string(kRepeats) + " 2>/dev/null";
  const int rc = run_capture(cmd, out);
  fs::remove_all(dir);
  if (rc != 0) {
    state.SkipWithError((std::string("Mitsuba ") + variant + " did not run (libLLVM?): " + cmd).c_str());
    return 0;
  }
  const nlohmann::json j = nlohmann::json::parse(out.substr(out.find('{')));
  label = std::string("Mitsuba ") + j.at("mitsuba").get<std::string>() + " " + variant;
  return j.at("paths_per_second").get<double>();
}

// The median of kRepeats timings of `render` after one warm-up call.
template <typename Fn>
double median_seconds(Fn&& render) {
  render();
  std::vector<double> seconds;
  for (int k = 0; k < kRepeats; ++k) {
    dnb::Stopwatch clock;
    render();
    seconds.push_back(clock.seconds());
  }
  return dnb::stats::median(seconds);
}

void BM_Mitsuba(benchmark::State& state, const char* variant) {
  const int spp = int(state.range(0));
  const dnb::RenderSettings s = dnb::bench::render_settings(kWidth, kHeight, spp, kPathLength);
  for (auto _ : state) {
    std::shared_ptr<const dnb::Scene> scene;
    std::string label;
    const double mitsuba = mitsuba_paths_per_second(state, variant, spp, scene, label);
    if (!(mitsuba > 0)) return;
    const double sec = median_seconds([&] { benchmark::DoNotOptimize(dnb::render_frame(*scene, s)); });
    const double tracer = double(kWidth) * kHeight * spp / sec;
    state.SetIterationTime(sec);
    state.counters["mitsuba_paths/s"] = mitsuba;
    state.counters["tracer_paths/s"] = tracer;
    state.counters["tracer/mitsuba"] = tracer / mitsuba;
    state.SetLabel(label);
  }
}

// The go/no-go experiment of docs/speed.md: tracer/colour_core.h's path tracer vectorised across
// paths, on the same scene, size, spp and path length as Mitsuba and the tracer, in one session
// (counters: each one's paths/s over Mitsuba's):
//   core/mitsuba         colour alone, lanes of 8 under the tracer's AVX2 cap, Embree packets
//   core_single/mitsuba  the same with every ray traced alone: what the packets give
//   core16/mitsuba       lanes of 16 with Embree's AVX-512 kernels, uncapped as Mitsuba's are
//                        (without AVX-512, Embree falls back to its best)
//   core_aov/mitsuba     the core as render_frame's main pass (PixelSampler): every AOV
//                        accumulated and stored by the tracer's code, the edge pass the tracer's
//   core_aov_sobol/mitsuba  the same with the tracer's own random numbers (rt::Sampler)
//   tracer/mitsuba       the tracer (render_frame)
// and the rays per path of the core and the tracer (they must do the same work per path). The
// checks, which skip the case as wrong when they fail:
//   - with independent numbers, the core's colour and its frame's level-0 layers have the
//     tracer's expectation: per layer, the mean over pixels and channels of the difference, in
//     standard errors from the pixels' own spread (independent pixels: z close to normal);
//     |z| > 4 fails (6e-5 per layer by chance). core_vs_tracer_worst_z is the largest |z|.
//   - with the tracer's numbers, the core traces the tracer's paths: every colour value within
//     1e-4 relative of the tracer's (the arithmetic differs in rounding only: vector sin and cos,
//     products in another order); sobol_within_1e-4 is the fraction, and must be 1 but for
//     1e-5 of the values (a rounding that flips one path's roulette or occlusion test).
// 2026-12-07, Intel Xeon, 2 cores, tracer 7, 64 spp: core 1.23, core_single 0.91, core16 0.89,
// core_aov 1.07, core_aov_sobol 0.94, tracer 0.66 (reports/speed/2026-12-07-vector-core-2.json;
// docs/speed.md, "The go/no-go, built and run").
void BM_ColourCore(benchmark::State& state) {
  const int spp = int(state.range(0));
  const dnb::RenderSettings s = dnb::bench::render_settings(kWidth, kHeight, spp, kPathLength);
  for (auto _ : state) {
    std::shared_ptr<const dnb::Scene> scene;
    std::string label;
    const double mitsuba = mitsuba_paths_per_second(state, "llvm_ad_rgb", spp, scene, label);
    if (!(mitsuba > 0)) return;
    if (const std::string why = dnb::ColourCore::supported(*scene); !why.empty()) {
      state.SkipWithError(("the colour core cannot render mcguire-cornell-box: " + why).c_str());
      return;
    }
    const double paths = double(kWidth) * kHeight * spp;
    dnb::AovFrame frame;
    const double tracer_sec = median_seconds([&] { frame = dnb::render_frame(*scene, s); });
    const double tracer_rays = std::stod(frame.meta.extra.at("rays"));
    dnb::ColourCore::Options o;
    o.width = kWidth;
    o.height = kHeight;
    o.spp = spp;
    o.max_depth = kPathLength;
    std::vector<float> img;
    double core_rays = 0;
    auto core_seconds = [&](int lanes, dnb::ColourCore::Trace trace, const char* config) {
      o.lanes = lanes;
      o.trace = trace;
      o.embree_config = config;
      const dnb::ColourCore core(*scene, o);
      return median_seconds([&] { img = core.render(&core_rays); });
    };
    const double single_sec = core_seconds(8, dnb::ColourCore::Trace::kSingleRays, dnb::Scene::kEmbreeConfig);
    const double wide_sec = core_seconds(16, dnb::ColourCore::Trace::kPackets, "max_isa=avx512");
    const double core_sec = core_seconds(8, dnb::ColourCore::Trace::kPackets, dnb::Scene::kEmbreeConfig);
    // The core as the main pass of render_frame: every AOV accumulated, stored and checked as the
    // tracer's own frames are; with independent numbers, then with the tracer's.
    dnb::AovFrame core_frame, sobol_frame;
    const dnb::ColourCore aov_core(*scene, o);  // o: 8 lanes, packets, the AVX2 cap (as core_sec)
    const double aov_sec = median_seconds([&] { core_frame = dnb::render_frame(*scene, s, aov_core); });
    o.numbers = dnb::ColourCore::Numbers::kTracer;
    o.seed = s.seed;
    const dnb::ColourCore sobol_core(*scene, o);
    const double sobol_sec = median_seconds([&] { sobol_frame = dnb::render_frame(*scene, s, sobol_core); });
    // The checks: the core's colour (img: its last render) and its frame's level-0 layers
    // against the tracer's frame.
    const dnb::Image& tc = frame.layer(dnb::layer::kColor);
    // Per layer: the mean difference over pixels and channels in standard errors (pixels are
    // independent: z close to normal where both have one expectation).
    double z = dnb::stats::paired_z(img.data(), tc.data(), tc.size());
    std::string worst_layer = "colour (colour-only core)";
    for (const char* name : {dnb::layer::kColor, dnb::layer::kDirect, dnb::layer::kIndirect, dnb::layer::kAlbedo,
                             dnb::layer::kEmission, dnb::layer::kNormal, dnb::layer::kDepth}) {
      const dnb::Image& a = core_frame.layer(name);
      const dnb::Image& b = frame.layer(name);
      const double za = dnb::stats::paired_z(a.data(), b.data(), a.size());
      if (!(std::abs(za) <= std::abs(z))) {
        z = za;
        worst_layer = name;
      }
    }
    const dnb::Image& sc = sobol_frame.layer(dnb::layer::kColor);
    std::size_t close = 0;
    for (std::size_t i = 0; i < tc.size(); ++i)
      close += std::abs(sc.data()[i] - tc.data()[i]) <= 1e-4f * std::max(1.0f, std::abs(tc.data()[i]));
    const double within = double(close) / double(tc.size());
    state.SetIterationTime(core_sec);
    state.counters["mitsuba_paths/s"] = mitsuba;
    state.counters["core_paths/s"] = paths / core_sec;
    state.counters["core/mitsuba"] = paths / core_sec / mitsuba;
    state.counters["core_single/mitsuba"] = paths / single_sec / mitsuba;
    state.counters["core16/mitsuba"] = paths / wide_sec / mitsuba;
    state.counters["tracer/mitsuba"] = paths / tracer_sec / mitsuba;
    state.counters["core_rays/path"] = core_rays / paths;
    state.counters["tracer_rays/path"] = tracer_rays / paths;
    state.counters["core_aov/mitsuba"] = paths / aov_sec / mitsuba;
    state.counters["core_aov_sobol/mitsuba"] = paths / sobol_sec / mitsuba;
    state.counters["sobol_within_1e-4"] = within;
    state.counters["core_vs_tracer_worst_z"] = z;
    state.SetLabel(label + ", worst z in " + worst_layer);
    if (!(std::abs(z) <= 4)) {
      state.SkipWithError(("the colour core disagrees with the tracer in " + worst_layer + ": z = " + std::to_string(z)).c_str());
      return;
    }
    if (!(within >= 1 - 1e-5)) {
      state.SkipWithError(("with the tracer's numbers, only " + std::to_string(within) +
                           " of the core's colour values are within 1e-4 of the tracer's").c_str());
      return;
    }
  }
}

BENCHMARK_CAPTURE(BM_Mitsuba, llvm, "llvm_ad_rgb")->Arg(4)->Arg(64)->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);
BENCHMARK(BM_ColourCore)->Arg(4)->Arg(64)->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);

}  // namespace
