// The irradiance cache itself, independent of the tracer (Ward et al. 1988; Ward and Heckbert
// 1992; Tabellion and Lamorlette 2004; Krivanek et al. 2005, 2006; the notation follows
// Krivanek and Gautron, "Practical Global Illumination with Irradiance Caching", 2009).
//
// - gather(): a stratified, cosine-proportional hemisphere gather of M x N cells through a
//   callback that returns the radiance and hit distance along a direction, turned into a
//   record: irradiance E, rotational and translational gradients, hit-distance statistics.
// - IrradianceCache: records in an octree, inserted with radius clamping (pixel footprint,
//   gradient, neighbours) and interpolated with Tabellion and Lamorlette's error weight and
//   gradient extrapolation clamped to non-negative values.
// irradiance_cache.cpp drives it with the shared tracer; the tests drive it with analytic callbacks.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <utility>
#include <vector>

#include "tracer/math.h"

namespace dnb::ic {

using rt::Vec3;

// Stratified numbers for the n light samples of one shading point's direct light: u0 (which
// light) in n strata, (u1, u2) (where on the light, or which sky direction) in a k x k jittered
// grid when n = k^2 (else u1 in n strata, u2 free), the pairing of the two decorrelated by a
// random permutation. Same expectation as independent samples, lower variance where a light is
// partly hidden (a penumbra, sky through a window). `rng()` returns a uniform float in [0, 1).
class LightStrata {
 public:
  struct Numbers {
    float u0, u1, u2;
  };
  explicit LightStrata(int n) : n_(n), k_(1) {
    while ((k_ + 1) * (k_ + 1) <= n_) ++k_;
  }
  // The d-th sample's numbers, d = 0 .. n-1 in order (d = 0 draws a new permutation).
  template <typename Rng>
  Numbers next(int d, Rng&& rng) {
    if (d == 0) {
      perm_.resize(std::size_t(n_));
      for (int i = 0; i < n_; ++i) perm_[std::size_t(i)] = i;
      for (int i = n_ - 1; i > 0; --i) {
        const int j = int(rng() * float(i + 1));
        std::swap(perm_[std::size_t(i)], perm_[std::size_t(j < i ? j : i)]);
      }
    }
    const float j0 = rng(), j1 = rng(), j2 = rng();
    const int c = perm_[std::size_t(d)];
    const float u0 = (float(d) + j0) / float(n_);
    if (k_ * k_ == n_) return {u0, (float(c % k_) + j1) / float(k_), (float(c / k_) + j2) / float(k_)};
    return {u0, (float(c) + j1) / float(n_), j2};
  }

 private:
  int n_, k_;
  std::vector<int> perm_;
};

// Radiance arriving from one gather direction and the distance to what it came from
// (infinity when the ray escaped).
struct GatherSample {
  Vec3 radiance;
  float distance = 1e30f;
};
// Called with a unit world direction in the hemisphere about the record's normal and the index
// of the gather cell (j * N + k) so that the caller can seed its random numbers per cell.
using IncomingFn = std::function<GatherSample(Vec3 dir, int cell)>;

// One gathered hemisphere reduced to what a record keeps. Gradients are stored per axis: grad[a]
// holds d E / d (axis a) for the three colour channels, as in E(p, n) ~= E + (n_i x n) . rot +
// (p - p_i) . trans.
struct GatherResult {
  Vec3 irradiance;
  std::array<Vec3, 3> rot_grad{};
  std::array<Vec3, 3> trans_grad{};
  float harmonic_mean_distance = 1e30f;  // of the cells that hit something; 1e30 when none did
  float min_distance = 1e30f;
};

// Gathers M (polar) x N (azimuth) cells about the unit normal n: one cosine-distributed
// direction per cell, jittered by (u, v) from `jitter(cell)` (two numbers in [0, 1)); pass
// nullptr for cell centres. The irradiance estimate is pi / (MN) sum L (exact for constant L).
// clamp_ratio > 0: before anything is computed from them, cells whose luminance exceeds
// clamp_ratio times the mean cell luminance are cut to that bound (colour kept), the mean
// taken again after each cut, 3 times. Why: one gather ray that finds a rare bright path (a
// small light through a specular bounce) carries radiance thousands of times the rest; the
// record then shows that one sample as a bright disc of its radius. A cut cell keeps at most
// clamp_ratio / (M N) of the record's irradiance. `cut` (optional): the cells over the first bound.
GatherResult gather(Vec3 n, int M, int N, const IncomingFn& incoming,
                    const std::function<std::array<float, 2>(int cell)>& jitter = nullptr,
                    float clamp_ratio = 0.0f, int* cut = nullptr);

struct Record {
  Vec3 p, n;           // position and unit normal
  Vec3 irradiance;
  std::array<Vec3, 3> rot_grad{}, trans_grad{};
  float radius = 0;    // validity radius R_i after every clamp (world units)
  float radius_unclamped = 0;  // before the pixel-footprint clamp: what neighbour clamping reduces
  float radius_min = 0, radius_max = 1e30f;  // pixel-footprint bounds of this record
  float placed_radius = 0;     // influence radius the octree placement used (never below radius / kappa)
};

struct CacheSettings {
  float kappa = 1.0f;              // Tabellion-Lamorlette accuracy: larger = smaller influence, more records
  float max_angle_degrees = 10.0f; // normal deviation where the angle term of the error reaches 1 / kappa
  bool use_gradients = true;       // gradient extrapolation and the gradient limit of the radius
  bool neighbor_clamp = true;      // Krivanek et al. 2006 neighbour clamping
  // Throws InputError naming the parameter when a value is out of range.
  void validate() const;
};

// Pixel-footprint bounds of a new record, in world units.
struct RadiusBounds {
  float min = 0, max = 1e30f;
};

class IrradianceCache {
 public:
  // `lo`, `hi`: bounds of the scene; records outside them still work (kept at the root).
  IrradianceCache(Vec3 lo, Vec3 hi, const CacheSettings& settings);
  ~IrradianceCache();
  IrradianceCache(IrradianceCache&&) noexcept;
  IrradianceCache& operator=(IrradianceCache&&) noexcept;

  const CacheSettings& settings() const { return settings_; }

  // Builds a record from a gather at (p, n): radius = harmonic mean hit distance, limited by
  // E / |grad_t E| per channel, by neighbours (and the neighbours by it), then clamped to the
  // pixel-footprint bounds. Returns the record's index. Not thread-safe: callers insert from one
  // thread (irradiance_cache.cpp inserts in a fixed order, which makes the cache deterministic).
  std::size_t insert(Vec3 p, Vec3 n, const GatherResult& g, RadiusBounds bounds);

  // Tabellion-Lamorlette weight of record r at (p, n); 0 when r does not apply there.
  float weight(const Record& r, Vec3 p, Vec3 n) const;
  // E extrapolated from record r to (p, n) with its gradients, clamped to >= 0.
  Vec3 extrapolate(const Record& r, Vec3 p, Vec3 n) const;

  // Adds sum w_i E_i(p, n) and sum w_i over the records that apply at (p, n). Thread-safe
  // with other const calls.
  void accumulate(Vec3 p, Vec3 n, Vec3& weighted_sum, float& weight_sum) const;
  // The interpolated irradiance, or false when no record applies.
  bool interpolate(Vec3 p, Vec3 n, Vec3& irradiance) const;

  // Indices of the records whose influence sphere (radius / kappa) contains p, found with the
  // octree, in ascending order. lookup_brute_force gives the same by testing every record.
  std::vector<std::size_t> lookup(Vec3 p) const;
  std::vector<std::size_t> lookup_brute_force(Vec3 p) const;

  const std::vector<Record>& records() const { return records_; }
  std::size_t size() const { return records_.size(); }

 private:
  struct Node;
  float influence(const Record& r) const { return r.radius / settings_.kappa; }
  template <typename F>
  void for_each_near(Vec3 p, F&& f) const;        // records stored on the root-to-leaf path of p
  template <typename F>
  void for_each_in_sphere(Vec3 c, float radius, F&& f) const;
  void place(std::size_t index);

  CacheSettings settings_;
  float cos_max_angle_term_ = 0;  // sqrt(1 - cos(max angle)), the angle term's normaliser
  std::vector<Record> records_;
  std::unique_ptr<Node> root_;
  Vec3 lo_, hi_;
};

}  // namespace dnb::ic
