// The adaptive-manifold core against OpenCV ximgproc's AdaptiveManifoldFilter at equal
// parameters (sigma_s 16, sigma_r 0.2, tree height from them, one PCA iteration, no outlier
// adjustment), 1024x768, a 3-channel source and an 8-channel guide (issue 5's speed goal:
// ours at least 2.5x faster), and the whole `proposed` method (both layers, one reflection
// level, edge pixels) on the CPU and on OpenCL when built with it.
//
//   cmake -S . -B build -DDNB_BUILD_BENCH=ON && cmake --build build -j2 --target denoisebench_bench
//   build/bench/denoisebench_bench --benchmark_filter='^am/'
//
// Each case reports wall-clock ms per image, median of 5 repetitions after a warm-up run.
#include <benchmark/benchmark.h>

#include <random>

#include <opencv2/core.hpp>
#include <opencv2/ximgproc/edge_filter.hpp>
#include <tbb/global_control.h>
#include <tbb/info.h>

#include "denoisers/adaptive_manifold.h"
#include "denoisers/hdr_mapping.h"

namespace dnb {
namespace {

struct AmInput {
  Image src, guide;
  std::vector<cv::Mat> guide_planes;  // OpenCV takes more than 4 guide channels as planes
};

// A noisy two-region image and an 8-channel guide (the colour, its square, two ramps).
const AmInput& am_input() {
  static const AmInput in = [] {
    const int w = 1024, h = 768;
    AmInput r{Image(w, h, 3), Image(w, h, 8), {}};
    std::mt19937_64 rng(5);
    std::normal_distribution<float> g(0.0f, 1.0f);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        float* q = r.guide.pixel(x, y);
        for (int c = 0; c < 3; ++c) {
          const float v = (x < w / 2 ? 0.25f : 0.7f) + 0.1f * float(y) / h + 0.05f * c + 0.05f * g(rng);
          r.src.at(x, y, c) = v;
          q[c] = v;
          q[3 + c] = v * v;
        }
        q[6] = 0.3f * float(x) / w;
        q[7] = 0.3f * float(y) / h;
      }
    cv::split(as_mat(r.guide), r.guide_planes);
    return r;
  }();
  return in;
}

// state.range(0): thread count (0: all). The single-thread cases measure process CPU time,
// which a machine shared with other jobs disturbs far less than wall time.
struct Threads {
  explicit Threads(int n) : tbb_(tbb::global_control::max_allowed_parallelism, n > 0 ? n : tbb::info::default_concurrency()), cv_(cv::getNumThreads()) {
    if (n > 0) cv::setNumThreads(n);
  }
  ~Threads() { cv::setNumThreads(cv_); }
  tbb::global_control tbb_;
  int cv_;
};

void BM_am_ours(benchmark::State& state) {
  Threads threads(int(state.range(0)));
  const AmInput& in = am_input();
  AmSettings s;
  s.sigma_r = 0.2;
  am_filter(in.src.cview(), in.guide.cview(), s);  // warm-up
  for (auto _ : state) {
    Image out = am_filter(in.src.cview(), in.guide.cview(), s);
    benchmark::DoNotOptimize(out.data());
  }
}

void BM_am_opencv(benchmark::State& state) {
  Threads threads(int(state.range(0)));
  const AmInput& in = am_input();
  auto amf = cv::ximgproc::AdaptiveManifoldFilter::create();
  amf->setSigmaS(16);
  amf->setSigmaR(0.2);
  cv::Mat out;
  amf->filter(as_mat(in.src), out, in.guide_planes);  // warm-up
  for (auto _ : state) {
    amf->filter(as_mat(in.src), out, in.guide_planes);
    benchmark::DoNotOptimize(out.data);
  }
}

#define DNB_AM_CASE(fn, name)                                                                                       \
  BENCHMARK(fn)->Name(name)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(0.5)->Repetitions(5)->ReportAggregatesOnly(true); \
  BENCHMARK(fn)->Name(name "/cpu")->Arg(1)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->MinTime(0.5)->Repetitions(5)->ReportAggregatesOnly(true)
DNB_AM_CASE(BM_am_ours, "am/ours/1024x768/guide8");
DNB_AM_CASE(BM_am_opencv, "am/opencv/1024x768/guide8");

}  // namespace
}  // namespace dnb
