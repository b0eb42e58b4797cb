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
// 4: two samples per stratum, and variance layers from the pairs (render.cpp's top).
inline constexpr const char* kTracerVersion = "dnb-tracer-4";
// Bumped whenever a frame gains or loses layers while the images of the layers it had stay the
// same (part of the frame cache key, not the references'). "halves-1": the half buffers
// half0.* and half1.* (core/aov_frame.h).
inline constexpr const char* kFrameLayers = "halves-1";
// Bumped whenever only the images of scenes with a sun change (part of their cache keys, frames
// and references, beside kTracerVersion; scenes without a sun keep theirs). "sun-rim-1": a sun
// sample that rounds to just outside the disc is a sky direction (Scene::in_sun), no longer the
// sun's radiance at the sky's density.
inline constexpr const char* kSunVersion = "sun-rim-1";

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

// Per-pixel sums of the full radiance F over the sample indices [sample_begin, sample_end) of a
// render with settings.spp samples per pixel in all, and the sums of the squared differences of
// the range's sample pairs (the two samples of a stratum, render.cpp's top; a range that starts
// inside a pair traces its first sample again). The sums of a range depend only on (scene,
// settings.seed, settings.spp, the range), never on threads.
struct ColorSums {
  int width = 0, height = 0;
  std::int64_t samples = 0;          // samples per pixel summed
  std::int64_t pairs = 0;            // sample pairs in pair_sq
  std::int64_t singles = 0;          // samples without a partner (the last of an odd spp)
  std::int64_t dropped = 0;          // NaN/Inf samples dropped (counted as 0)
  std::vector<double> sum, pair_sq;  // 3 per pixel, row-major
  // Adds another range's sums. Adding ranges in a fixed order gives a fixed result.
  void add(const ColorSums& other);
  Image mean() const;                // sum / samples, as float RGB
  // Of value i (pixel * 3 + channel): the variance of its mean from the pairs,
  // pair_sq (1 + singles / (2 pairs)) / samples^2; 0 without a pair.
  double variance_of_mean(std::size_t i) const;
  Image variance_of_mean() const;
};
ColorSums render_color_sums(const Scene& scene, const RenderSettings& settings, int sample_begin,
                            int sample_end);

}  // namespace dnb
