// Small vector maths for the tracer: a 3-float vector, an orthonormal frame, and the
// counter-based random numbers that make renders independent of thread count and tile order.
// (Written by hand because Embree's own vector types are internal to its tutorials and glm
// would be a new dependency for a dozen inline functions.)
#pragma once

#include <pmmintrin.h>
#include <xmmintrin.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace dnb::rt {

constexpr float kPi = 3.14159265358979323846f;
constexpr float kInvPi = 1.0f / kPi;

struct Vec3 {
  float x = 0, y = 0, z = 0;
  Vec3() = default;
  constexpr Vec3(float a, float b, float c) : x(a), y(b), z(c) {}
  explicit constexpr Vec3(float a) : x(a), y(a), z(a) {}
  float operator[](int i) const { return i == 0 ? x : (i == 1 ? y : z); }
  float& operator[](int i) { return i == 0 ? x : (i == 1 ? y : z); }
};

inline Vec3 operator+(Vec3 a, Vec3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3 operator-(Vec3 a, Vec3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3 operator-(Vec3 a) { return {-a.x, -a.y, -a.z}; }
inline Vec3 operator*(Vec3 a, Vec3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
inline Vec3 operator*(Vec3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
inline Vec3 operator*(float s, Vec3 a) { return {a.x * s, a.y * s, a.z * s}; }
inline Vec3 operator/(Vec3 a, float s) { return a * (1.0f / s); }
inline Vec3& operator+=(Vec3& a, Vec3 b) { a = a + b; return a; }
inline Vec3& operator*=(Vec3& a, Vec3 b) { a = a * b; return a; }
inline Vec3& operator*=(Vec3& a, float s) { a = a * s; return a; }
inline float dot(Vec3 a, Vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline float length(Vec3 a) { return std::sqrt(dot(a, a)); }
inline Vec3 normalize(Vec3 a) {
  float l = length(a);
  return l > 0 ? a / l : Vec3(0, 0, 1);
}
inline float max_component(Vec3 a) { return std::max(a.x, std::max(a.y, a.z)); }
inline float luminance(Vec3 a) { return 0.2126f * a.x + 0.7152f * a.y + 0.0722f * a.z; }
inline bool is_black(Vec3 a) { return a.x == 0 && a.y == 0 && a.z == 0; }
inline bool is_finite(Vec3 a) { return std::isfinite(a.x) && std::isfinite(a.y) && std::isfinite(a.z); }
inline Vec3 vmin(Vec3 a, Vec3 b) { return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)}; }
inline Vec3 vmax(Vec3 a, Vec3 b) { return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)}; }
// Mirror reflection of the direction `wo` (pointing away from the surface) about n.
inline Vec3 reflect(Vec3 wo, Vec3 n) { return 2.0f * dot(wo, n) * n - wo; }

// Orthonormal basis around a unit normal (Duff et al. 2017, "Building an orthonormal basis,
// revisited").
struct Frame {
  Vec3 t, b, n;
  explicit Frame(Vec3 nn) : n(nn) {
    float sign = std::copysign(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float bb = n.x * n.y * a;
    t = {1.0f + sign * n.x * n.x * a, sign * bb, -sign * n.x};
    b = {bb, sign + n.y * n.y * a, -n.y};
  }
  Vec3 to_world(Vec3 v) const { return t * v.x + b * v.y + n * v.z; }
  Vec3 to_local(Vec3 v) const { return {dot(v, t), dot(v, b), dot(v, n)}; }
};

// Cosine-weighted hemisphere direction around +z (Malley's method), pdf = cos / pi.
inline Vec3 sample_cosine_hemisphere(float u1, float u2) {
  float r = std::sqrt(u1);
  float phi = 2.0f * kPi * u2;
  return {r * std::cos(phi), r * std::sin(phi), std::sqrt(std::max(0.0f, 1.0f - u1))};
}

// Uniform direction inside a cone around +z with cos(half-angle) = cos_max; pdf = 1 / (2 pi (1 - cos_max)).
inline Vec3 sample_cone(float u1, float u2, float cos_max) {
  float cos_t = 1.0f - u1 * (1.0f - cos_max);
  float sin_t = std::sqrt(std::max(0.0f, 1.0f - cos_t * cos_t));
  float phi = 2.0f * kPi * u2;
  return {sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t};
}

// Shirley and Chiu's concentric map of the unit square onto the unit disc (area-preserving,
// low distortion, so that stratified lens samples stay stratified).
inline void concentric_disk(float u1, float u2, float& x, float& y) {
  const float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
  if (a == 0 && b == 0) {
    x = y = 0;
    return;
  }
  float r, phi;
  if (std::fabs(a) > std::fabs(b)) {
    r = a;
    phi = (kPi / 4) * (b / a);
  } else {
    r = b;
    phi = (kPi / 2) - (kPi / 4) * (a / b);
  }
  x = r * std::cos(phi);
  y = r * std::sin(phi);
}

// Uniform direction on the unit sphere; pdf = 1 / (4 pi).
inline Vec3 sample_sphere(float u1, float u2) {
  float z = 1.0f - 2.0f * u1;
  float r = std::sqrt(std::max(0.0f, 1.0f - z * z));
  float phi = 2.0f * kPi * u2;
  return {r * std::cos(phi), r * std::sin(phi), z};
}

// Flush denormals to zero on the calling thread (Embree's recommendation, and it keeps every
// rendering thread computing the same bits). The tracer calls it on each of its tasks; a
// renderer that calls the tracer from its own threads should call it on them too.
inline void enable_flush_to_zero() {
  _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
  _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

// ---- Counter-based random numbers ------------------------------------------------------------
// Every random number of a render is a pure function of (seed, pixel, sample index, dimension),
// so a sample gives the same value whichever thread renders it and in whichever order: images
// are bit-identical for any thread count. The mixer is SplitMix64's finaliser (Steele et al.
// 2014), applied to a combination of the four counters.
inline std::uint64_t mix64(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// ---- Owen-scrambled Sobol' points (the pixel samples of render.cpp) --------------------------
// Written here because no library in Debian offers hash-based Owen scrambling: Boost has Sobol'
// generators (tests/tracer/sampler_test.cpp checks ours against boost::random::sobol) but no
// scrambling, and a render needs a random-access point (pixel, sample, dimension) per call.
// The construction is Burley's "Practical Hash-based Owen Scrambling" (JCGT 2020): the first two
// dimensions of Sobol's sequence (a (0,2)-sequence in base 2), the point's index shuffled and its
// coordinates scrambled by nested uniform (Owen) scrambles made of a Laine-Karras style hash, a
// fresh seed per pair of dimensions ("padding"), so every pair of dimensions is its own
// scrambled (0,2)-sequence and pairs are independent of each other.

inline std::uint32_t reverse_bits(std::uint32_t x) {
  x = (x << 16) | (x >> 16);
  x = ((x & 0x00ff00ffu) << 8) | ((x & 0xff00ff00u) >> 8);
  x = ((x & 0x0f0f0f0fu) << 4) | ((x & 0xf0f0f0f0u) >> 4);
  x = ((x & 0x33333333u) << 2) | ((x & 0xccccccccu) >> 2);
  return ((x & 0x55555555u) << 1) | ((x & 0xaaaaaaaau) >> 1);
}

// A random permutation of 32-bit words in which bit k of the result depends only on bits 0..k
// of x (carries and products move information only upwards): Burley's improved Laine-Karras hash.
inline std::uint32_t laine_karras_permutation(std::uint32_t x, std::uint32_t seed) {
  x += seed;
  x ^= x * 0x6c50b47cu;
  x ^= x * 0xb82f1e52u;
  x ^= x * 0xc7afe638u;
  x ^= x * 0x8d22f6e6u;
  return x;
}

// Nested uniform scramble of x read as a binary fraction (most significant bit first): each digit
// is flipped by a random function of the digits before it.
inline std::uint32_t nested_uniform_scramble(std::uint32_t x, std::uint32_t seed) {
  return reverse_bits(laine_karras_permutation(reverse_bits(x), seed));
}

// Point i of Sobol's first two dimensions as 32-bit fractions: the van der Corput radical
// inverse, and the second dimension (primitive polynomial x + 1: its direction numbers are the
// rows of Pascal's triangle mod 2, each the previous one xor itself shifted right by one).
inline std::uint32_t sobol_dim0(std::uint32_t i) { return reverse_bits(i); }
inline std::uint32_t sobol_dim1(std::uint32_t i) {
  std::uint32_t r = 0;
  for (std::uint32_t v = 1u << 31; i != 0; i >>= 1, v ^= v >> 1)
    if (i & 1u) r ^= v;
  return r;
}

// reverse_bits(sobol_dim1(i)), without the reversal: the reversed direction numbers (each the
// previous one xor itself shifted left by one).
inline std::uint32_t sobol_dim1_reversed(std::uint32_t i) {
  std::uint32_t r = 0;
  for (std::uint32_t w = 1; i != 0; i >>= 1, w ^= w << 1)
    if (i & 1u) r ^= w;
  return r;
}

inline float u32_to_unit(std::uint32_t x) { return float(x >> 8) * (1.0f / 16777216.0f); }  // 24 bits, < 1

// Where a path's random numbers sit (sequence mode): the film position takes dimensions 0 and 1,
// and the path's vertex v (1 for the camera ray's hit) the kVertexDims dimensions from
// kFilmDims + kVertexDims (v - 1), one fixed slot per use, so that the same use meets the same
// pair of dimensions on every path (pairs: light choice and lobe, the light point, the BSDF
// direction, Russian roulette). The film and the first kSequenceVertices vertices come from the
// scrambled sequences; deeper vertices, whose stratification gains little, from independent
// hashed numbers (a fifth of the cost per number), as every renderer's sampler pads high
// dimensions. The roulette pair of the sequence vertices (slots kRoulette and the spare 7) is
// hashed too: the tracer plays roulette only after PathTracer::Options::rr_depth (3) vertices,
// so scrambling it cost SampleTable::prepare two of its nine pairs for numbers no render read
// (a path that did read one would still get a uniform number, unstratified).
namespace dims {
enum : int {
  kFilmDims = 2,
  kLightChoice = 0, kLobe = 1, kLightU = 2, kLightV = 3, kBsdfU = 4, kBsdfV = 5, kRoulette = 6,
  kSequenceSlots = 6,  // the slots of a sequence vertex from the scrambled sequence: 0 .. 5
  kVertexDims = 8,
  kSequenceVertices = 2,
  kSequenceDims = kFilmDims + kVertexDims * kSequenceVertices,
  // The lens's two numbers: hashed dimensions of their own, far past any vertex's, so that adding
  // them left every pinhole render's numbers as they were (they are not part of the scrambled
  // sequence: unstratified, which costs a lens some noise, not correctness).
  kLensU = 0x7fff0000, kLensV = kLensU + 1,
  // The sample's time in the shutter interval (motion blur): hashed too, for the same reason.
  kTime = kLensU + 2,
};
}  // namespace dims
static_assert(dims::kSequenceSlots % 2 == 0 && dims::kRoulette >= dims::kSequenceSlots,
              "a pair of dimensions is scrambled or hashed as a whole; roulette is hashed");

// The random numbers of one sample. Two modes:
//  - independent (the constructor): every number a hash of (seed, key, sample, dimension in call
//    order); slots are ignored. Used where samples need no stratification (the irradiance
//    cache's records).
//  - sequence (pixel_sample()): the render's pixel samples. Sample s of a pixel belongs to group
//    g = s mod kGroups and is point s / kGroups of that group's own Owen-scrambled Sobol'
//    sequence (independent scrambles per pixel and group). Any prefix of a group's points whose
//    length is a power of two is a scrambled (0, m, 2)-net in every pair of the sequence's
//    dimensions (the film and the first dims::kSequenceVertices vertices; the index shuffle maps
//    the prefix onto one aligned block of the sequence), so the first N samples of a
//    render are as well stratified as a render of N samples, and are that render: the samples
//    do not depend on the total spp (render.cpp's progressive curve). The groups are independent
//    replicates, which gives an unbiased variance of a pixel's mean (render.cpp's top).
class SampleTable;

class Sampler {
 public:
  static constexpr int kGroups = 8;
  // A SampleTable holds the sequence dimensions of up to kTableSamples samples.
  static constexpr int kTableSamples = 256;

  // Independent mode.
  Sampler(std::uint64_t seed, std::uint64_t pixel, std::uint64_t sample)
      : key_(mix64(mix64(mix64(seed + 0x9e3779b97f4a7c15ULL) ^ pixel) + sample * 0x9e3779b97f4a7c15ULL)) {}

  // Sequence mode: sample s of pixel `pixel` of a render with `seed`.
  static Sampler pixel_sample(std::uint64_t seed, std::uint64_t pixel, std::uint64_t s) {
    Sampler r;  // not the independent mode's key (three hashes per sample): this mode's, below
    r.key_ = group_key(pixel_key(seed, pixel), int(s % kGroups));
    r.index_reversed_ = reverse_bits(std::uint32_t(s / kGroups));
    r.sample_key_ = sample_key(r.key_, s / kGroups);
    r.sequence_ = true;
    return r;
  }

  // The sequence mode's keys and scrambles, one definition for pixel_sample and SampleTable (whose
  // numbers must agree bit for bit): a pixel's key, its group g's key, the key of point i of a
  // group (the hashed dimensions), and the scrambles of a pair of dimensions of a group.
  static std::uint64_t pixel_key(std::uint64_t seed, std::uint64_t pixel) {
    return mix64(mix64(seed ^ 0x243f6a8885a308d3ULL) + pixel * 0x9e3779b97f4a7c15ULL);
  }
  static std::uint64_t group_key(std::uint64_t pixel_key, int g) { return mix64(pixel_key + std::uint64_t(g)); }
  static std::uint64_t sample_key(std::uint64_t group_key, std::uint64_t i) {
    return mix64(group_key + (i + 1) * 0x9e3779b97f4a7c15ULL);
  }
  struct PairScrambles {
    std::uint32_t s1, s2, s3;  // the index shuffle's, and the x and y coordinates'
  };
  static PairScrambles pair_scrambles(std::uint64_t group_key, std::uint32_t pair) {
    const std::uint64_t h = mix64(group_key + std::uint64_t(pair + 1) * 0xd1b54a32d192ed03ULL);
    return {std::uint32_t(h), std::uint32_t(h >> 32), std::uint32_t((h ^ (h >> 29)) * 0xbf58476d1ce4e5b9ULL >> 32)};
  }

  // The next dimension's uniform number in [0, 1).
  float next() {
    if (!sequence_) {
      std::uint64_t h = mix64(key_ + (dim_++) * 0xd1b54a32d192ed03ULL);
      return float(h >> 40) * (1.0f / 16777216.0f);  // 24 bits: exactly representable, < 1
    }
    return dimension_value(dim_++);
  }
  // Sequence mode: the number of slot `slot` (dims::) of the current vertex; independent mode:
  // next().
  float at(int slot) { return sequence_ ? dimension_value(base_ + std::uint32_t(slot)) : next(); }
  // A dimension by number (dims::kLensU, ...): sequence mode reads it, independent mode draws next().
  float dimension_at(std::uint32_t d) { return sequence_ ? dimension_value(d) : next(); }
  // Sequence mode: the path reached vertex v >= 1; at() now reads that vertex's slots.
  void start_vertex(int v) { base_ = std::uint32_t(dims::kFilmDims + dims::kVertexDims * (v - 1)); }
  std::uint32_t dimension() const { return dim_; }

 private:
  Sampler() = default;
  // The pair of dimensions holding d: Burley's construction, computed on bit-reversed words
  // (the Laine-Karras permutation scrambles a reversed word's digits), which saves half of the
  // reversals: with R = reverse_bits, LK = laine_karras_permutation, ri = R(index),
  //   shuffled index j = R(LK(ri, s1) ^ LK(0, s1))   (nested_uniform_scramble(index) xor
  //                      nested_uniform_scramble(0): the same permutation of every block
  //                      [0, 2^k) of indices, and j < 2^k whenever index < 2^k, so the Sobol'
  //                      loop runs over the index's few bits; xor by a constant is a digital
  //                      shift of the points, which the coordinates' own scrambles absorb)
  //   x = nested_uniform_scramble(sobol_dim0(j), s2) = R(LK(j, s2))
  //   y = nested_uniform_scramble(sobol_dim1(j), s3) = R(LK(sobol_dim1_reversed(j), s3)).
  // Dimensions from kSequenceDims on, and the roulette pair of the sequence vertices
  // (is_hashed): hashed from (the sample's key, dimension).
  static constexpr bool is_hashed(std::uint32_t d) {
    return d >= std::uint32_t(dims::kSequenceDims) ||
           (d >= std::uint32_t(dims::kFilmDims) &&
            (d - std::uint32_t(dims::kFilmDims)) % std::uint32_t(dims::kVertexDims) >= std::uint32_t(dims::kSequenceSlots));
  }
  float dimension_value(std::uint32_t d) {
    if (is_hashed(d)) {
      const std::uint64_t h = mix64(sample_key_ + std::uint64_t(d) * 0xd1b54a32d192ed03ULL);
      return float(h >> 40) * (1.0f / 16777216.0f);
    }
    if (table_) return table_[d * kTableSamples];
    const std::uint32_t pair = d >> 1;
    if (pair != pair_) {
      const PairScrambles p = pair_scrambles(key_, pair);
      j_ = reverse_bits(laine_karras_permutation(index_reversed_, p.s1) ^ laine_karras_permutation(0, p.s1));
      s2_ = p.s2;
      s3_ = p.s3;
      pair_ = pair;
    }
    // Each coordinate when asked for (a path uses one of some pairs: the lobe only on coated
    // surfaces).
    return (d & 1) == 0 ? u32_to_unit(reverse_bits(laine_karras_permutation(j_, s2_)))
                        : u32_to_unit(reverse_bits(laine_karras_permutation(sobol_dim1_reversed(j_), s3_)));
  }

  friend class SampleTable;
  const float* table_ = nullptr;  // this sample's sequence dimensions in a SampleTable, when made by one
  std::uint64_t key_ = 0;
  std::uint64_t sample_key_ = 0;
  std::uint32_t dim_ = 0;
  std::uint32_t index_reversed_ = 0, base_ = 0;  // reverse_bits(point index in the group)
  std::uint32_t pair_ = ~0u, j_ = 0, s2_ = 0, s3_ = 0;  // the current pair: shuffled index, scrambles
  bool sequence_ = false;
};

// The sequence dimensions (dims::kSequenceDims) of a run of one pixel's samples, computed
// together: Sampler::pixel_sample computes a pair's scrambles and its shuffled index on first
// use and each coordinate when asked, one number at a time, which was a seventh of a render's
// time; here every number of up to kMaxSamples samples is computed in one loop per pair of
// dimensions over the samples, eight to a vector (the groups' scrambles once per pixel and
// pair, not once per sample). The same integer operations in the same order: sampler(s) gives exactly the
// numbers of Sampler::pixel_sample(seed, pixel, s) (tests/tracer/sampler_test.cpp). ~18 KB; one
// per thread, reused across pixels.
class SampleTable {
 public:
  static constexpr int kMaxSamples = Sampler::kTableSamples;
  // Samples [begin, end) of `pixel` of a render with `seed`; end - begin <= kMaxSamples.
  void prepare(std::uint64_t seed, std::uint64_t pixel, std::uint64_t begin, std::uint64_t end);
  // Sample s (begin <= s < end of the last prepare()): equal to Sampler::pixel_sample(seed, pixel, s).
  // The sampler reads the table: it must not outlive it or the next prepare().
  Sampler sampler(std::uint64_t s) const {
    const int g = int(s % Sampler::kGroups);
    const std::uint64_t i = s / Sampler::kGroups;
    Sampler r;
    r.key_ = group_key_[g];  // index_reversed_ and the pair cache stay unused: the table has them
    r.sample_key_ = Sampler::sample_key(r.key_, i);
    r.sequence_ = true;
    r.table_ = &values_[std::size_t(s - begin_)];
    return r;
  }

 private:
  std::uint64_t group_key_[Sampler::kGroups] = {};
  std::uint64_t begin_ = 0;
  // values_[d * kMaxSamples + s - begin_]: dimension d of sample s.
  alignas(32) float values_[dims::kSequenceDims * kMaxSamples] = {};
};

// Calls f(s, sampler) for s = begin .. end - 1 in order, the samples of `pixel` of a render with
// `seed`, their sequence dimensions computed kMaxSamples at a time into `table`.
template <typename F>
void for_pixel_samples(SampleTable& table, std::uint64_t seed, std::uint64_t pixel, std::uint64_t begin,
                       std::uint64_t end, F&& f) {
  for (std::uint64_t b = begin; b < end; b += SampleTable::kMaxSamples) {
    const std::uint64_t e = std::min<std::uint64_t>(end, b + SampleTable::kMaxSamples);
    table.prepare(seed, pixel, b, e);
    for (std::uint64_t s = b; s < e; ++s) f(s, table.sampler(s));
  }
}

}  // namespace dnb::rt
