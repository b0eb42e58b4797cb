// The public face of the shared tracer: render an AOV frame of a loaded scene
// (tracer/scene_loader.h), or accumulate colour sums over a range of sample indices (the
// building block of checkpointed and distributed references). Everything else in tracer/ is an
// implementation detail that only the tracer and renderer-type methods (irradiance_cache/)
// include.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/aov_frame.h"
#include "core/image.h"

namespace dnb {

class Scene;  // tracer/scene.h

// Bumped whenever a change to the tracer changes its images (part of every cache key).
inline constexpr const char* kTracerVersion = "dnb-tracer-3";

struct RenderSettings {
  int width = 1024;
  int height = 768;
  int spp = 256;
  std::uint64_t seed = 1;
  int threads = 0;            // 0: all cores (the image does not depend on it)
  int max_depth = 8;          // path length
  int reflection_levels = 2;  // refl1.* .. reflK.* layers
  bool edge_subpixels = true; // 4x4 sub-pixel data for edge pixels
  // Called from worker threads with the number of pixel-samples just finished.
  std::function<void(std::int64_t)> on_progress;
};

// Renders every AOV layer of DESIGN.md (plus edge sub-pixels and reflection levels).
AovFrame render_frame(const Scene& scene, const RenderSettings& settings);

// Per-pixel sums of the full radiance F and of its square over the sample indices
// [sample_begin, sample_end) of a render with settings.spp samples per pixel in all. The sums
// of a range depend only on (scene, settings.seed, settings.spp, the range), never on threads.
struct ColorSums {
  int width = 0, height = 0;
  std::int64_t samples = 0;          // samples per pixel summed
  std::int64_t dropped = 0;          // NaN/Inf samples dropped
  std::vector<double> sum, sum_sq;   // 3 per pixel, row-major
  // Adds another range's sums. Adding ranges in a fixed order gives a fixed result.
  void add(const ColorSums& other);
  Image mean() const;                // sum / samples, as float RGB
  Image variance_of_mean() const;    // per-pixel sample variance / samples
};
ColorSums render_color_sums(const Scene& scene, const RenderSettings& settings, int sample_begin,
                            int sample_end);

}  // namespace dnb
