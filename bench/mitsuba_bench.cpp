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
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bench_util.h"
#include "core/stats.h"
#include "core/timer.h"
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

void BM_Mitsuba(benchmark::State& state, const char* variant) {
  const int spp = int(state.range(0));
  const std::string src = DNB_BENCH_SOURCE_DIR, py = src + "/.venv/bin/python";
  std::string out;
  if (run_capture(py + " -c 'import mitsuba' 2>/dev/null", out) != 0) {
    state.SkipWithError("needs Mitsuba 3 in .venv (scripts/setup)");
    return;
  }
  std::shared_ptr<const dnb::Scene> scene;
  const fs::path dir = fs::temp_directory_path() / ("dnb-bench-mitsuba-" + std::to_string(spp));
  try {
    scene = dnb::load_scene("mcguire-cornell-box");
    fs::remove_all(dir);
    dnb::export_mitsuba(*scene, {.width = kWidth, .height = kHeight, .spp = spp, .max_depth = kPathLength}, dir.string());
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  std::string env;
  if (!std::getenv("DRJIT_LIBLLVM_PATH"))
    if (const std::string llvm = find_libllvm(); !llvm.empty()) env = "DRJIT_LIBLLVM_PATH=" + llvm + " ";
  const std::string cmd = env + py + " " + src + "/python/mitsuba_speed.py " + (dir / "scene.xml").string() +
                          " --variant " + variant + " --repeats " + std::to_string(kRepeats) + " 2>/dev/null";
  const dnb::RenderSettings s = dnb::bench::render_settings(kWidth, kHeight, spp, kPathLength);
  for (auto _ : state) {
    if (run_capture(cmd, out) != 0) {
      state.SkipWithError((std::string("Mitsuba ") + variant + " did not run (libLLVM?): " + cmd).c_str());
      return;
    }
    const nlohmann::json j = nlohmann::json::parse(out.substr(out.find('{')));
    const double mitsuba = j.at("paths_per_second").get<double>();
    std::vector<double> seconds;
    benchmark::DoNotOptimize(dnb::render_frame(*scene, s));  // warm-up
    for (int k = 0; k < kRepeats; ++k) {
      dnb::Stopwatch clock;
      dnb::AovFrame f = dnb::render_frame(*scene, s);
      seconds.push_back(clock.seconds());
      benchmark::DoNotOptimize(f);
    }
    const double tracer = double(kWidth) * kHeight * spp / dnb::stats::median(seconds);
    state.SetIterationTime(dnb::stats::median(seconds));
    state.counters["mitsuba_paths/s"] = mitsuba;
    state.counters["tracer_paths/s"] = tracer;
    state.counters["tracer/mitsuba"] = tracer / mitsuba;
    state.SetLabel(std::string("Mitsuba ") + j.at("mitsuba").get<std::string>() + " " + variant);
  }
  fs::remove_all(dir);
}

BENCHMARK_CAPTURE(BM_Mitsuba, llvm, "llvm_ad_rgb")->Arg(4)->Arg(64)->Iterations(1)->UseManualTime()->Unit(benchmark::kSecond);

}  // namespace
