// render_frame and render_color_sums: per-pixel sample loops over tiles (TBB), accumulation of
// the layers of tracer/integrator.h, the edge set G and its sub-pixel data (paper 3.1).
//
// Sampling: the samples of a pixel come in pairs (2j, 2j + 1) that share a stratum. The first
// 2 gx gy samples cover a gx x gy grid of strata, two each, jittered independently inside it
// (gx gy <= spp / 2, gx in gy .. 2 gy, chosen to leave as few samples over as possible: 16 x 8
// at 256 spp); the samples past them are uniform in the pixel, also taken in pairs, and with an
// odd spp the last one is alone. Every random number comes from Sampler(seed, pixel, s)
// (tracer/math.h), so a sample's value does not depend on threads, tiles or order, and samples
// of one pixel are summed in index order: frames are bit-identical for any thread count.
//
// Variance of a pixel's mean: stratified samples are not independent, so the sample variance
// of a pixel's samples / spp overstates the variance of its mean (by ~3x where the pixel holds
// an edge or texture that stratification averages out: issue 25, and the old estimator's
// figures in tests/tracer/variance_test.cpp). The two samples of a stratum are independent and
// alike, so half their squared difference estimates that stratum's variance without bias, and
// the variance of the mean is the sum of the pairs' squared differences / spp^2 (pixel_sums.h's
// PairMoments, spp / 2 degrees of freedom; a lone last sample is given the pairs' average).
// variance_test.cpp checks it against the seed-to-seed variance over 800 seeds. The cost of
// two samples per stratum instead of one: half as many strata, which raises only the
// film-position part of the noise (1.13x the variance at 256x192 and 64 spp on cornell-box;
// docs/references.md).
//
// Edge set G (paper 3.1), from the finished normal and depth layers: pixel p is in G when
//  - its own samples disagree: |mean normal| < kEdgeNormalLength (normals spread over > ~25
//    degrees, or hits mixed with misses) or the relative standard deviation of its depth
//    samples exceeds kEdgeDepthSpread; or
//  - a 4-neighbour q differs: the angle between their mean normals exceeds kEdgeNormalAngle,
//    one is a miss and the other not, or |depth_p - depth_q| > kEdgeDepthRel * min(depth_p,
//    depth_q) (both then belong to G).
// For pixels of G the samples are traced again (the same random numbers give the same paths)
// and averaged per 4x4 sub-pixel stratum: sub-pixel (i, j) holds the samples whose film position
// falls in [i/4, (i+1)/4) x [j/4, (j+1)/4) of the pixel. With spp = 256 each holds 16 samples.
// A sub-pixel that no sample falls in (spp < 16) gets the pixel's means.
//
// Pixel means of D and I are albedo-weighted ("demodulated"): per channel c,
//   D_c = sum_s D_c(s) T_c(s) / sum_s T_c(s)   (and likewise I), T_c = mean of T_c(s),
// so that (D + I) * T + R + E equals the mean of F exactly for every pixel, also where the
// albedo varies inside the pixel (texture detail, silhouettes): the product-of-means error of
// paper 3.1 never enters the layers. Where sum_s T_c(s) = 0 (mirrors, sky, black albedo) D_c and
// I_c are the plain means, which keeps the illumination of such pixels available to filters.
// For a pixel of constant albedo both definitions coincide. direct_variance and
// indirect_variance are the variances of these means (from the pairs' differences of D T and T: the
// ratio estimator's first-order variance). Edge sub-pixels use the same definition of the means
// over their stratum's samples.
#include <atomic>
#include <cmath>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include "core/bounds.h"
#include "core/errors.h"
#include "core/timer.h"
#include "core/version.h"
#include "tracer/integrator.h"
#include "tracer/pixel_sums.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"

namespace dnb {
using namespace rt;

namespace {

constexpr float kEdgeNormalLength = 0.95f;  // |mean of unit normals| below: normals disagree inside
constexpr float kEdgeNormalAngle = 25.0f;   // degrees between neighbours' normals
constexpr float kEdgeDepthRel = 0.05f;      // relative depth jump between neighbours
constexpr float kEdgeDepthSpread = 0.02f;   // relative std. deviation of depth inside a pixel
constexpr int kTile = 16;

// Embree and the integrator want denormals flushed (speed); set on every rendering task, so
// every thread computes the same bits.
void set_ftz_daz() { enable_flush_to_zero(); }

void check_settings(const RenderSettings& s) {
  Image::check_size(s.width, s.height, 3, "render size");
  check_bound(s.spp, bounds::kSpp, "render: spp");
  check_bound(s.max_depth, bounds::kMaxDepth, "render: max depth");
  if (s.reflection_levels < 0 || s.reflection_levels > kMaxReflectionLevels)
    throw InputError(fmt::format("reflection levels must be in 0..{} (got {})", kMaxReflectionLevels,
                                 s.reflection_levels));
  check_bound(s.threads, bounds::kThreads, "render: threads");
}

// How the samples of a pixel are stratified (see top of file).
struct SampleLayout {
  int spp = 1;
  int gx = 1, gy = 1;  // strata, two samples each
  SampleLayout() = default;
  explicit SampleLayout(int spp_) : spp(spp_) {
    const int m = std::max(1, spp / 2);
    int best = 0;
    for (int y = std::max(1, int(std::floor(std::sqrt(double(m))))); y >= 1; --y) {
      const int x = std::min(m / y, 2 * y);
      if (x < y) continue;
      if (x * y > best) best = x * y, gx = x, gy = y;
      if (2 * y * y < m) break;  // narrower cells than 2:1 are not worth a few more strata
    }
  }
  int stratified() const { return spp >= 2 ? 2 * gx * gy : 0; }  // samples in the strata
};

// Film position of sample s inside its pixel, in [0, 1)^2 (see top of file).
inline void sample_position(int s, const SampleLayout& layout, Sampler& rng, float& fx, float& fy) {
  float u = rng.next(), v = rng.next();
  if (s < layout.stratified()) {
    const int h = s / 2;
    fx = (float(h % layout.gx) + u) / float(layout.gx);
    fy = (float(h / layout.gx) + v) / float(layout.gy);
  } else {
    fx = u;
    fy = v;
  }
  fx = std::min(fx, 0x1.fffffep-1f);
  fy = std::min(fy, 0x1.fffffep-1f);
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

PathTracer::Options tracer_options(const RenderSettings& s) {
  PathTracer::Options o;
  o.max_depth = s.max_depth;
  o.reflection_levels = s.reflection_levels;
  return o;
}

Vec3 pixel_vec(const Image& img, int x, int y) {
  const float* p = img.pixel(x, y);
  return {p[0], p[1], p[2]};
}

// What tracing one sample needs: the scene's camera, the tracer, the image size, the seed and
// the stratification of the render (see top of file).
struct SampleSource {
  const Scene& scene;
  const PathTracer& tracer;
  int width, height;
  std::uint64_t seed;
  SampleLayout layout;

  // Traces sample s of pixel (x, y) into r; its film position inside the pixel goes to fx, fy.
  // Returns the rays traced.
  std::uint64_t trace(int x, int y, int s, SampleResult& r, float& fx, float& fy) const {
    Sampler rng(seed, std::uint64_t(y) * width + x, std::uint64_t(s));
    sample_position(s, layout, rng, fx, fy);
    PathContext ctx{rng};
    tracer.sample_layers(scene.camera.generate_ray(x + fx, y + fy, width, height), ctx, r);
    return ctx.rays;
  }
};

// ---- The frame's layers ----

struct LevelImages {
  Image *direct, *indirect, *albedo, *reflection, *emission, *normal, *depth, *tint;  // tint: k > 0
};

// One half buffer's layers (core/aov_frame.h's layer::kHalfLayers).
struct HalfImages {
  Image *color, *direct, *indirect, *albedo, *normal, *depth;
};

// The layers the main pass writes, looked up once.
struct FrameLayers {
  Image *color, *var_f, *var_d, *var_i, *samples, *edge;
  std::vector<LevelImages> level;  // 0 .. K
  HalfImages half[2];              // the even and the odd samples' level 0
};

// Every layer of a frame with K reflection levels, zero-filled in parallel (a 1024x768 frame
// with two reflection levels holds ~260 MB: filling it on one thread costs as much as a sample
// per pixel).
AovFrame allocate_frame(int W, int H, int K, int threads) {
  AovFrame frame(W, H);
  std::vector<std::pair<std::string, int>> names = {{layer::kColor, 3},          {layer::kVariance, 3},
                                                    {layer::kDirectVariance, 3}, {layer::kIndirectVariance, 3},
                                                    {layer::kSamples, 1},        {layer::kEdge, 1}};
  for (int k = 0; k <= K; ++k) {
    for (const char* b : {layer::kDirect, layer::kIndirect, layer::kAlbedo, layer::kReflection, layer::kEmission,
                          layer::kNormal})
      names.emplace_back(layer::at_level(k, b), 3);
    names.emplace_back(layer::at_level(k, layer::kDepth), 1);
    if (k > 0) names.emplace_back(layer::at_level(k, layer::kTint), 3);
  }
  for (int h = 0; h < 2; ++h)
    for (const char* b : layer::kHalfLayers) names.emplace_back(layer::at_half(h, b), default_channels(b));
  std::vector<Image> images(names.size());
  run_in_arena(threads, [&] {
    tbb::parallel_for(std::size_t(0), names.size(), [&](std::size_t i) { images[i] = Image(W, H, names[i].second); });
  });
  for (std::size_t i = 0; i < names.size(); ++i) frame.set(names[i].first, std::move(images[i]));
  return frame;
}

FrameLayers layers_of(AovFrame& frame, int K) {
  FrameLayers out;
  out.color = &frame.layer(layer::kColor);
  out.var_f = &frame.layer(layer::kVariance);
  out.var_d = &frame.layer(layer::kDirectVariance);
  out.var_i = &frame.layer(layer::kIndirectVariance);
  out.samples = &frame.layer(layer::kSamples);
  out.edge = &frame.layer(layer::kEdge);
  out.level.resize(K + 1);
  for (int k = 0; k <= K; ++k) {
    LevelImages& l = out.level[k];
    l.direct = &frame.layer(layer::at_level(k, layer::kDirect));
    l.indirect = &frame.layer(layer::at_level(k, layer::kIndirect));
    l.albedo = &frame.layer(layer::at_level(k, layer::kAlbedo));
    l.reflection = &frame.layer(layer::at_level(k, layer::kReflection));
    l.emission = &frame.layer(layer::at_level(k, layer::kEmission));
    l.normal = &frame.layer(layer::at_level(k, layer::kNormal));
    l.depth = &frame.layer(layer::at_level(k, layer::kDepth));
    l.tint = k > 0 ? &frame.layer(layer::at_level(k, layer::kTint)) : nullptr;
  }
  for (int h = 0; h < 2; ++h) {
    HalfImages& l = out.half[h];
    l.color = &frame.layer(layer::at_half(h, layer::kColor));
    l.direct = &frame.layer(layer::at_half(h, layer::kDirect));
    l.indirect = &frame.layer(layer::at_half(h, layer::kIndirect));
    l.albedo = &frame.layer(layer::at_half(h, layer::kAlbedo));
    l.normal = &frame.layer(layer::at_half(h, layer::kNormal));
    l.depth = &frame.layer(layer::at_half(h, layer::kDepth));
  }
  return out;
}

// ---- Main pass: per-pixel sums, then the pixel's layers ----

// The sums of one half buffer: level 0's layers and the colour over the even or the odd samples.
struct HalfSums {
  LevelSums level;
  alignas(32) double extra[acc::kExtraSize] = {};
};

// Adds one finite sample to its pixel's sums: levels 0 .. min(r.levels, K + 1) - 1, and the
// level-0 colour (`extra`, acc::kExtraSize values); level 0 and the colour also to its half's
// sums. The full sums stay their own sequence of additions (not half0 + half1), so the layers
// are bit for bit what they were before the half buffers.
inline void accumulate_sample(const SampleResult& r, int K, LevelSums* sums, double* extra, HalfSums& half) {
  alignas(32) float vals[acc::kLevelSize];
  const Vec3 f = r.level[0].color();
  alignas(32) double xvals[acc::kExtraSize] = {f.x, f.y, f.z, 0.0};
  add_values<acc::kExtraSize>(extra, xvals);
  add_values<acc::kExtraSize>(half.extra, xvals);
  for (int k = 0; k < r.levels && k <= K; ++k) {
    pack_level(r.level[k], vals);
    ++sums[k].n;
    add_values<acc::kLevelSize>(sums[k].v, vals);
    if (k == 0) {
      ++half.level.n;
      add_values<acc::kLevelSize>(half.level.v, vals);
    }
  }
}

// A half buffer's layers of pixel (x, y): the level-0 means over its samples, D and I
// albedo-weighted as in the full layers (all zero for a half without a finite sample: spp 1).
void store_half(const HalfImages& l, int x, int y, const HalfSums& h) {
  const LevelSums& L = h.level;
  const double li = L.n > 0 ? 1.0 / L.n : 0.0;
  store(*l.color, x, y, h.extra + acc::kColor, li);
  demodulated(L.at(acc::kDirectT), L.at(acc::kDirect), L.at(acc::kAlbedo), L.n, l.direct->pixel(x, y));
  demodulated(L.at(acc::kIndirectT), L.at(acc::kIndirect), L.at(acc::kAlbedo), L.n, l.indirect->pixel(x, y));
  store(*l.albedo, x, y, L.at(acc::kAlbedo), li);
  store(*l.normal, x, y, L.at(acc::kNormal), li);
  l.depth->at(x, y, 0) = float(L.v[acc::kDepth] * li);
}

// Level k's layers of pixel (x, y) from its sums; `prev`: level k - 1's sums (k > 0), whose
// bounce weights into level k make refl(k).tint.
void store_level(const LevelImages& l, int x, int y, const LevelSums& L, const LevelSums* prev) {
  const double li = L.n > 0 ? 1.0 / L.n : 0.0;
  demodulated(L.at(acc::kDirectT), L.at(acc::kDirect), L.at(acc::kAlbedo), L.n, l.direct->pixel(x, y));
  demodulated(L.at(acc::kIndirectT), L.at(acc::kIndirect), L.at(acc::kAlbedo), L.n, l.indirect->pixel(x, y));
  store(*l.albedo, x, y, L.at(acc::kAlbedo), li);
  store(*l.reflection, x, y, L.at(acc::kReflection), li);
  store(*l.emission, x, y, L.at(acc::kEmission), li);
  store(*l.normal, x, y, L.at(acc::kNormal), li);
  l.depth->at(x, y, 0) = float(L.v[acc::kDepth] * li);
  // refl(k).tint: mean over the samples of level k-1 of the bounce weight into level k.
  if (prev) store(*l.tint, x, y, prev->at(acc::kTint), prev->n > 0 ? 1.0 / prev->n : 0.0);
}

// The pair moments of a pixel's level-0 means (pixel_sums.h): each sample's values are kept
// until its partner arrives; a pair with a dropped (non-finite) sample leaves the other alone.
struct PixelPairs {
  PairMoments color, direct, indirect;  // weights: 1 for the colour, the albedo T for D T and I T
  PairMoments direct_plain, indirect_plain;  // D and I where the albedo sums to 0 (weight 1)
  LevelSample first;
  bool have_first = false;

  // Sample s, finite or not (finite: its level 0 is `l0`).
  void add(int s, bool finite, const LevelSample& l0) {
    if (s % 2 == 0) {
      if (have_first) single();
      have_first = finite;
      if (finite) first = l0;
      return;
    }
    if (!finite || !have_first) {
      if (have_first) single();
      if (finite) single();
      have_first = false;
      return;
    }
    const Vec3 df = first.color() - l0.color(), dt = first.albedo - l0.albedo;
    const Vec3 ddt = first.direct * first.albedo - l0.direct * l0.albedo;
    const Vec3 dit = first.indirect * first.albedo - l0.indirect * l0.albedo;
    const Vec3 zero{0, 0, 0};
    color.add_pair(df, zero);
    direct.add_pair(ddt, dt);
    indirect.add_pair(dit, dt);
    direct_plain.add_pair(first.direct - l0.direct, zero);
    indirect_plain.add_pair(first.indirect - l0.indirect, zero);
    have_first = false;
  }
  void finish() {
    if (have_first) single();
    have_first = false;
  }
  void single() {
    for (PairMoments* m : {&color, &direct, &indirect, &direct_plain, &indirect_plain}) ++m->singles;
  }
};

// The variance of an illumination layer's mean: albedo-weighted where its mean is (demodulated()'s
// test), plain otherwise.
void store_demodulated_var(const PairMoments& weighted, const PairMoments& plain, const double* sum_t,
                           const double* sum, const double* albedo, std::int64_t n, float* out) {
  for (int c = 0; c < 3; ++c)
    out[c] = albedo[c] > 1e-12 * double(n) ? weighted.variance(c, sum_t[c], albedo[c])
                                           : plain.variance(c, sum[c], double(n));
}

// Every layer of pixel (x, y) from its sums, and the relative depth spread of its samples.
void store_pixel(const FrameLayers& out, int x, int y, const std::vector<LevelSums>& sums, const double* extra,
                 const PixelPairs& pairs, Image& depth_spread) {
  const std::int64_t n = sums[0].n;
  const double inv = n > 0 ? 1.0 / n : 0.0;
  const LevelSums& L0 = sums[0];
  store(*out.color, x, y, extra + acc::kColor, inv);
  float* vf = out.var_f->pixel(x, y);
  for (int c = 0; c < 3; ++c) vf[c] = pairs.color.variance(c, extra[acc::kColor + c], double(n));
  store_demodulated_var(pairs.direct, pairs.direct_plain, L0.at(acc::kDirectT), L0.at(acc::kDirect), L0.at(acc::kAlbedo),
                        n, out.var_d->pixel(x, y));
  store_demodulated_var(pairs.indirect, pairs.indirect_plain, L0.at(acc::kIndirectT), L0.at(acc::kIndirect),
                        L0.at(acc::kAlbedo), n, out.var_i->pixel(x, y));
  out.samples->at(x, y, 0) = float(n);
  for (std::size_t k = 0; k < sums.size(); ++k)
    store_level(out.level[k], x, y, sums[k], k > 0 ? &sums[k - 1] : nullptr);
  if (n > 1) {
    double m = L0.v[acc::kDepth] * inv;
    double var = std::max(0.0, L0.v[acc::kDepthSq] * inv - m * m);
    depth_spread.at(x, y, 0) = m > 0 ? float(std::sqrt(var) / m) : 0.0f;
  }
}

struct PassCounts {
  std::int64_t dropped = 0;  // non-finite samples
  std::uint64_t rays = 0;
};

// The main pass over the tile [x0, x1) x [y0, y1): every sample of every pixel, then its layers.
void render_tile(const SampleSource& src, int spp, const FrameLayers& out, Image& depth_spread, int x0, int y0,
                 int x1, int y1, PassCounts& counts) {
  SampleResult r;
  const int K = int(out.level.size()) - 1;
  std::vector<LevelSums> sums(K + 1);
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      for (auto& s : sums) s = LevelSums{};
      alignas(32) double extra[acc::kExtraSize] = {};
      HalfSums half[2];
      PixelPairs pairs;
      for (int s = 0; s < spp; ++s) {
        float fx, fy;
        counts.rays += src.trace(x, y, s, r, fx, fy);
        const bool finite = sample_finite(r);
        if (finite) accumulate_sample(r, K, sums.data(), extra, half[s & 1]);
        else ++counts.dropped;
        pairs.add(s, finite, r.level[0]);
      }
      pairs.finish();
      store_pixel(out, x, y, sums, extra, pairs, depth_spread);
      for (int h = 0; h < 2; ++h) store_half(out.half[h], x, y, half[h]);
    }
}

// Says how many variance values were clamped to float's range (pixel_sums.h's
// variance_to_float): legal but extreme emitters only, so once per frame, not per pixel.
void warn_clamped_variance(const AovFrame& frame) {
  std::size_t clamped = 0;
  for (const char* name : {layer::kVariance, layer::kDirectVariance, layer::kIndirectVariance}) {
    const Image& v = frame.layer(name);
    for (std::size_t k = 0; k < v.size(); ++k) clamped += v.data()[k] == std::numeric_limits<float>::max();
  }
  if (clamped > 0)
    spdlog::warn("{} variance values exceed float's range (an emitter near 1e30?) and were clamped to {:g}", clamped,
                 std::numeric_limits<float>::max());
}

// ---- Edge set G (see top of file) ----

void mark_edge_set(const LevelImages& l0, const Image& depth_spread, Image& edge, int threads) {
  const Image& normal = *l0.normal;
  const Image& depth = *l0.depth;
  const int W = edge.width(), H = edge.height();
  const float cos_edge = std::cos(kEdgeNormalAngle * kPi / 180);
  auto differ = [&](int xa, int ya, int xb, int yb) {
    Vec3 na = pixel_vec(normal, xa, ya), nb = pixel_vec(normal, xb, yb);
    float la = length(na), lb = length(nb);
    if ((la < 1e-3f) != (lb < 1e-3f)) return true;
    if (la >= 1e-3f && dot(na, nb) < cos_edge * la * lb) return true;
    float da = depth.at(xa, ya, 0), db = depth.at(xb, yb, 0);
    return std::fabs(da - db) > kEdgeDepthRel * std::min(da, db);
  };
  // Each pixel tests itself and its four neighbours (so rows can run in parallel).
  run_in_arena(threads, [&] {
    tbb::parallel_for(0, H, [&](int y) {
      for (int x = 0; x < W; ++x) {
        Vec3 n = pixel_vec(normal, x, y);
        float ln = length(n);
        bool in_g = (ln > 1e-3f && ln < kEdgeNormalLength) || depth_spread.at(x, y, 0) > kEdgeDepthSpread ||
                    (x + 1 < W && differ(x, y, x + 1, y)) || (x > 0 && differ(x, y, x - 1, y)) ||
                    (y + 1 < H && differ(x, y, x, y + 1)) || (y > 0 && differ(x, y, x, y - 1));
        edge.at(x, y, 0) = in_g ? 1.0f : 0.0f;
      }
    });
  });
}

// ---- Edge sub-pixels: G's samples traced again, averaged per 4x4 stratum ----

struct SubpixelSums {
  int n = 0;
  D3 normal, albedo, direct, indirect, direct_t, indirect_t;
  double depth = 0;
};

void trace_subpixels(const SampleSource& src, int spp, int x, int y, SampleResult& r,
                     SubpixelSums (&sub)[EdgeSubpixels::kPerPixel]) {
  constexpr int side = EdgeSubpixels::kPerSide;
  for (int s = 0; s < spp; ++s) {
    float fx, fy;
    src.trace(x, y, s, r, fx, fy);
    if (!sample_finite(r)) continue;
    SubpixelSums& b = sub[int(fy * side) * side + int(fx * side)];
    const LevelSample& l0 = r.level[0];
    ++b.n;
    b.normal.add(l0.normal);
    b.albedo.add(l0.albedo);
    b.direct.add(l0.direct);
    b.indirect.add(l0.indirect);
    b.direct_t.add(l0.direct * l0.albedo);
    b.indirect_t.add(l0.indirect * l0.albedo);
    b.depth += l0.depth;
  }
}

// The sub-pixels' means; one that no sample fell in gets the pixel's means from level 0's layers.
void store_subpixels(const SubpixelSums (&sub)[EdgeSubpixels::kPerPixel], const LevelImages& l0, int x, int y,
                     EdgeSample* out) {
  for (int k = 0; k < EdgeSubpixels::kPerPixel; ++k) {
    EdgeSample& e = out[k];
    if (sub[k].n == 0) {
      for (int c = 0; c < 3; ++c) {
        e.normal[c] = l0.normal->at(x, y, c);
        e.albedo[c] = l0.albedo->at(x, y, c);
        e.direct[c] = l0.direct->at(x, y, c);
        e.indirect[c] = l0.indirect->at(x, y, c);
      }
      e.depth = l0.depth->at(x, y, 0);
      continue;
    }
    const double inv = 1.0 / sub[k].n;
    for (int c = 0; c < 3; ++c) {
      e.normal[c] = float(sub[k].normal.v[c] * inv);
      e.albedo[c] = float(sub[k].albedo.v[c] * inv);
    }
    e.depth = float(sub[k].depth * inv);
    demodulated(sub[k].direct_t.v, sub[k].direct.v, sub[k].albedo.v, sub[k].n, e.direct);
    demodulated(sub[k].indirect_t.v, sub[k].indirect.v, sub[k].albedo.v, sub[k].n, e.indirect);
  }
}

// The sub-pixel data of every pixel of G, in parallel over chunks of edge pixels.
EdgeSubpixels render_edge_subpixels(const SampleSource& src, int spp, const Image& edge, const LevelImages& l0,
                                    int threads) {
  const int W = edge.width(), H = edge.height();
  EdgeSubpixels es;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      if (edge.at(x, y, 0) > 0) es.pixels.push_back(std::int32_t(y * W + x));
  es.samples.resize(es.pixels.size() * EdgeSubpixels::kPerPixel);
  const std::size_t chunk = 64;
  const std::size_t chunks = (es.pixels.size() + chunk - 1) / chunk;
  run_in_arena(threads, [&] {
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
      set_ftz_daz();
      SampleResult r;
      for (std::size_t i = c * chunk; i < std::min(es.pixels.size(), (c + 1) * chunk); ++i) {
        const int x = es.pixels[i] % W, y = es.pixels[i] / W;
        SubpixelSums sub[EdgeSubpixels::kPerPixel];
        trace_subpixels(src, spp, x, y, r, sub);
        store_subpixels(sub, l0, x, y, &es.samples[i * EdgeSubpixels::kPerPixel]);
      }
    });
  });
  return es;
}

void write_meta(FrameMeta& meta, const Scene& scene, const RenderSettings& settings, const PassCounts& counts) {
  meta.scene = scene_name(scene);
  meta.spp = settings.spp;
  meta.seed = settings.seed;
  meta.tracer_version = kTracerVersion;
  meta.build_version = std::string(DNB_VERSION) + " (" + DNB_GIT_REVISION + ")";
  meta.dropped_samples = counts.dropped;
  meta.reflection_levels = settings.reflection_levels;
  meta.extra["max_depth"] = std::to_string(settings.max_depth);
  meta.extra["scene_hash"] = scene_content_hash(scene);
  // Rays of the main pass (closest-hit and shadow rays; the edge pass re-traces G's samples).
  meta.extra["rays"] = std::to_string(counts.rays);
}

}  // namespace

AovFrame render_frame(const Scene& scene, const RenderSettings& settings) {
  check_settings(settings);
  Stopwatch clock;
  const int W = settings.width, H = settings.height, K = settings.reflection_levels;
  PathTracer tracer(scene, tracer_options(settings));
  const SampleSource src{scene, tracer, W, H, settings.seed, SampleLayout(settings.spp)};

  AovFrame frame = allocate_frame(W, H, K, settings.threads);
  const FrameLayers out = layers_of(frame, K);
  // Relative depth spread inside each pixel, for the edge test (kept only until G is known).
  Image depth_spread(W, H, 1);
  std::atomic<std::int64_t> dropped{0};
  std::atomic<std::uint64_t> rays{0};
  for_each_tile(W, H, settings.threads, [&](int x0, int y0, int x1, int y1) {
    PassCounts tile;
    render_tile(src, settings.spp, out, depth_spread, x0, y0, x1, y1, tile);
    dropped += tile.dropped;
    rays += tile.rays;
    if (settings.on_progress) settings.on_progress(std::int64_t(x1 - x0) * (y1 - y0) * settings.spp);
  });

  warn_clamped_variance(frame);
  mark_edge_set(out.level[0], depth_spread, *out.edge, settings.threads);
  depth_spread = Image();
  if (settings.edge_subpixels)
    frame.edges = render_edge_subpixels(src, settings.spp, *out.edge, out.level[0], settings.threads);

  write_meta(frame.meta, scene, settings, PassCounts{dropped.load(), rays.load()});
  frame.meta.render_seconds = clock.seconds();
  return frame;
}

ColorSums render_color_sums(const Scene& scene, const RenderSettings& settings, int sample_begin, int sample_end) {
  check_settings(settings);
  if (sample_begin < 0 || sample_end > settings.spp || sample_begin > sample_end)
    throw InputError(fmt::format("sample range [{}, {}) is not inside [0, {})", sample_begin, sample_end,
                                 settings.spp));
  const int W = settings.width, H = settings.height;
  PathTracer tracer(scene, tracer_options(settings));
  const SampleSource src{scene, tracer, W, H, settings.seed, SampleLayout(settings.spp)};
  ColorSums out;
  out.width = W;
  out.height = H;
  out.samples = sample_end - sample_begin;
  // Pair (2j, 2j + 1) is counted by the range that holds 2j + 1 (which traces 2j again when the
  // range starts there); with an odd spp the last sample is alone.
  out.pairs = sample_end / 2 - (sample_begin + 1) / 2;
  out.singles = (sample_end == settings.spp && settings.spp % 2 == 1) ? 1 : 0;
  out.sum.assign(std::size_t(W) * H * 3, 0.0);
  out.pair_sq.assign(std::size_t(W) * H * 3, 0.0);
  std::atomic<std::int64_t> dropped{0};
  for_each_tile(W, H, settings.threads, [&](int x0, int y0, int x1, int y1) {
    SampleResult r;
    std::int64_t tile_dropped = 0;
    // A sample's colour, 0 when dropped (as mean() counts it: the attempted samples divide).
    auto color_of = [&](int x, int y, int s, bool count) {
      float fx, fy;
      src.trace(x, y, s, r, fx, fy);
      if (sample_finite(r)) return r.level[0].color();
      if (count) ++tile_dropped;
      return Vec3{0, 0, 0};
    };
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        const std::uint64_t pixel = std::uint64_t(y) * W + x;
        double* s1 = &out.sum[pixel * 3];
        double* s2 = &out.pair_sq[pixel * 3];
        Vec3 first{0, 0, 0};
        if (sample_begin % 2 == 1) first = color_of(x, y, sample_begin - 1, false);
        for (int s = sample_begin; s < sample_end; ++s) {
          const Vec3 f = color_of(x, y, s, true);
          for (int c = 0; c < 3; ++c) s1[c] += f[c];
          if (s % 2 == 0) {
            first = f;
          } else {
            for (int c = 0; c < 3; ++c) {
              const double d = double(first[c]) - f[c];
              s2[c] += d * d;
            }
          }
        }
      }
    dropped += tile_dropped;
    if (settings.on_progress) settings.on_progress(std::int64_t(x1 - x0) * (y1 - y0) * (sample_end - sample_begin));
  });
  out.dropped = dropped.load();
  return out;
}

void ColorSums::add(const ColorSums& o) {
  if (sum.empty()) {
    *this = o;
    return;
  }
  if (o.width != width || o.height != height)
    throw WorkError(fmt::format("cannot add colour sums of {}x{} to {}x{}", o.width, o.height, width, height));
  samples += o.samples;
  pairs += o.pairs;
  singles += o.singles;
  dropped += o.dropped;
  for (std::size_t i = 0; i < sum.size(); ++i) {
    sum[i] += o.sum[i];
    pair_sq[i] += o.pair_sq[i];
  }
}

Image ColorSums::mean() const {
  // `samples` counts per-pixel samples attempted; dropped samples (rare) are spread over the
  // image, so dividing by the attempted count biases by at most dropped / (pixels x samples).
  Image img(width, height, 3);
  const double inv = samples > 0 ? 1.0 / double(samples) : 0.0;
  for (std::size_t i = 0; i < sum.size(); ++i) img.data()[i] = float(sum[i] * inv);
  return img;
}

double ColorSums::variance_of_mean(std::size_t i) const {
  // PairMoments' formula (pixel_sums.h) with weight 1 per sample.
  if (pairs < 1 || samples < 2) return 0.0;
  const double n = double(samples);
  return pair_sq[i] * (1.0 + double(singles) / (2.0 * double(pairs))) / (n * n);
}

Image ColorSums::variance_of_mean() const {
  Image img(width, height, 3);
  for (std::size_t i = 0; i < sum.size(); ++i) img.data()[i] = variance_to_float(variance_of_mean(i));
  return img;
}

}  // namespace dnb
