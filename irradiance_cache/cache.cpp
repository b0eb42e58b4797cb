#include "irradiance_cache/cache.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "core/errors.h"

namespace dnb::ic {

using rt::Frame;
using rt::kPi;

// ---- Gather (Ward and Heckbert 1992, with Krivanek et al. 2005's translational gradient) ----
GatherResult gather(Vec3 n, int M, int N, const IncomingFn& incoming,
                    const std::function<std::array<float, 2>(int cell)>& jitter, float clamp_ratio, int* cut) {
  if (M < 1 || N < 1) throw InputError(fmt::format("gather needs at least 1 x 1 cells (got {} x {})", M, N));
  const Frame f(n);
  std::vector<GatherSample> cells(std::size_t(M) * N);
  for (int j = 0; j < M; ++j)
    for (int k = 0; k < N; ++k) {
      const int cell = j * N + k;
      std::array<float, 2> u = jitter ? jitter(cell) : std::array<float, 2>{0.5f, 0.5f};
      // Cosine-proportional strata: sin^2(theta) uniform in [j/M, (j+1)/M), phi uniform in
      // [2 pi k / N, 2 pi (k+1) / N): every cell carries the same share of the irradiance.
      float sin2 = (float(j) + u[0]) / float(M);
      float sin_t = std::sqrt(sin2), cos_t = std::sqrt(std::max(0.0f, 1.0f - sin2));
      float phi = 2.0f * kPi * (float(k) + u[1]) / float(N);
      Vec3 dir = f.to_world({sin_t * std::cos(phi), sin_t * std::sin(phi), cos_t});
      cells[cell] = incoming(rt::normalize(dir), cell);
    }
  if (cut) *cut = 0;
  if (clamp_ratio > 0) {
    for (int pass = 0; pass < 3; ++pass) {
      double total = 0;
      for (const GatherSample& s : cells) total += std::max(0.0f, rt::luminance(s.radiance));
      const float bound = float(clamp_ratio * total / double(cells.size()));
      int n_cut = 0;
      for (GatherSample& s : cells) {
        const float l = rt::luminance(s.radiance);
        if (l > bound && l > 0) {
          s.radiance = s.radiance * (bound / l);
          ++n_cut;
        }
      }
      if (cut && pass == 0) *cut = n_cut;
      if (n_cut == 0) break;
    }
  }

  GatherResult g;
  double sum[3] = {0, 0, 0};  // double: E is exact for constant radiance (white furnace)
  double inv_dist = 0;
  std::array<Vec3, 3> rot{}, trans{};
  auto add_axis = [](std::array<Vec3, 3>& acc, Vec3 axis, Vec3 value) {
    for (int a = 0; a < 3; ++a) acc[a] += value * axis[a];
  };
  for (int j = 0; j < M; ++j) {
    // Cell boundaries theta_j^-, theta_j^+ and the centre theta_j (Krivanek and Gautron 2009,
    // section 2.x notation), with sin^2 theta linear in j.
    const float sin_minus = std::sqrt(float(j) / M), cos_minus = std::sqrt(1.0f - float(j) / M);
    const float cos_plus = std::sqrt(std::max(0.0f, 1.0f - float(j + 1) / M));
    const float sin_c = std::sqrt((j + 0.5f) / M), cos_c = std::sqrt(1.0f - (j + 0.5f) / M);
    // The stratum's mean of tan(theta) under the cosine density, instead of Ward and
    // Heckbert's tan at the centre: with sin^2 theta uniform, the integral of tan over the
    // stratum is [theta - sin theta cos theta], so M [...] is exact for radiance constant over
    // the cell; the centre value underestimates the horizon row by up to sqrt(2) (7% of the
    // whole gradient for 32 rows, a bias the rotational-gradient test catches).
    const double th_minus = std::asin(std::sqrt(double(j) / M)), th_plus = std::asin(std::sqrt(double(j + 1) / M));
    const float tan_c = float(M * ((th_plus - std::sin(th_plus) * std::cos(th_plus)) -
                                   (th_minus - std::sin(th_minus) * std::cos(th_minus))));
    for (int k = 0; k < N; ++k) {
      const GatherSample& s = cells[j * N + k];
      for (int c = 0; c < 3; ++c) sum[c] += s.radiance[c];
      if (s.distance < 1e29f) {
        inv_dist += 1.0 / std::max(s.distance, 1e-20f);
        g.min_distance = std::min(g.min_distance, s.distance);
      }
      const float phi_c = 2.0f * kPi * (k + 0.5f) / N, phi_minus = 2.0f * kPi * k / N;
      // Rotational gradient: grad_r E = integral L (n x w) dw; its cosine-weighted estimate
      // pi / (MN) sum L tan(theta) v, v = n x (unit azimuth direction) = (-sin phi, cos phi, 0).
      const Vec3 v_c = f.to_world({-std::sin(phi_c), std::cos(phi_c), 0.0f});
      add_axis(rot, v_c, s.radiance * (tan_c * kPi / float(M * N)));
      // Translational gradient: the change of each cell boundary's solid angle as the centre
      // moves, times the radiance difference across it, divided by the nearer hit distance.
      // Polar boundaries (between cells j - 1 and j) move along u_k.
      // Boundaries between two escaped cells (distance 1e30) do not move: skipped.
      if (j > 0) {
        const GatherSample& o = cells[(j - 1) * N + k];
        const float d = std::min(s.distance, o.distance);
        if (d < 1e29f) {
        const Vec3 u_k = f.to_world({std::cos(phi_c), std::sin(phi_c), 0.0f});
        const float c = 2.0f * kPi / N * sin_minus * cos_minus * cos_minus / d;
        add_axis(trans, u_k, (s.radiance - o.radiance) * c);
        }
      }
      // Azimuthal boundaries (between cells k - 1 and k) move along v_k^-.
      {
        const GatherSample& o = cells[j * N + (k + N - 1) % N];
        const float d = std::min(s.distance, o.distance);
        if (d < 1e29f) {
          const Vec3 v_minus = f.to_world({-std::sin(phi_minus), std::cos(phi_minus), 0.0f});
          const float c = cos_c * (cos_minus - cos_plus) / (sin_c * d);
          add_axis(trans, v_minus, (s.radiance - o.radiance) * c);
        }
      }
    }
  }
  for (int c = 0; c < 3; ++c) g.irradiance[c] = float(sum[c] * (3.14159265358979323846 / double(M * N)));
  g.rot_grad = rot;
  g.trans_grad = trans;
  // Harmonic mean over all cells, escaped ones counting as infinitely far (Ward's split-sphere
  // model: the irradiance changes at a rate of about E / harmonic mean distance).
  g.harmonic_mean_distance = inv_dist > 0 ? float(double(M * N) / inv_dist) : 1e30f;
  return g;
}

// ---- Settings -----------------------------------------------------------------------------
void CacheSettings::validate() const {
  if (!(kappa > 0) || !std::isfinite(kappa))
    throw InputError(fmt::format("irradiance cache: parameter 'kappa' must be > 0 (got {})", kappa));
  if (!(max_angle_degrees > 0 && max_angle_degrees <= 90))
    throw InputError(
        fmt::format("irradiance cache: parameter 'max_angle_degrees' must be in (0, 90] (got {})", max_angle_degrees));
}

// ---- Octree -------------------------------------------------------------------------------
// A loose point-location octree in the style of pbrt-v2's Octree: a record is stored in every
// node of the first level whose children would be smaller than its influence box, so that the
// nodes on the root-to-leaf path of a point hold every record whose box contains the point.
// (Hand-written: the query is "which spheres contain this point", which neither Embree's point
// queries nor nanoflann's nearest-neighbour searches answer directly.)
struct IrradianceCache::Node {
  std::array<std::unique_ptr<Node>, 8> child;
  std::vector<std::uint32_t> items;
};

namespace {
constexpr int kMaxDepth = 16;
}

IrradianceCache::IrradianceCache(Vec3 lo, Vec3 hi, const CacheSettings& settings)
    : settings_(settings), root_(std::make_unique<Node>()) {
  settings_.validate();
  // The root is a cube around the scene bounds (slightly enlarged), so that nodes stay cubes.
  Vec3 c = (lo + hi) * 0.5f;
  float half = 0.5f * rt::max_component(hi - lo) * 1.01f + 1e-4f;
  lo_ = c - Vec3(half);
  hi_ = c + Vec3(half);
  // The angle term of Tabellion and Lamorlette's error, sqrt(1 - n . n_i) / sqrt(1 - cos a_max).
  // a_max is given in degrees and converted to radians here: pbrt-v2's IrradianceCacheIntegrator
  // passes its degree parameter through Degrees() where Radians() is meant, so its angle
  // threshold is cos(573 deg) for the default 10 deg; do not repeat that.
  const float a_max = settings_.max_angle_degrees * kPi / 180.0f;
  cos_max_angle_term_ = std::sqrt(1.0f - std::cos(a_max));
}
IrradianceCache::~IrradianceCache() = default;
IrradianceCache::IrradianceCache(IrradianceCache&&) noexcept = default;
IrradianceCache& IrradianceCache::operator=(IrradianceCache&&) noexcept = default;

void IrradianceCache::place(std::size_t index) {
  const Record& r = records_[index];
  const float rad = r.placed_radius;
  const Vec3 blo = r.p - Vec3(rad), bhi = r.p + Vec3(rad);
  // A box reaching outside the root is placed like any other, in the nodes its inside part
  // overlaps: for_each_near descends only for points inside the root and scans every record
  // for the others. (Keeping such records at the root made every look-up scan them: in the
  // Cornell box, whose walls are the scene's bounds, that was nearly every record.)
  auto rec = [&](auto&& self, Node& node, Vec3 lo, Vec3 hi, int depth) -> void {
    const float child_side = 0.5f * (hi.x - lo.x);
    if (depth == kMaxDepth || child_side < 2.0f * rad) {
      node.items.push_back(std::uint32_t(index));
      return;
    }
    const Vec3 mid = (lo + hi) * 0.5f;
    for (int c = 0; c < 8; ++c) {
      Vec3 clo{(c & 1) ? mid.x : lo.x, (c & 2) ? mid.y : lo.y, (c & 4) ? mid.z : lo.z};
      Vec3 chi{(c & 1) ? hi.x : mid.x, (c & 2) ? hi.y : mid.y, (c & 4) ? hi.z : mid.z};
      // Inclusive overlap, matching the point descent (p >= mid goes to the upper child).
      if (bhi.x < clo.x || blo.x > chi.x || bhi.y < clo.y || blo.y > chi.y || bhi.z < clo.z || blo.z > chi.z)
        continue;
      if (!node.child[c]) node.child[c] = std::make_unique<Node>();
      self(self, *node.child[c], clo, chi, depth + 1);
    }
  };
  rec(rec, *root_, lo_, hi_, 0);
}

template <typename F>
void IrradianceCache::for_each_near(Vec3 p, F&& f) const {
  const Node* node = root_.get();
  Vec3 lo = lo_, hi = hi_;
  const bool inside = p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y && p.z <= hi.z;
  if (!inside) {  // outside the scene's bounds (no hit point is): every record, once
    for (std::size_t i = 0; i < records_.size(); ++i) f(records_[i], i);
    return;
  }
  while (node) {
    for (std::uint32_t i : node->items) f(records_[i], std::size_t(i));
    const Vec3 mid = (lo + hi) * 0.5f;
    int c = (p.x >= mid.x ? 1 : 0) | (p.y >= mid.y ? 2 : 0) | (p.z >= mid.z ? 4 : 0);
    lo = {(c & 1) ? mid.x : lo.x, (c & 2) ? mid.y : lo.y, (c & 4) ? mid.z : lo.z};
    hi = {(c & 1) ? hi.x : mid.x, (c & 2) ? hi.y : mid.y, (c & 4) ? hi.z : mid.z};
    node = node->child[c].get();
  }
}

template <typename F>
void IrradianceCache::for_each_in_sphere(Vec3 center, float radius, F&& f) const {
  auto rec = [&](auto&& self, const Node& node, Vec3 lo, Vec3 hi) -> void {
    // Squared distance from the sphere's centre to the node's box.
    float d2 = 0;
    for (int a = 0; a < 3; ++a) {
      float v = std::max(std::max(lo[a] - center[a], 0.0f), center[a] - hi[a]);
      d2 += v * v;
    }
    if (d2 > radius * radius && &node != root_.get()) return;
    for (std::uint32_t i : node.items) f(records_[i], std::size_t(i));
    const Vec3 mid = (lo + hi) * 0.5f;
    for (int c = 0; c < 8; ++c)
      if (node.child[c]) {
        Vec3 clo{(c & 1) ? mid.x : lo.x, (c & 2) ? mid.y : lo.y, (c & 4) ? mid.z : lo.z};
        Vec3 chi{(c & 1) ? hi.x : mid.x, (c & 2) ? hi.y : mid.y, (c & 4) ? hi.z : mid.z};
        self(self, *node.child[c], clo, chi);
      }
  };
  rec(rec, *root_, lo_, hi_);
}

// ---- Records ------------------------------------------------------------------------------
std::size_t IrradianceCache::insert(Vec3 p, Vec3 n, const GatherResult& g, RadiusBounds bounds) {
  float R = g.harmonic_mean_distance;
  if (settings_.use_gradients) {
    // Krivanek et al. 2006: R_i <= E_i / |grad_t E_i| (per channel), so that the first-order
    // extrapolation cannot change E by more than E itself inside the record's radius.
    for (int c = 0; c < 3; ++c) {
      Vec3 grad{g.trans_grad[0][c], g.trans_grad[1][c], g.trans_grad[2][c]};
      float len = rt::length(grad);
      if (len > 0) R = std::min(R, g.irradiance[c] / len);
    }
  }
  const std::size_t index = records_.size();
  if (settings_.neighbor_clamp) {
    // Neighbour clamping (Krivanek et al. 2006): R_i <= R_j + |p_i - p_j| and R_j <= R_i +
    // |p_i - p_j|, so that a small radius (a nearby occluder) spreads to the neighbours that
    // could not see it, and no record's radius jumps across its neighbours'.
    // R_i <= R_j + d only binds for d < R_i: search that sphere (capped at the pixel bound,
    // beyond which the record's radius is clamped anyway; this keeps open-sky records cheap).
    const float search = std::min(R, bounds.max);
    for_each_in_sphere(p, search, [&](const Record& r, std::size_t) {
      float d = rt::length(p - r.p);
      if (d < search) R = std::min(R, r.radius_unclamped + d);
    });
    // R_j <= R_i + d for every record whose domain reaches p_i.
    for_each_near(p, [&](const Record& r, std::size_t i) {
      float d = rt::length(p - r.p);
      if (d < influence(r) && r.radius_unclamped > R + d) {
        Record& m = records_[i];
        m.radius_unclamped = R + d;
        m.radius = std::clamp(m.radius_unclamped, m.radius_min, m.radius_max);
      }
    });
  }
  Record r;
  r.p = p;
  r.n = n;
  r.irradiance = g.irradiance;
  r.rot_grad = g.rot_grad;
  r.trans_grad = g.trans_grad;
  r.radius_unclamped = R;
  r.radius_min = bounds.min;
  r.radius_max = std::max(bounds.min, bounds.max);
  r.radius = std::clamp(R, r.radius_min, r.radius_max);
  r.placed_radius = r.radius / settings_.kappa;
  if (!settings_.use_gradients) r.rot_grad = r.trans_grad = {};
  // A radius the pixel-footprint minimum raised above the gradient limit: the gradient is
  // scaled down so that R_i |grad_t E_i| <= E_i still holds (Krivanek et al. 2006). Without
  // this, a record beside a bright source (E small, gradient steep) extrapolated to ramps of
  // hundreds of times E over its clamped radius (bedroom: streaks of 13 against 0.02).
  for (int c = 0; c < 3 && settings_.use_gradients; ++c) {
    const float len = rt::length(Vec3{r.trans_grad[0][c], r.trans_grad[1][c], r.trans_grad[2][c]});
    const float e = std::max(0.0f, r.irradiance[c]);
    if (len * r.radius > e) {
      const float s = len > 0 ? e / (len * r.radius) : 0.0f;
      for (int a = 0; a < 3; ++a) r.trans_grad[a][c] *= s;
    }
  }
  records_.push_back(r);
  place(index);
  return index;
}

float IrradianceCache::weight(const Record& r, Vec3 p, Vec3 n) const {
  const Vec3 d = p - r.p;
  // Ward's "in front" test: a record lying above p's tangent plane (by more than a small share
  // of its radius, for curvature and tessellation) sees occluders that p does not.
  if (rt::dot(d, (n + r.n) * 0.5f) < -0.05f * r.radius) return 0.0f;
  const float e_pos = rt::length(d) / r.radius;
  const float e_dir = std::sqrt(std::max(0.0f, 1.0f - rt::dot(n, r.n))) / cos_max_angle_term_;
  // Tabellion and Lamorlette 2004: error = kappa max(position term, angle term); weight 1 - error
  // goes to 0 continuously at the edge of the record's domain, unlike Ward's 1 / error.
  const float err = settings_.kappa * std::max(e_pos, e_dir);
  return err < 1.0f ? 1.0f - err : 0.0f;
}

Vec3 IrradianceCache::extrapolate(const Record& r, Vec3 p, Vec3 n) const {
  Vec3 e = r.irradiance;
  if (settings_.use_gradients) {
    const Vec3 cn = rt::cross(r.n, n), d = p - r.p;
    for (int a = 0; a < 3; ++a) e += r.rot_grad[a] * cn[a] + r.trans_grad[a] * d[a];
    e = rt::vmax(e, Vec3(0.0f));  // first-order extrapolation may overshoot below zero
  }
  return e;
}

void IrradianceCache::accumulate(Vec3 p, Vec3 n, Vec3& weighted_sum, float& weight_sum) const {
  for_each_near(p, [&](const Record& r, std::size_t) {
    float w = weight(r, p, n);
    if (w > 0) {
      weighted_sum += extrapolate(r, p, n) * w;
      weight_sum += w;
    }
  });
}

bool IrradianceCache::interpolate(Vec3 p, Vec3 n, Vec3& irradiance) const {
  Vec3 s(0.0f);
  float w = 0;
  accumulate(p, n, s, w);
  if (!(w > 0)) return false;
  irradiance = s / w;
  return true;
}

std::vector<std::size_t> IrradianceCache::lookup(Vec3 p) const {
  std::vector<std::size_t> out;
  for_each_near(p, [&](const Record& r, std::size_t i) {
    if (rt::length(p - r.p) < influence(r)) out.push_back(i);
  });
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<std::size_t> IrradianceCache::lookup_brute_force(Vec3 p) const {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < records_.size(); ++i)
    if (rt::length(p - records_[i].p) < influence(records_[i])) out.push_back(i);
  return out;
}

}  // namespace dnb::ic
