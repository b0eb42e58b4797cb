// render_frame and render_color_sums: per-pixel sample loops over tiles (TBB), accumulation of
// the layers of tracer/integrator.h, the edge set G and its sub-pixel data (paper 3.1).
//
// Sampling: sample s of a pixel is point s / 8 of group s mod 8's own Owen-scrambled Sobol'
// sequence (rt::Sampler, tracer/math.h: eight groups, independently scrambled per pixel and
// group; every pair of dimensions its own scrambled (0,2)-sequence; the film position takes the
// first pair, each path vertex fixed slots after it; vertices past the second independent
// hashed numbers). A group's first 2^m points are a scrambled (0, m, 2)-net in every pair of
// those dimensions, so the film position and the first two vertices' light and BSDF samples are
// stratified at every power-of-two spp per group, and the samples of a pixel do
// not depend on the render's spp: the first N samples of any render are the N-spp render
// (nested; the progressive curve of the experiment takes every point of the plain path-tracing
// curve from one render). Every random number is a pure function of (seed, pixel, s, dimension),
// so a sample's value does not depend on threads, tiles or order, and a pixel's sums are made in
// sample order: frames are bit-identical for any thread count.
//
// Variance of a pixel's mean: stratified samples are not independent, so the sample variance
// of a pixel's samples / spp overstates the variance of its mean (by ~3x where the pixel holds
// an edge or texture that stratification averages out: issue 25, and the old estimator's
// figures in tests/tracer/variance_test.cpp). The eight groups are independent replicates of
// the same estimator, so the spread of their means gives the variance of the pixel's mean without
// bias (pixel_sums.h's group_ratio_variance; 7 degrees of freedom per pixel: a single pixel's
// value is noisy, +-53% (one standard deviation), its expectation exact). variance_test.cpp
// checks it against the seed-to-seed variance over many seeds. The half buffers half0.* and
// half1.* are the even and the odd groups: two independent half-sample estimates.
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
// indirect_variance are the variances of these means (from the groups' sums of D T and T: the
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
#include "core/build_info.h"
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
                        tracer.sample_layers(scene.camera.generate_ray(x + fx, y + fy, width, height), ctx, r);
                        rays += ctx.rays;
                        f(int(s), r, fx, fy);
                      });
    return rays;
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

constexpr int kGroups = Sampler::kGroups;
static_assert(kGroups == kSampleGroups, "render.h's group count is the sampler's");
static_assert(kGroups % 2 == 0, "the half buffers are the even and the odd groups");

// The sums of one sample group (rt::Sampler): level 0's layers and the colour. The pixel's
// level-0 sums, its half buffers and the variances of its means are all made from them.
struct GroupSums {
  LevelSums level;
  alignas(32) double extra[acc::kExtraSize] = {};
};

// Adds one finite sample to its pixel's sums: its group's level 0 and colour (`group`), and
// levels 1 .. min(r.levels, K + 1) - 1 to `sums` (level 0 is made from the groups at the end).
inline void accumulate_sample(const SampleResult& r, int K, LevelSums* sums, GroupSums& group) {
  alignas(32) float vals[acc::kLevelSize];
  const Vec3 f = r.level[0].color();
  alignas(32) double xvals[acc::kExtraSize] = {f.x, f.y, f.z, 0.0};
  add_values<acc::kExtraSize>(group.extra, xvals);
  for (int k = 0; k < r.levels && k <= K; ++k) {
    pack_level(r.level[k], vals);
    LevelSums& L = k == 0 ? group.level : sums[k];
    ++L.n;
    add_values<acc::kLevelSize>(L.v, vals);
  }
}

// The sums of the groups g = first, first + step, ... (in that order) into `out`.
inline void add_groups(const GroupSums* groups, int first, int step, GroupSums& out) {
  for (int g = first; g < kGroups; g += step) {
    out.level.n += groups[g].level.n;
    add_values<acc::kLevelSize>(out.level.v, groups[g].level.v);
    add_values<acc::kExtraSize>(out.extra, groups[g].extra);
  }
}

// A half buffer's layers of pixel (x, y): the level-0 means over its samples, D and I
// albedo-weighted as in the full layers (all zero for a half without a finite sample: spp 1).
void store_half(const HalfImages& l, int x, int y, const GroupSums& h) {
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

// The variances of a pixel's level-0 means from its groups' sums (pixel_sums.h).
struct GroupVariance {
  double a[kGroups], b[kGroups];
  std::int64_t n[kGroups];
  explicit GroupVariance(const GroupSums* groups) {
    for (int g = 0; g < kGroups; ++g) n[g] = groups[g].level.n;
  }
  // Of the mean sum a / sum b, with a = level value `ao` + c (acc::, or the colour when `colour`),
  // and b = level value `bo` + c, or the sample count when bo < 0.
  float of(const GroupSums* groups, bool colour, int ao, int bo, int c, double A, double B) {
    for (int g = 0; g < kGroups; ++g) {
      a[g] = colour ? groups[g].extra[acc::kColor + c] : groups[g].level.v[ao + c];
      b[g] = bo < 0 ? double(n[g]) : groups[g].level.v[bo + c];
    }
    return group_ratio_variance(a, b, n, A, B);
  }
};

// The variance of an illumination layer's mean (acc:: offsets of D T and of D): albedo-weighted
// where its mean is (demodulated()'s test), plain otherwise.
void store_demodulated_var(GroupVariance& gv, const GroupSums* groups, int weighted, int plain, const LevelSums& L0,
                           float* out) {
  const double* albedo = L0.at(acc::kAlbedo);
  for (int c = 0; c < 3; ++c)
    out[c] = albedo[c] > 1e-12 * double(L0.n)
                 ? gv.of(groups, false, weighted, acc::kAlbedo, c, L0.v[weighted + c], albedo[c])
                 : gv.of(groups, false, plain, -1, c, L0.v[plain + c], double(L0.n));
}

// Every layer of pixel (x, y) from its sums (level 0's and the colour's made from the groups
// here), and the relative depth spread of its samples.
void store_pixel(const FrameLayers& out, int x, int y, std::vector<LevelSums>& sums, const GroupSums* groups,
                 Image& depth_spread) {
  GroupSums all;
  add_groups(groups, 0, 1, all);
  sums[0] = all.level;
  const double* extra = all.extra;
  const std::int64_t n = sums[0].n;
  const double inv = n > 0 ? 1.0 / n : 0.0;
  const LevelSums& L0 = sums[0];
  store(*out.color, x, y, extra + acc::kColor, inv);
  GroupVariance gv(groups);
  float* vf = out.var_f->pixel(x, y);
  for (int c = 0; c < 3; ++c) vf[c] = gv.of(groups, true, 0, -1, c, extra[acc::kColor + c], double(n));
  store_demodulated_var(gv, groups, acc::kDirectT, acc::kDirect, L0, out.var_d->pixel(x, y));
  store_demodulated_var(gv, groups, acc::kIndirectT, acc::kIndirect, L0, out.var_i->pixel(x, y));
  out.samples->at(x, y, 0) = float(n);
  for (std::size_t k = 0; k < sums.size(); ++k)
    store_level(out.level[k], x, y, sums[k], k > 0 ? &sums[k - 1] : nullptr);
  if (n > 1) {
    double m = L0.v[acc::kDepth] * inv;
    double var = std::max(0.0, L0.v[acc::kDepthSq] * inv - m * m);
    depth_spread.at(x, y, 0) = m > 0 ? float(std::sqrt(var) / m) : 0.0f;
  }
  for (int h = 0; h < 2; ++h) {
    GroupSums half;
    add_groups(groups, h, 2, half);
    store_half(out.half[h], x, y, half);
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
  SampleTable table;
  const int K = int(out.level.size()) - 1;
  std::vector<LevelSums> sums(K + 1);
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      for (auto& s : sums) s = LevelSums{};
      GroupSums groups[kGroups];
      counts.rays += src.trace_samples(table, x, y, 0, spp, r, [&](int s, const SampleResult& sr, float, float) {
        if (sample_finite(sr)) accumulate_sample(sr, K, sums.data(), groups[s % kGroups]);
        else ++counts.dropped;
      });
      store_pixel(out, x, y, sums, groups, depth_spread);
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

void trace_subpixels(const SampleSource& src, int spp, int x, int y, SampleTable& table, SampleResult& r,
                     SubpixelSums (&sub)[EdgeSubpixels::kPerPixel]) {
  constexpr int side = EdgeSubpixels::kPerSide;
  src.trace_samples(table, x, y, 0, spp, r, [&](int, const SampleResult& sr, float fx, float fy) {
    if (!sample_finite(sr)) return;
    SubpixelSums& b = sub[int(fy * side) * side + int(fx * side)];
    const LevelSample& l0 = sr.level[0];
    ++b.n;
    b.normal.add(l0.normal);
    b.albedo.add(l0.albedo);
    b.direct.add(l0.direct);
    b.indirect.add(l0.indirect);
    b.direct_t.add(l0.direct * l0.albedo);
    b.indirect_t.add(l0.indirect * l0.albedo);
    b.depth += l0.depth;
  });
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
      SampleTable table;
      for (std::size_t i = c * chunk; i < std::min(es.pixels.size(), (c + 1) * chunk); ++i) {
        const int x = es.pixels[i] % W, y = es.pixels[i] / W;
        SubpixelSums sub[EdgeSubpixels::kPerPixel];
        trace_subpixels(src, spp, x, y, table, r, sub);
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
  meta.build_version = build_version_and_revision();
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
  const SampleSource src{scene, tracer, W, H, settings.seed};

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
  const SampleSource src{scene, tracer, W, H, settings.seed};
  ColorSums out;
  out.width = W;
  out.height = H;
  out.samples = sample_end - sample_begin;
  for (int s = sample_begin; s < sample_end; ++s) ++out.group_samples[s % kGroups];
  out.sum.assign(std::size_t(W) * H * 3, 0.0);
  out.group_sum.assign(std::size_t(W) * H * 3 * kGroups, 0.0);
  std::atomic<std::int64_t> dropped{0};
  for_each_tile(W, H, settings.threads, [&](int x0, int y0, int x1, int y1) {
    SampleResult r;
    SampleTable table;
    std::int64_t tile_dropped = 0;
    for (int y = y0; y < y1; ++y)
      for (int x = x0; x < x1; ++x) {
        const std::uint64_t pixel = std::uint64_t(y) * W + x;
        double* s1 = &out.sum[pixel * 3];
        double* sg = &out.group_sum[pixel * 3 * kGroups];
        src.trace_samples(table, x, y, sample_begin, sample_end, r, [&](int s, const SampleResult& sr, float, float) {
          // A dropped sample counts as 0 (mean() divides by the attempted samples).
          Vec3 f{0, 0, 0};
          if (sample_finite(sr)) f = sr.level[0].color();
          else ++tile_dropped;
          double* g = sg + 3 * (s % kGroups);
          for (int c = 0; c < 3; ++c) {
            s1[c] += f[c];
            g[c] += f[c];
          }
        });
      }
    dropped += tile_dropped;
    if (settings.on_progress) settings.on_progress(std::int64_t(x1 - x0) * (y1 - y0) * (sample_end - sample_begin));
  });
  out.dropped = dropped.load();
  return out;
}

void render_color_prefixes(const Scene& scene, const RenderSettings& settings, const std::vector<int>& prefixes,
                           const std::function<void(std::size_t, Image, double)>& on_prefix) {
  check_settings(settings);
  for (std::size_t k = 0; k < prefixes.size(); ++k)
    if (prefixes[k] < 1 || (k > 0 && prefixes[k] <= prefixes[k - 1]) || prefixes[k] > settings.spp)
      throw InputError(fmt::format("render prefixes must rise from 1 to at most the spp ({}); got {} at position {}",
                                   settings.spp, prefixes[k], k + 1));
  Stopwatch clock;
  const int W = settings.width, H = settings.height;
  PathTracer tracer(scene, tracer_options(settings));
  const SampleSource src{scene, tracer, W, H, settings.seed};
  // Per pixel and group: the colour's sums and the finite samples, as render_tile keeps them
  // (GroupSums' colour and level-0 count), so that a prefix's image is made by the same
  // additions in the same order as render_frame's colour layer.
  struct GroupColor {
    double c[3] = {0, 0, 0};
    std::int64_t n = 0;
  };
  std::vector<GroupColor> groups(std::size_t(W) * H * kGroups);
  int done = 0;
  for (std::size_t k = 0; k < prefixes.size(); ++k) {
    const int begin = done, end = prefixes[k];
    Image color(W, H, 3);
    for_each_tile(W, H, settings.threads, [&](int x0, int y0, int x1, int y1) {
      SampleResult r;
      SampleTable table;
      for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x) {
          GroupColor* g = &groups[(std::size_t(y) * W + x) * kGroups];
          src.trace_samples(table, x, y, begin, end, r, [&](int s, const SampleResult& sr, float, float) {
            if (!sample_finite(sr)) return;
            const Vec3 f = sr.level[0].color();
            GroupColor& gs = g[s % kGroups];
            for (int c = 0; c < 3; ++c) gs.c[c] += double(f[c]);
            ++gs.n;
          });
          // add_groups' order: the groups' sums added to 0 in group order.
          double sum[3] = {0, 0, 0};
          std::int64_t n = 0;
          for (int j = 0; j < kGroups; ++j) {
            n += g[j].n;
            for (int c = 0; c < 3; ++c) sum[c] += g[j].c[c];
          }
          store(color, x, y, sum, n > 0 ? 1.0 / n : 0.0);
        }
      if (settings.on_progress) settings.on_progress(std::int64_t(x1 - x0) * (y1 - y0) * (end - begin));
    });
    done = end;
    on_prefix(k, std::move(color), clock.seconds());
  }
}

void ColorSums::add(const ColorSums& o) {
  if (sum.empty()) {
    *this = o;
    return;
  }
  if (o.width != width || o.height != height)
    throw WorkError(fmt::format("cannot add colour sums of {}x{} to {}x{}", o.width, o.height, width, height));
  samples += o.samples;
  for (int g = 0; g < kSampleGroups; ++g) group_samples[g] += o.group_samples[g];
  dropped += o.dropped;
  for (std::size_t i = 0; i < sum.size(); ++i) sum[i] += o.sum[i];
  for (std::size_t i = 0; i < group_sum.size(); ++i) group_sum[i] += o.group_sum[i];
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
  // pixel_sums.h's group_ratio_variance with weight 1 per sample.
  double a[kGroups], b[kGroups];
  std::int64_t n[kGroups];
  const std::size_t pixel = i / 3, c = i % 3;
  for (int g = 0; g < kGroups; ++g) {
    a[g] = group_sum[(pixel * kGroups + std::size_t(g)) * 3 + c];
    b[g] = double(group_samples[g]);
    n[g] = group_samples[g];
  }
  return group_ratio_variance(a, b, n, sum[i], double(samples));
}

Image ColorSums::variance_of_mean() const {
  Image img(width, height, 3);
  for (std::size_t i = 0; i < sum.size(); ++i) img.data()[i] = float(variance_of_mean(i));
  return img;
}

}  // namespace dnb
