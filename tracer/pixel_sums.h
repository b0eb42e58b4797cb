// Per-pixel sums of the sample layers, and the pixel means and variances made from them: the
// accumulation of render_frame (tracer/render.cpp, whose top comment defines the albedo-weighted
// "demodulated" means of D and I). Internal to the tracer; header-only, so that the per-sample
// adds still inline into the sample loops and vectorise there.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>

#include "core/image.h"
#include "tracer/integrator.h"
#include "tracer/math.h"

namespace dnb::rt {

// Three double sums (the sub-pixel strata of edge pixels).
struct D3 {
  double v[3] = {0, 0, 0};
  void add(Vec3 a) {
    v[0] += a.x;
    v[1] += a.y;
    v[2] += a.z;
  }
};

// Per-pixel sums of one level's layers over the samples that reached the level, kept as one
// flat array so that adding a sample is a single loop the compiler vectorises (float -> double
// conversions and adds four at a time); the per-sample bookkeeping of all layers otherwise
// costs as much as tracing the camera ray.
namespace acc {
enum : int {
  kDirect = 0, kIndirect = 3, kAlbedo = 6, kReflection = 9, kEmission = 12, kNormal = 15, kTint = 18,
  kDirectT = 21, kIndirectT = 24, kDepth = 27, kDepthSq = 28,
  kLevelSize = 32,  // padded to a multiple of 4
  // Level 0 only: the colour (its variance comes from the sample groups, GroupMoments).
  kColor = 0,
  kExtraSize = 4,
};
}  // namespace acc

// Level 0's reflected and refracted light as Cycles splits it (integrator.h's LevelSample), per
// pixel only: no variance and no half buffer is made of them, so not per sample group.
namespace acc {
enum : int {
  kGlossColor = 0, kGlossDirect = 3, kGlossIndirect = 6, kTransColor = 9, kTransDirect = 12, kTransIndirect = 15,
  kSpecularSize = 20,  // padded to a multiple of 4
};
}  // namespace acc

struct SpecularSums {
  alignas(32) double v[acc::kSpecularSize] = {};
};

struct LevelSums {
  std::int64_t n = 0;
  alignas(32) double v[acc::kLevelSize] = {};
  const double* at(int off) const { return v + off; }
};

inline void put3(float* o, Vec3 a) {
  o[0] = a.x;
  o[1] = a.y;
  o[2] = a.z;
}

inline void pack_level(const LevelSample& l, float* o) {
  put3(o + acc::kDirect, l.direct);
  put3(o + acc::kIndirect, l.indirect);
  put3(o + acc::kAlbedo, l.albedo);
  put3(o + acc::kReflection, l.reflection);
  put3(o + acc::kEmission, l.emission);
  put3(o + acc::kNormal, l.normal);
  put3(o + acc::kTint, l.tint);
  put3(o + acc::kDirectT, l.direct * l.albedo);
  put3(o + acc::kIndirectT, l.indirect * l.albedo);
  o[acc::kDepth] = l.depth;
  o[acc::kDepthSq] = l.depth * l.depth;
  o[29] = o[30] = o[31] = 0;
}

inline void pack_specular(const SpecularParts& l, float* o) {
  put3(o + acc::kGlossColor, l.gloss_color);
  put3(o + acc::kGlossDirect, l.gloss_direct);
  put3(o + acc::kGlossIndirect, l.gloss_indirect);
  put3(o + acc::kTransColor, l.trans_color);
  put3(o + acc::kTransDirect, l.trans_direct);
  put3(o + acc::kTransIndirect, l.trans_indirect);
  o[18] = o[19] = 0;
}

template <int N>
inline void add_values(double* __restrict a, const float* __restrict v) {
  for (int i = 0; i < N; ++i) a[i] += double(v[i]);
}
template <int N>
inline void add_values(double* __restrict a, const double* __restrict v) {
  for (int i = 0; i < N; ++i) a[i] += v[i];
}

// A variance as a layer value: the variance of a mean of samples near float's limit (an emitter
// of 1e30 seen directly) can exceed float's range, and is then clamped to its largest value
// rather than written as Inf (render_frame warns when it does).
inline float variance_to_float(double var) {
  return var < double(std::numeric_limits<float>::max()) ? float(var) : std::numeric_limits<float>::max();
}

// Mean of three sums.
inline void store(Image& img, int x, int y, const double* s, double inv) {
  float* p = img.pixel(x, y);
  for (int c = 0; c < 3; ++c) p[c] = float(s[c] * inv);
}

// A glossy or transmission light layer's mean, weighted by its colour as D and I are by T: the
// sum of the light over the sum of the colour (0 where the colour's sum is 0: no such lobe, so
// no such light), so that colour * (direct + indirect) is the mean of that part of R.
inline void colour_weighted(const double* light, const double* colour, float* out) {
  for (int c = 0; c < 3; ++c) out[c] = colour[c] > 0 ? float(light[c] / colour[c]) : 0.0f;
}

// The albedo-weighted mean of an illumination layer (tracer/render.cpp's top) into out[0..2].
inline void demodulated(const double* sum_t, const double* sum, const double* albedo, std::int64_t n, float* out) {
  for (int c = 0; c < 3; ++c) {
    if (albedo[c] > 1e-12 * double(n)) out[c] = float(sum_t[c] / albedo[c]);
    else out[c] = n > 0 ? float(sum[c] / double(n)) : 0.0f;
  }
}

// The variance of a pixel's mean from its sample groups (render.cpp's top; rt::Sampler's
// groups are independent replicates). A mean is a ratio of sums A / B: of the colour over the
// sample count (weights b = 1), or of D T over T for the albedo-weighted means (b = T). With
// a_g, b_g the sums over group g's samples and R = A / B, its first-order variance is
//   Var(A / B) = k / (k - 1) sum_g (a_g - R b_g)^2 / B^2
// over the k groups that hold a sample: unbiased for b = 1 and groups of equal size (every spp
// that is a multiple of Sampler::kGroups), k - 1 degrees of freedom. 0 with fewer than 2 groups.
template <int G>
inline float group_ratio_variance(const double (&a)[G], const double (&b)[G], const std::int64_t (&n)[G], double A,
                                  double B) {
  if (!(B > 0)) return 0.0f;
  const double r = A / B;
  double s = 0;
  int k = 0;
  for (int g = 0; g < G; ++g) {
    if (n[g] == 0) continue;
    const double e = a[g] - r * b[g];
    s += e * e;
    ++k;
  }
  if (k < 2) return 0.0f;
  return variance_to_float(s * double(k) / double(k - 1) / (B * B));
}

}  // namespace dnb::rt
