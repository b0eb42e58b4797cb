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
// 5: Owen-scrambled Sobol' samples in 8 independent groups, nested in the spp, and variance
//    layers from the groups (render.cpp's top); 484ede7 only.
// 6: the same, with hashed numbers past the second vertex and a cheaper index shuffle (the same
//    distribution, other bits; tracer/math.h's Sampler).
// 7: the same, with Embree's kernels capped at AVX2 (Scene::kEmbreeConfig): other bits on
//    AVX-512 machines, the same images on AVX2 and AVX-512 machines (docs/speed.md).
inline constexpr const char* kTracerVersion = "dnb-tracer-7";
// Bumped whenever a frame gains or loses layers while the images of the layers it had stay the
// same (part of the frame cache key, not the references'). "halves-1": the half buffers
// half0.* and half1.* (core/aov_frame.h). "gloss-trans-1": also R split as Cycles splits it,
// gloss_* and trans_* (core/aov_frame.h).
inline constexpr const char* kFrameLayers = "gloss-trans-1";
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

// Renders every AOV layer of docs/design.md, "AOV frame file" (plus edge sub-pixels and reflection levels).
AovFrame render_frame(const Scene& scene, const RenderSettings& settings);

namespace rt {
struct SampleResult;  // tracer/integrator.h
}
// Another integrator for render_frame's main pass, for experiments that measure one against the
// tracer's own with everything else of a frame unchanged (the accumulation of every layer, the
// variances, the half buffers, the edge set; docs/speed.md: tracer/colour_core.h's vectorised
// core). No command uses one. trace_pixels fills out[p * spp + s] with sample s of pixel
// (x0 + p, y) for p < count and s < spp, and returns the rays it traced; render_frame calls it
// from its worker threads, at most `batch_samples() / spp` pixels at a time (at least one).
class PixelSampler {
 public:
  virtual ~PixelSampler() = default;
  virtual std::uint64_t trace_pixels(int x0, int y, int count, int spp, rt::SampleResult* out) const = 0;
  virtual int batch_samples() const { return 1024; }
};
// render_frame with `main_pass` tracing the main pass's samples (the edge sub-pixels are still
// the tracer's own).
AovFrame render_frame(const Scene& scene, const RenderSettings& settings, const PixelSampler& main_pass);

// Frame `scene.frame` of an animated scene (docs/sequences.md): render_frame with the frame's
// sample seed (tracer/animation.h's frame_seed of settings.seed), plus the motion layer
// (motion.X/Y) against `previous`, the same scene loaded at the previous frame (null at frame 0:
// zero motion). Its metadata records frame, frames and sequence_seed. WorkError when `previous`
// is not the same geometry at the previous frame.
AovFrame render_sequence_frame(const Scene& scene, const Scene* previous, const RenderSettings& settings);
// The motion layer of `current` against `previous` at width x height (docs/sequences.md): one
// ray through each pixel's centre at the frame's instant, its hit carried to the previous frame
// on its triangle and projected with the previous camera. Deterministic; `threads` as render's.
Image motion_layer(const Scene& current, const Scene& previous, int width, int height, int threads = 0);

// The colour layer of a render at each of `prefixes` (rising, at most settings.spp): the image of
// the first N samples of every pixel, bit for bit render_frame's colour layer at spp N (the samples
// do not depend on the spp: render.cpp's top). One progressive render: pass k adds samples
// [prefixes[k - 1], prefixes[k]) to every pixel, then calls on_prefix(k, image, seconds since the
// start), so each prefix's time is what reaching it took.
void render_color_prefixes(const Scene& scene, const RenderSettings& settings, const std::vector<int>& prefixes,
                           const std::function<void(std::size_t, Image, double)>& on_prefix);

// The number of independent sample groups of a pixel (rt::Sampler in tracer/math.h): sample s
// belongs to group s mod kSampleGroups; the variances of pixel means come from the groups' sums.
inline constexpr int kSampleGroups = 8;

// Per-pixel sums of the full radiance F over the sample indices [sample_begin, sample_end) of a
// render, and the same sums per sample group. The samples do not depend on the render's total spp
// (render.cpp's top), so the sums of a range depend only on (scene, settings.seed, the range),
// never on threads.
struct ColorSums {
  int width = 0, height = 0;
  std::int64_t samples = 0;                          // samples per pixel summed
  std::int64_t group_samples[kSampleGroups] = {};    // of them, in each group
  std::int64_t dropped = 0;                          // NaN/Inf samples dropped (counted as 0)
  std::vector<double> sum;        // 3 per pixel, row-major
  std::vector<double> group_sum;  // kSampleGroups x 3 per pixel: pixel-major, then group, then channel
  // Adds another range's sums. Adding ranges in a fixed order gives a fixed result.
  void add(const ColorSums& other);
  Image mean() const;                // sum / samples, as float RGB
  // Of value i (pixel * 3 + channel): the variance of its mean from the groups' sums
  // (tracer/pixel_sums.h's group_ratio_variance); 0 with fewer than two groups.
  double variance_of_mean(std::size_t i) const;
  Image variance_of_mean() const;
};
ColorSums render_color_sums(const Scene& scene, const RenderSettings& settings, int sample_begin,
                            int sample_end);

}  // namespace dnb
