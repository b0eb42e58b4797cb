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
// an edge or texture that stratification averages out: tests/tracer/variance_test.cpp has the
// figures). The eight groups are independent replicates of
// the same estimator, so the spread of their means gives the variance of the pixel's mean without
// bias (pixel_sums.h's group_ratio_variance; 7 degrees of freedom per pixel: a single pixel's
// value is noisy, +-53% (one standard deviation), its expectation exact). variance_test.cpp
// checks it against the seed-to-seed variance over many seeds. The half buffers half0.* and
// half1.* are the even and the odd groups: two independent half-sample estimates.
//
// Edge set G and its sub-pixels: tracer/render_edges.cpp.
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
#include "tracer/render_internal.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"

namespace dnb {
using namespace rt;
using namespace render_pass;

namespace {

// ---- The frame's layers ----

// One half buffer's layers (those with `halves` in core/aov_frame.h's layer::table()).
struct HalfImages {
  Image *color, *direct, *indirect, *albedo, *normal, *depth;
};

// The layers the main pass writes, looked up once.
struct FrameLayers {
  Image *color, *var_f, *var_d, *var_i, *samples, *edge;
  Image *gloss_direct, *gloss_indirect, *gloss_color, *trans_direct, *trans_indirect, *trans_color;
  std::vector<LevelImages> level;  // 0 .. K
  HalfImages half[2];              // the even and the odd samples' level 0
};

// Every layer of a frame with K reflection levels, allocated in parallel and not filled: the
// main pass (store_pixel: every level's and half's layers, the variances, the Cycles parts) and
// mark_edge_set write every value of every layer, and nothing reads one before. (A 1024x768 frame
// with two reflection levels holds ~330 MB.)
AovFrame allocate_frame(int W, int H, int K, int threads) {
  AovFrame frame(W, H);
  std::vector<std::pair<std::string, int>> names;
  for (const layer::Info& l : layer::table()) {
    if (l.sequence_only) continue;  // motion: render_sequence_frame adds it
    if (l.level0) names.emplace_back(l.name, l.channels);
    for (int k = 1; l.levels && k <= K; ++k) names.emplace_back(layer::at_level(k, l.name), l.channels);
    for (int h = 0; l.halves && h < 2; ++h) names.emplace_back(layer::at_half(h, l.name), l.channels);
  }
  std::vector<Image> images(names.size());
  run_in_arena(threads, [&] {
    tbb::parallel_for(std::size_t(0), names.size(),
                      [&](std::size_t i) { images[i] = Image(W, H, names[i].second, Image::NoFill{}); });
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
  out.gloss_direct = &frame.layer(layer::kGlossDirect);
  out.gloss_indirect = &frame.layer(layer::kGlossIndirect);
  out.gloss_color = &frame.layer(layer::kGlossColor);
  out.trans_direct = &frame.layer(layer::kTransDirect);
  out.trans_indirect = &frame.layer(layer::kTransIndirect);
  out.trans_color = &frame.layer(layer::kTransColor);
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

// The sums of one sample group (rt::Sampler): level 0's layers and the colour. The pixel's
// level-0 sums, its half buffers and the variances of its means are all made from them.
struct GroupSums {
  LevelSums level;
  alignas(32) double extra[acc::kExtraSize] = {};
};

// Adds one finite sample to its pixel's sums: its group's level 0 and colour (`group`), and
// levels 1 .. min(r.levels, K + 1) - 1 to `sums` (level 0 is made from the groups at the end).
inline void accumulate_sample(const SampleResult& r, int K, LevelSums* sums, GroupSums& group, SpecularSums& spec) {
  alignas(32) float vals[acc::kLevelSize];
  const Vec3 f = r.level[0].color();
  alignas(32) double xvals[acc::kExtraSize] = {f.x, f.y, f.z, 0.0};
  add_values<acc::kExtraSize>(group.extra, xvals);
  // A sample whose first hit has no glossy or refracting lobe adds only zeros: skipped (most
  // samples of most scenes; the sums are the same bits either way).
  if (!is_black(r.specular.gloss_color) || !is_black(r.specular.trans_color)) {
    alignas(32) float svals[acc::kSpecularSize];
    pack_specular(r.specular, svals);
    add_values<acc::kSpecularSize>(spec.v, svals);
  }
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
                 const SpecularSums& spec, Image& depth_spread) {
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
  const double* s = spec.v;
  store(*out.gloss_color, x, y, s + acc::kGlossColor, inv);
  store(*out.trans_color, x, y, s + acc::kTransColor, inv);
  colour_weighted(s + acc::kGlossDirect, s + acc::kGlossColor, out.gloss_direct->pixel(x, y));
  colour_weighted(s + acc::kGlossIndirect, s + acc::kGlossColor, out.gloss_indirect->pixel(x, y));
  colour_weighted(s + acc::kTransDirect, s + acc::kTransColor, out.trans_direct->pixel(x, y));
  colour_weighted(s + acc::kTransIndirect, s + acc::kTransColor, out.trans_indirect->pixel(x, y));
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
// `other`: a PixelSampler that traces the samples instead of src's tracer (render.h).
void render_tile(const SampleSource& src, const PixelSampler* other, int spp, const FrameLayers& out,
                 Image& depth_spread, int x0, int y0, int x1, int y1, PassCounts& counts) {
  SampleResult r;
  SampleTable table;
  const int K = int(out.level.size()) - 1;
  std::vector<LevelSums> sums(K + 1);
  // Pixel (x, y)'s layers from its samples: feed(add) calls add(s, result) for s = 0 .. spp - 1.
  auto pixel = [&](int x, int y, auto&& feed) {
    for (auto& s : sums) s = LevelSums{};
    GroupSums groups[kGroups];
    SpecularSums spec;
    feed([&](int s, const SampleResult& sr) {
      if (sample_finite(sr)) accumulate_sample(sr, K, sums.data(), groups[s % kGroups], spec);
      else ++counts.dropped;
    });
    store_pixel(out, x, y, sums, groups, spec, depth_spread);
  };
  if (other) {
    thread_local std::vector<SampleResult> batch;
    const int per_call = std::max(1, other->batch_samples() / spp);
    for (int y = y0; y < y1; ++y)
      for (int xb = x0; xb < x1; xb += per_call) {
        const int count = std::min(per_call, x1 - xb);
        batch.resize(std::size_t(count) * std::size_t(spp));
        counts.rays += other->trace_pixels(xb, y, count, spp, batch.data());
        for (int p = 0; p < count; ++p)
          pixel(xb + p, y, [&](auto&& add) {
            const SampleResult* samples = batch.data() + std::size_t(p) * std::size_t(spp);
            for (int s = 0; s < spp; ++s) add(s, samples[s]);
          });
      }
    return;
  }
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x)
      pixel(x, y, [&](auto&& add) {
        counts.rays += src.trace_samples(table, x, y, 0, spp, r,
                                         [&](int s, const SampleResult& sr, float, float) { add(s, sr); });
      });
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

AovFrame render_frame_impl(const Scene& scene, const RenderSettings& settings, const PixelSampler* main_pass) {
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
    render_tile(src, main_pass, settings.spp, out, depth_spread, x0, y0, x1, y1, tile);
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

}  // namespace

AovFrame render_frame(const Scene& scene, const RenderSettings& settings) {
  return render_frame_impl(scene, settings, nullptr);
}

AovFrame render_frame(const Scene& scene, const RenderSettings& settings, const PixelSampler& main_pass) {
  return render_frame_impl(scene, settings, &main_pass);
}

}  // namespace dnb
