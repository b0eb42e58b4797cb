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
  // Level 0 only: colour and the squares for the variance layers.
  kColor = 0, kColorSq = 3, kDirectSq = 6, kIndirectSq = 9, kDirectTSq = 12, kIndirectTSq = 15,
  kExtraSize = 20,
};
}  // namespace acc

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

template <int N>
inline void add_values(double* __restrict a, const float* __restrict v) {
  for (int i = 0; i < N; ++i) a[i] += double(v[i]);
}
template <int N>
inline void add_values(double* __restrict a, const double* __restrict v) {
  for (int i = 0; i < N; ++i) a[i] += v[i];
}

// Squares in double: a legal emitter of 1e30 squares to 1e60, beyond float.
inline void put_squares(double* o, Vec3 a) {
  o[0] = double(a.x) * a.x;
  o[1] = double(a.y) * a.y;
  o[2] = double(a.z) * a.z;
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

// Sample variance of the mean of three sums (0 below two samples).
inline void store_var(Image& img, int x, int y, const double* sum, const double* sq, std::int64_t n) {
  float* p = img.pixel(x, y);
  for (int c = 0; c < 3; ++c) {
    if (n < 2) {
      p[c] = 0;
      continue;
    }
    double mean = sum[c] / n;
    double var = std::max(0.0, (sq[c] - mean * sum[c]) / double(n - 1));
    p[c] = variance_to_float(var / n);
  }
}

// The albedo-weighted mean of an illumination layer (tracer/render.cpp's top) into out[0..2].
inline void demodulated(const double* sum_t, const double* sum, const double* albedo, std::int64_t n, float* out) {
  for (int c = 0; c < 3; ++c) {
    if (albedo[c] > 1e-12 * double(n)) out[c] = float(sum_t[c] / albedo[c]);
    else out[c] = n > 0 ? float(sum[c] / double(n)) : 0.0f;
  }
}

// Variance of that mean: of the samples X T / mean(T), or of X where the albedo sums to 0.
inline void demodulated_var(const double* sum_t, const double* sq_t, const double* sum, const double* sq,
                            const double* albedo, std::int64_t n, float* out) {
  for (int c = 0; c < 3; ++c) {
    if (n < 2) {
      out[c] = 0;
      continue;
    }
    const bool weighted = albedo[c] > 1e-12 * double(n);
    const double s1 = weighted ? sum_t[c] : sum[c], s2 = weighted ? sq_t[c] : sq[c];
    const double mean = s1 / n;
    double var = std::max(0.0, (s2 - mean * s1) / double(n - 1)) / n;
    if (weighted) {
      const double t = albedo[c] / n;
      var /= t * t;
    }
    out[c] = variance_to_float(var);
  }
}

}  // namespace dnb::rt
