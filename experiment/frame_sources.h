// Where a run's cells get their pixels: the input frame of a scene at one spp, loaded on first
// use (InputFrame), and the plain path-tracing curve, one progressive render whose prefixes are
// its points (PlainCurve). Both go through the render cache (tracer/render_cache.h). A scene a
// renderer back-end renders (BackendScene, docs/renderers.md) gets its input, its curve and its
// reference (backend_reference) from the back-end, through the same cache.
#pragma once

#include <cstdint>
#include <exception>
#include <memory>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/aov_frame.h"
#include "core/hash.h"
#include "core/image.h"
#include "experiment/config.h"
#include "experiment/input_files.h"
#include "interop/renderers.h"
#include "tracer/render_cache.h"
#include "tracer/render_cache_keys.h"
#include "tracer/render.h"
#include "tracer/scene.h"

namespace dnb::experiment {

// The render settings of the input frames of config `c` at `spp` with `seed`.
RenderSettings input_settings(const ExperimentConfig& c, int spp, std::uint64_t seed);

// A scene a renderer back-end renders ([[scene]] renderer = ..., file = ...): the back-end, the
// scene file and what every render of it is keyed by.
struct BackendScene {
  std::shared_ptr<interop::RendererBackend> backend;
  std::string file;       // the scene file, absolute
  std::string file_hash;  // SHA-256 of its bytes
  std::string identity;   // the back-end's (interop::RendererBackend::identity: name, version, folder)
  // What a record's scene_hash is for this scene: the back-end's identity and the file's content.
  std::string scene_hash() const { return sha256_hex("renderer=" + identity + "\nfile=" + file_hash + "\n"); }
  // A request of `settings` (size, spp, threads, max depth) with the back-end seed `seed`.
  interop::RenderRequest request(const RenderSettings& settings, std::uint32_t seed, std::vector<std::string> layers) const;
  // The cache key of a product of `kind` made from the renders of `settings`: the back-end's
  // identity, the scene file's content, size, spp, seed, max depth, and `parts`.
  CacheKey key(const std::string& kind, const RenderSettings& settings,
               const std::vector<std::pair<std::string, std::string>>& parts = {}) const;
};

// The 32-bit seed a back-end render is given: a hash of the kind of render (`stream`: "half0",
// "half1", "reference", "curve"), the config's seed and an index (a block, an increment), so
// that no two renders of a run share their random numbers. Deterministic.
std::uint32_t backend_seed(const std::string& stream, std::uint64_t seed, int index);

// The reference of a back-end scene: `spp` samples in blocks of `block_spp`, each block a render
// of its own seed kept in the render cache as it finishes (the checkpoint: an interrupted run
// renders only the blocks it lacks), then the mean, with the variance of the mean from the
// spread of the block means (none with a single block), stored in the cache as the tracer's
// references are (reference.exr: R,G,B and variance.R/G/B) and its blocks removed.
Reference backend_reference(Cache& cache, const BackendScene& b, const RenderSettings& settings, std::uint64_t seed,
                            int block_spp, bool use_cache);

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
  // Frame `frame_scene.frame` of animated scene `name` (docs/sequences.md: its seed and motion
  // layer; experiment/sequences.h), keyed as a rendered frame is.
  InputFrame(Cache& cache, const Scene& frame_scene, const std::string& name, RenderSettings settings, bool use_cache,
             int reference_spp);
  // A back-end scene's frame: two independent renders of spp / 2 samples (two seeds), combined
  // into one frame with half buffers and variances as `import --second` does
  // (interop::combine_halves), kept in the render cache whole. Keyed by its cache key's digest
  // and the reference's spp, as a tracer frame.
  InputFrame(Cache& cache, const BackendScene& b, RenderSettings settings, bool use_cache, int reference_spp);
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
  // The frame; a load that failed (a back-end's render) throws the same error again without
  // trying again, so that the cells of a frame that cannot be had fail with its reason at once.
  const AovFrame& get() {
    if (error_) std::rethrow_exception(error_);
    if (!frame_) {
      try {
        auto [frame, path] = load_(&hit_);
        frame_ = std::move(frame);
        path_ = std::move(path);
      } catch (...) {
        error_ = std::current_exception();
        throw;
      }
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
  std::exception_ptr error_;
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
      : PlainCurve(c, &scene, nullptr, cache, use_cache) {}
  // A back-end scene's curve: the back-end renders the samples each point adds to the last
  // (point N is the spp-weighted mean of the renders up to it, the first N samples of one
  // sequence of renders), each render of its own seed and cached; a point's time is the sum of
  // the render times up to it.
  PlainCurve(const ExperimentConfig& c, const BackendScene& b, Cache& cache, bool use_cache)
      : PlainCurve(c, nullptr, &b, cache, use_cache) {}
  PlainCurve(const ExperimentConfig& c, const Scene* scene, const BackendScene* backend, Cache& cache, bool use_cache)
      : config_(c), scene_(scene), backend_(backend), cache_(cache), use_cache_(use_cache) {
    for (int spp : c.plain_spp) prefixes_.push_back(spp);
    std::sort(prefixes_.begin(), prefixes_.end());
    prefixes_.erase(std::unique(prefixes_.begin(), prefixes_.end()), prefixes_.end());
  }
  int rendered_spp() const { return prefixes_.empty() ? 0 : prefixes_.back(); }
  // Point spp's image and seconds.
  const std::pair<Image, double>& get(int spp) {
    if (error_) std::rethrow_exception(error_);  // as InputFrame::get
    if (points_.empty()) {
      try {
        backend_ ? load_backend() : load();
      } catch (...) {
        points_.clear();
        error_ = std::current_exception();
        throw;
      }
    }
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
  void load_backend();
  static std::string point_file(int spp) { return fmt::format("prefix_{}.exr", spp); }

  const ExperimentConfig& config_;
  const Scene* scene_;
  const BackendScene* backend_;
  Cache& cache_;
  bool use_cache_;
  bool hit_ = false;
  std::vector<int> prefixes_;
  std::map<int, std::pair<Image, double>> points_;
  std::exception_ptr error_;
};

}  // namespace dnb::experiment
