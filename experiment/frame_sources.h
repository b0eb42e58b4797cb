// Where a run's cells get their pixels: the input frame of a scene at one spp, loaded on first
// use (InputFrame), and the plain path-tracing curve, one progressive render whose prefixes are
// its points (PlainCurve). Both go through the render cache (tracer/render_cache.h).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/aov_frame.h"
#include "core/image.h"
#include "experiment/config.h"
#include "experiment/input_files.h"
#include "tracer/render_cache.h"
#include "tracer/render_cache_keys.h"
#include "tracer/render.h"
#include "tracer/scene.h"

namespace dnb::experiment {

// The render settings of the input frames of config `c` at `spp` with `seed`.
RenderSettings input_settings(const ExperimentConfig& c, int spp, std::uint64_t seed);

// The input frame of a scene at one spp, read on first use only (a scene whose cells are all
// finished reads no frame): rendered, through the render cache, or read from the file a
// [[scene]] names (read_input_frame). `identity` is what its cells are keyed by; `path` the file
// it was read from, which the input cell keeps in the folder. Not movable: loading refers to it.
class InputFrame {
 public:
  // A rendered frame: keyed by its cache key's digest and the reference's spp, the identity older
  // results folders' cells have too, so that their finished cells are still reused.
  InputFrame(Cache& cache, const Scene& scene, RenderSettings settings, bool use_cache, int reference_spp)
      : use_cache_(use_cache) {
    const CacheKey key = frame_cache_key(scene, settings);
    identity_ = {{"input", key.digest()}, {"ref", reference_spp}};
    load_ = [this, &cache, &scene, settings, key](bool* hit) {
      if (!use_cache_) cache.remove(key);
      AovFrame f = cached_frame(cache, key, [&] { return render_frame(scene, settings); }, hit);
      return std::pair(std::move(f), cache.entry_dir(key) + "/frame.exr");
    };
  }
  // A frame read from a file: keyed by the contents of both files and the scene's name.
  explicit InputFrame(const SceneSpec& spec)
      : identity_{{"input_file", spec.files->frame_hash}, {"reference_file", spec.files->reference_hash}, {"scene", spec.name}},
        from_file_(true) {
    load_ = [files = *spec.files](bool*) {
      return std::pair(read_input_frame(files.frame, files.input_format, files.second.empty() ? files.spp : files.spp / 2,
                                        files.second),
                       files.frame);
    };
  }
  InputFrame(const InputFrame&) = delete;
  InputFrame& operator=(const InputFrame&) = delete;

  const nlohmann::json& identity() const { return identity_; }
  bool from_file() const { return from_file_; }
  const AovFrame& get() {
    if (!frame_) {
      auto [frame, path] = load_(&hit_);
      frame_ = std::move(frame);
      path_ = std::move(path);
    }
    return *frame_;
  }
  const std::string& path() {
    get();
    return path_;
  }
  std::optional<bool> cache_hit() const {
    if (from_file_) return std::nullopt;
    return stored_hit_ ? stored_hit_ : std::optional<bool>(hit_);
  }
  // A distributed run's method cells: another rank has put the frame in the cache (rendered it,
  // or found it there: `hit`). Read it from the cache, and report `hit` as the cells of a
  // one-process run, which share one load of the frame, do.
  void use_stored(std::optional<bool> hit) {
    use_cache_ = true;
    stored_hit_ = hit;
  }
  // Frees the frame (it is loaded again on the next use).
  void release() { frame_.reset(); }

 private:
  nlohmann::json identity_;
  bool from_file_ = false;
  bool use_cache_ = true;
  std::function<std::pair<AovFrame, std::string>(bool* hit)> load_;
  bool hit_ = false;
  std::optional<bool> stored_hit_;
  std::optional<AovFrame> frame_;
  std::string path_;
};

// The plain path-tracing curve of a scene: one progressive render to the curve's largest spp,
// each point the image of its first N samples (tracer/render.h's render_color_prefixes: bit for
// bit `render --spp N`), its time what the render took to reach N. Rendered whole when the first
// cell that needs a point asks for it, so the curve costs one render whichever of its points are
// computed, and kept in the render cache (a resumed run that misses one point reads them all from
// there, or renders to the largest again: its records then say the same as an uninterrupted run's).
class PlainCurve {
 public:
  PlainCurve(const ExperimentConfig& c, const Scene& scene, Cache& cache, bool use_cache)
      : config_(c), scene_(scene), cache_(cache), use_cache_(use_cache) {
    for (int spp : c.plain_spp) prefixes_.push_back(spp);
    std::sort(prefixes_.begin(), prefixes_.end());
    prefixes_.erase(std::unique(prefixes_.begin(), prefixes_.end()), prefixes_.end());
  }
  int rendered_spp() const { return prefixes_.empty() ? 0 : prefixes_.back(); }
  // Point spp's image and seconds.
  const std::pair<Image, double>& get(int spp) {
    if (points_.empty()) load();
    return points_.at(spp);
  }
  // Whether the points came from the render cache (known once a point was asked for).
  bool cache_hit() const { return hit_; }
  void release() { points_.clear(); }

 private:
  // From the render cache when it holds this curve (each point's image and the seconds the render
  // took to reach it, as first measured), else rendered and stored there: a run whose plain cells
  // must be scored again (the metrics changed) reads the curve instead of rendering it again.
  void load();
  static std::string point_file(int spp) { return fmt::format("prefix_{}.exr", spp); }

  const ExperimentConfig& config_;
  const Scene& scene_;
  Cache& cache_;
  bool use_cache_;
  bool hit_ = false;
  std::vector<int> prefixes_;
  std::map<int, std::pair<Image, double>> points_;
};

}  // namespace dnb::experiment
