// The edge set G of a frame (paper 3.1), from the finished normal and depth layers: pixel p is in G when
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
#include <cmath>
#include <cstdint>

#include "tracer/pixel_sums.h"
#include "tracer/render_internal.h"

namespace dnb::render_pass {

namespace {

constexpr float kEdgeNormalLength = 0.95f;  // |mean of unit normals| below: normals disagree inside
constexpr float kEdgeNormalAngle = 25.0f;   // degrees between neighbours' normals
constexpr float kEdgeDepthRel = 0.05f;      // relative depth jump between neighbours
constexpr float kEdgeDepthSpread = 0.02f;   // relative std. deviation of depth inside a pixel

}  // namespace

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

namespace {

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

}  // namespace

// In parallel over chunks of edge pixels.
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

}  // namespace dnb::render_pass
