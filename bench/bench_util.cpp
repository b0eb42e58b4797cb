#include "bench/bench_util.h"

#include <chrono>
#include <ctime>
#include <mutex>
#include <optional>

#include <opencv2/core.hpp>
#include <tbb/global_control.h>

#include "tracer/render_cache.h"
#include "tracer/render_cache_keys.h"
#include "tracer/reference.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace dnb::bench {

std::shared_ptr<const Scene> scene(const std::string& name) {
  static std::mutex mutex;
  static std::map<std::string, std::shared_ptr<const Scene>> scenes;
  std::lock_guard lock(mutex);
  auto& s = scenes[name];
  if (!s) s = load_scene(name);
  return s;
}

const AovFrame& rendered_frame(const std::string& scene_name, int w, int h, int spp) {
  static std::mutex mutex;
  static std::map<std::tuple<std::string, int, int, int>, AovFrame> frames;
  std::lock_guard lock(mutex);
  const auto id = std::tuple{scene_name, w, h, spp};
  auto it = frames.find(id);
  if (it != frames.end()) return it->second;
  auto sc = scene(scene_name);
  RenderSettings s;
  s.width = w;
  s.height = h;
  s.spp = spp;
  Cache cache(Cache::default_dir());
  return frames.emplace(id, cached_frame(cache, frame_cache_key(*sc, s), [&] { return render_frame(*sc, s); }))
      .first->second;
}

struct ThreadLimit::Impl {
  std::optional<tbb::global_control> tbb;
  int cv_threads = cv::getNumThreads();
};

ThreadLimit::ThreadLimit(int threads) : impl_(std::make_unique<Impl>()) {
  if (threads > 0) {
    impl_->tbb.emplace(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
    cv::setNumThreads(threads);
  }
}

ThreadLimit::~ThreadLimit() { cv::setNumThreads(impl_->cv_threads); }

double process_cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

double wall_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

namespace {
constexpr int kRefWidth = 32, kRefHeight = 24, kRefSpp = 4;
}

ReferenceWorkload::ReferenceWorkload(int threads) : scene_(scene("cornell-box")), threads_(threads) {}

void ReferenceWorkload::run() const {
  RenderSettings s;
  s.width = kRefWidth;
  s.height = kRefHeight;
  s.spp = kRefSpp;
  s.seed = 7;
  s.threads = threads_;
  ColorSums sums = render_color_sums(*scene_, s, 0, kRefSpp);
  if (sums.sum.empty()) std::abort();  // keeps the job from being optimised away
}

std::string ReferenceWorkload::description() {
  return "path tracing cornell-box " + std::to_string(kRefWidth) + "x" + std::to_string(kRefHeight) + ", " +
         std::to_string(kRefSpp) + " spp, colour only";
}

RenderSettings render_settings(int w, int h, int spp, int max_depth) {
  RenderSettings s;
  s.width = w;
  s.height = h;
  s.spp = spp;
  s.max_depth = max_depth;
  return s;
}

}  // namespace dnb::bench
