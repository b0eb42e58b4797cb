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

class Sampler {
 public:
  Sampler(std::uint64_t seed, std::uint64_t pixel, std::uint64_t sample)
      : key_(mix64(mix64(mix64(seed + 0x9e3779b97f4a7c15ULL) ^ pixel) + sample * 0x9e3779b97f4a7c15ULL)) {}
  // The next dimension's uniform number in [0, 1).
  float next() {
    std::uint64_t h = mix64(key_ + (dim_++) * 0xd1b54a32d192ed03ULL);
    return float(h >> 40) * (1.0f / 16777216.0f);  // 24 bits: exactly representable, < 1
  }
  std::uint32_t dimension() const { return dim_; }

 private:
  std::uint64_t key_;
  std::uint32_t dim_ = 0;
};

}  // namespace dnb::rt
