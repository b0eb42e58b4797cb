// What the passes of a render share (render.cpp's main pass, render_edges.cpp's edge set and its
// sub-pixels, color_sums.cpp's colour-only renders): the tile loop, the thread arena, the
// settings' checks and one sample traced from its pixel's random numbers. Internal to tracer/.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "core/bounds.h"
#include "core/errors.h"
#include "core/image.h"
#include "tracer/integrator.h"
#include "tracer/render.h"
#include "tracer/scene.h"

namespace dnb::render_pass {
using namespace rt;

constexpr int kGroups = Sampler::kGroups;
static_assert(kGroups == kSampleGroups, "render.h's group count is the sampler's");
static_assert(kGroups % 2 == 0, "the half buffers are the even and the odd groups");

constexpr int kTile = 16;

// Embree and the integrator want denormals flushed (speed); set on every rendering task, so
// every thread computes the same bits.
inline void set_ftz_daz() { enable_flush_to_zero(); }

inline void check_settings(const RenderSettings& s) {
  Image::check_size(s.width, s.height, 3, "render size");
  check_bound(s.spp, bounds::kSpp, "render: spp");
  check_bound(s.max_depth, bounds::kMaxDepth, "render: max depth");
  if (s.reflection_levels < 0 || s.reflection_levels > kMaxReflectionLevels)
    throw InputError(fmt::format("reflection levels must be in 0..{} (got {})", kMaxReflectionLevels,
                                 s.reflection_levels));
  check_bound(s.threads, bounds::kThreads, "render: threads");
}

// Film position of a sample inside its pixel, in [0, 1)^2: its sampler's first two dimensions.
inline void sample_position(Sampler& rng, float& fx, float& fy) {
  fx = rng.next();
  fy = rng.next();
}

inline bool sample_finite(const SampleResult& r) {
  float acc = 0;
  for (int k = 0; k < r.levels; ++k) {
    const LevelSample& l = r.level[k];
    acc += l.direct.x + l.direct.y + l.direct.z + l.indirect.x + l.indirect.y + l.indirect.z + l.reflection.x +
           l.reflection.y + l.reflection.z + l.emission.x + l.emission.y + l.emission.z + l.tint.x + l.tint.y +
           l.tint.z + l.depth;
  }
  return std::isfinite(acc) && is_finite(r.level[0].color());
}

// Runs f inside an arena of `threads` threads (0: TBB's default, all cores).
template <typename F>
void run_in_arena(int threads, F&& f) {
  if (threads > 0) {
    tbb::task_arena arena(threads);
    arena.execute(f);
  } else {
    f();
  }
}

// Runs f(tile_x0, tile_y0, tile_x1, tile_y1) over all tiles with `threads` threads (0: all).
template <typename F>
void for_each_tile(int width, int height, int threads, F&& f) {
  const int tx = (width + kTile - 1) / kTile, ty = (height + kTile - 1) / kTile;
  run_in_arena(threads, [&] {
    tbb::parallel_for(0, tx * ty, [&](int t) {
      set_ftz_daz();
      int x0 = (t % tx) * kTile, y0 = (t / tx) * kTile;
      f(x0, y0, std::min(width, x0 + kTile), std::min(height, y0 + kTile));
    });
  });
}

inline PathTracer::Options tracer_options(const RenderSettings& s) {
  PathTracer::Options o;
  o.max_depth = s.max_depth;
  o.reflection_levels = s.reflection_levels;
  return o;
}

inline Vec3 pixel_vec(const Image& img, int x, int y) {
  const float* p = img.pixel(x, y);
  return {p[0], p[1], p[2]};
}

// What tracing one sample needs: the scene's camera, the tracer, the image size and the seed.
struct SampleSource {
  const Scene& scene;
  const PathTracer& tracer;
  int width, height;
  std::uint64_t seed;

  // Traces the samples s = begin .. end - 1 of pixel (x, y) in order, calling f(s, r, fx, fy)
  // after each with its layers in r and its film position inside the pixel in fx, fy; their
  // sequence dimensions are made in `table` (math.h's SampleTable). Returns the rays traced.
  // (Tracing the camera rays of a pixel eight at a time as an Embree packet gave the same hits
  // bit for bit but no measurable speed-up: 2.82 M paths/s against 2.85 M on McGuire's box.)
  template <typename F>
  std::uint64_t trace_samples(SampleTable& table, int x, int y, int begin, int end, SampleResult& r, F&& f) const {
    std::uint64_t rays = 0;
    for_pixel_samples(table, seed, std::uint64_t(y) * width + x, std::uint64_t(begin), std::uint64_t(end),
                      [&](std::uint64_t s, Sampler rng) {
                        float fx, fy;
                        sample_position(rng, fx, fy);
                        PathContext ctx{rng};
                        const Camera& cam = scene.camera;
                        // Every layer of the sample sees the scene at its time (motion blur).
                        const float time =
                            cam.has_shutter() ? cam.time_at(rng.dimension_at(dims::kTime)) : cam.shutter_open;
                        const Ray ray =
                            cam.has_lens()
                                ? cam.generate_ray_at(x + fx, y + fy, width, height, rng.dimension_at(dims::kLensU),
                                                      rng.dimension_at(dims::kLensV), time)
                                : cam.generate_ray_at(x + fx, y + fy, width, height, 0, 0, time);
                        tracer.sample_layers(ray, ctx, r);
                        rays += ctx.rays;
                        f(int(s), r, fx, fy);
                      });
    return rays;
  }
};

// Level k's layers of a frame (k = 0: the pixel's own; k > 0: reflection level k).
struct LevelImages {
  Image *direct, *indirect, *albedo, *reflection, *emission, *normal, *depth, *tint;  // tint: k > 0
};

// The edge set G from level 0's finished normal and depth layers and each pixel's relative
// depth spread: edge = 1 for pixels of G, 0 elsewhere (render_edges.cpp).
void mark_edge_set(const LevelImages& l0, const Image& depth_spread, Image& edge, int threads);
// The sub-pixel data of every pixel of G: its samples traced again, averaged per 4x4 stratum.
EdgeSubpixels render_edge_subpixels(const SampleSource& src, int spp, const Image& edge, const LevelImages& l0,
                                    int threads);

}  // namespace dnb::render_pass
