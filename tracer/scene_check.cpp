// find_coplanar_overlaps (tracer/scene_check.h). Triangles go into buckets by their plane
// (canonical unit normal and offset, quantised), and into a neighbouring bucket too when they lie
// within the tolerance of its border, so that any two triangles close enough to be compared share
// a bucket. Inside a bucket a sweep over the bounding boxes' x finds the candidates; a candidate
// pair whose materials make the tie-break matter is tested exactly: every corner of each within
// the offset of the other's plane, and the area of their intersection in that plane (Boost.Geometry).
#include "tracer/scene_check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <set>
#include <tuple>
#include <unordered_set>

// Boost 1.74's rescale policy trips GCC 12's -Wmaybe-uninitialized (a false positive in the header;
// clang, which builds the fuzz targets, has no such warning).
#pragma GCC diagnostic push
#if !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <boost/geometry/algorithms/area.hpp>
#include <boost/geometry/algorithms/correct.hpp>
#include <boost/geometry/algorithms/intersection.hpp>
#include <boost/geometry/geometries/multi_polygon.hpp>
#include <boost/geometry/geometries/point_xy.hpp>
#include <boost/geometry/geometries/polygon.hpp>
#pragma GCC diagnostic pop
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/parallel_sort.h>

#include "core/timer.h"

namespace dnb {
namespace {

namespace bg = boost::geometry;
using Point2 = bg::model::d2::point_xy<double>;
using Polygon2 = bg::model::polygon<Point2>;
// Doubles (rt::Vec3 is float): the plane and area tests compare distances of 1e-4 of the
// coordinates, which float's rounding of products would blur.
using D3 = std::array<double, 3>;

D3 d3(rt::Vec3 v) { return {v.x, v.y, v.z}; }
D3 sub(const D3& a, const D3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
double dot(const D3& a, const D3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
D3 cross(const D3& a, const D3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
D3 scaled(const D3& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
double norm(const D3& a) { return std::sqrt(dot(a, a)); }

// Parallel within this angle (radians; also the largest difference of one normal component).
constexpr double kNormalTolerance = 1e-3;
// A direction no axis-aligned or regularly tessellated face is perpendicular to: normals are
// turned to its side, so that a face and its reverse (a glass box's bottom facing down, the
// floor facing up) share a bucket. A normal within kNormalTolerance of perpendicular to it is
// bucketed both ways.
const D3 kSide = [] {
  const D3 g{0.3713907, 0.5570860, 0.7427814};
  return scaled(g, 1.0 / norm(g));
}();
// Overlaps smaller than this share of the smaller triangle are rounding at a shared edge.
constexpr double kMinAreaShare = 1e-3;
// Nor is an overlap under (this x the ray offset)^2 (1 mm^2 in a scene in metres) reported: the
// slivers where a sphere's tessellation meets itself at its poles (1e-10 m^2) are no surface a
// ray would meet in a frame's worth of samples.
constexpr double kMinAreaOffsets = 10;

struct Tri {
  unsigned mesh, material;
  bool transmissive;
  D3 p[3];
  D3 n;         // unit normal, on kSide's side
  double d;     // dot(n, p[0])
  double area;
  double offset;  // rt::ray_offset at the triangle's farthest corner
  D3 lo, hi;    // bounding box
};

// A bucket's entry: its key's 64-bit hash (two keys of one hash share a bucket: more
// comparisons, the same result) and the triangle.
struct Entry {
  std::uint64_t key;
  std::uint32_t id;
  bool operator<(const Entry& o) const { return key < o.key || (key == o.key && id < o.id); }
};
std::uint64_t key_hash(const std::int64_t (&c)[4]) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (std::int64_t v : c) {
    h ^= std::uint64_t(v);
    h *= 0x100000001b3ULL;
    h ^= h >> 32;
  }
  return h;
}

// Whether which of the two a ray meets can change the image: their materials differ, or one is
// transmissive (a ray inside the glass meets its face and the floor at once). Whether a ray can
// get there at all is reachable()'s question.
template <typename T>
bool tie_break_matters(const T& a, const T& b) {
  return a.material != b.material || a.transmissive || b.transmissive;
}

// The area of the intersection of triangles a and b, which lie in one plane, and points inside its
// largest piece to probe (its centre, and each corner a quarter of the way to the centre).
double overlap_area(const Tri& a, const Tri& b, std::vector<D3>& probes) {
  // An orthonormal frame of a's plane, about a's first corner (small coordinates: precision).
  const D3 helper = std::fabs(a.n[0]) < 0.9 ? D3{1, 0, 0} : D3{0, 1, 0};
  D3 u = cross(a.n, helper);
  u = scaled(u, 1.0 / norm(u));
  const D3 v = cross(a.n, u);
  double xy[2][3][2];  // the corners of a and b in that frame
  for (int t = 0; t < 2; ++t)
    for (int k = 0; k < 3; ++k) {
      const D3 q = sub((t == 0 ? a : b).p[k], a.p[0]);
      xy[t][k][0] = dot(q, u);
      xy[t][k][1] = dot(q, v);
    }
  // Most pairs that reach here are neighbours of one mesh that share an edge or a corner: an
  // edge's normal separates them (the separating axis theorem), and Boost need not be asked.
  double size = 0;
  for (auto& tri : xy)
    for (auto& c : tri) size = std::max({size, std::fabs(c[0]), std::fabs(c[1])});
  for (int t = 0; t < 2; ++t)
    for (int k = 0; k < 3; ++k) {
      const double* p0 = xy[t][k];
      const double* p1 = xy[t][(k + 1) % 3];
      const double nx = p1[1] - p0[1], ny = p0[0] - p1[0];
      double lo[2] = {1e300, 1e300}, hi[2] = {-1e300, -1e300};
      for (int w = 0; w < 2; ++w)
        for (const auto& c : xy[w]) {
          const double d = c[0] * nx + c[1] * ny;
          lo[w] = std::min(lo[w], d);
          hi[w] = std::max(hi[w], d);
        }
      // Touching within rounding (1e-9 of the pair's size along a unit axis) is no overlap.
      const double touch = 1e-9 * size * std::hypot(nx, ny);
      if (std::min(hi[0], hi[1]) - std::max(lo[0], lo[1]) <= touch) return 0;
    }
  auto polygon = [&](int t) {
    Polygon2 poly;
    for (int k = 0; k <= 3; ++k) bg::append(poly.outer(), Point2(xy[t][k % 3][0], xy[t][k % 3][1]));
    bg::correct(poly);
    return poly;
  };
  bg::model::multi_polygon<Polygon2> out;
  try {
    bg::intersection(polygon(0), polygon(1), out);
  } catch (const std::exception&) {  // degenerate input Boost refuses: no overlap to report
    return 0;
  }
  const double area = bg::area(out);
  probes.clear();
  if (area > 0) {
    const Polygon2& big = *std::max_element(out.begin(), out.end(), [](const Polygon2& x, const Polygon2& y) {
      return bg::area(x) < bg::area(y);
    });
    // The intersection of two triangles is convex: the mean of its corners is inside it.
    double cx = 0, cy = 0;
    const std::size_t corners = big.outer().size() - 1;  // a closed ring repeats its first corner
    for (std::size_t k = 0; k < corners; ++k) {
      cx += big.outer()[k].x() / double(corners);
      cy += big.outer()[k].y() / double(corners);
    }
    auto at = [&](double x, double y) {
      return D3{a.p[0][0] + x * u[0] + y * v[0], a.p[0][1] + x * u[1] + y * v[1], a.p[0][2] + x * u[2] + y * v[2]};
    };
    probes.push_back(at(cx, cy));
    for (std::size_t k = 0; k < corners; ++k)
      probes.push_back(at(0.75 * big.outer()[k].x() + 0.25 * cx, 0.75 * big.outer()[k].y() + 0.25 * cy));
  }
  return area;
}

bool coplanar(const Tri& a, const Tri& b, double tol_d) {
  for (int i = 0; i < 3; ++i)
    if (std::fabs(a.n[i] - b.n[i]) > kNormalTolerance) return false;
  if (std::fabs(a.d - b.d) > tol_d) return false;
  for (int k = 0; k < 3; ++k) {
    if (std::fabs(dot(a.n, b.p[k]) - a.d) > a.offset) return false;
    if (std::fabs(dot(b.n, a.p[k]) - b.d) > b.offset) return false;
  }
  return true;
}

// Glass faces a probe's ray passes through before it gives up (and counts the point as hidden).
constexpr int kGlassCrossings = 8;

// Where a ray ends when glass is looked through (a ray refracts through it; for these questions
// the direction's change does not matter): at an opaque surface (`hit`), nowhere within tmax, or
// lost after kGlassCrossings faces of glass.
enum class Walk { kOpaque, kClear, kLost };
Walk walk_through_glass(const Scene& scene, rt::Ray ray, rt::SurfaceHit& hit) {  // at ray.time
  for (int crossings = 0; crossings < kGlassCrossings; ++crossings) {
    if (!scene.intersect(ray, hit)) return Walk::kClear;
    if (hit.material->type != rt::MaterialType::kDielectric) return Walk::kOpaque;
    const rt::Vec3 next = hit.spawn_origin(ray.dir);
    ray.tmax -= rt::length(next - ray.origin);
    ray.origin = next;
  }
  return Walk::kLost;
}

// Whether a ray at `time` gets from `from` to `to` past every opaque surface.
bool clear_path(const Scene& scene, rt::Vec3 from, rt::Vec3 to, float time) {
  const rt::Vec3 d = to - from;
  const float dist = rt::length(d);
  if (!(dist > 0)) return true;
  rt::SurfaceHit hit;
  return walk_through_glass(scene, rt::Ray{from, d / dist, dist, time}, hit) == Walk::kClear;
}

// Whether the camera's rays can get to point p from side `side` (a unit normal) of the plane
// there, in at most two straight segments: p, just off the plane on that side, seen from the eye,
// or a surface that p sees over that side's hemisphere seen from the eye. Just off a face of a
// closed solid on its inside (a box's bottom on the floor) nothing is seen from the eye, nor under
// a floor or outside a building's walls. Deterministic: 64 fixed directions (a Fibonacci spiral).
// Every ray at `time` (where the moving geometry is).
bool reachable(const Scene& scene, const D3& p, const D3& side, double offset, float time) {
  const rt::Vec3 s{float(side[0]), float(side[1]), float(side[2])};
  const rt::Vec3 q = rt::Vec3(float(p[0]), float(p[1]), float(p[2])) + s * float(4 * offset);
  const rt::Vec3 eye = scene.camera.eye;
  if (clear_path(scene, q, eye, time)) return true;
  const rt::Vec3 t = rt::normalize(std::fabs(s.x) < 0.9f ? rt::cross(s, rt::Vec3(1, 0, 0)) : rt::cross(s, rt::Vec3(0, 1, 0)));
  const rt::Vec3 b = rt::cross(s, t);
  constexpr int kDirections = 64;
  const float golden = rt::kPi * (3.0f - std::sqrt(5.0f));
  for (int k = 0; k < kDirections; ++k) {
    const float z = 1.0f - (float(k) + 0.5f) / kDirections;  // cosine to the side's normal
    const float r = std::sqrt(std::max(0.0f, 1.0f - z * z)), phi = golden * float(k);
    const rt::Vec3 dir = rt::normalize(t * (r * std::cos(phi)) + b * (r * std::sin(phi)) + s * z);
    rt::SurfaceHit hit;
    // Into the sky (or lost in glass): camera rays do not come back from there.
    if (walk_through_glass(scene, rt::Ray{q, dir, 1e30f, time}, hit) != Walk::kOpaque) continue;
    if (clear_path(scene, hit.spawn_origin(-dir), eye, time)) return true;
  }
  return false;
}

}  // namespace

std::vector<CoplanarOverlap> find_coplanar_overlaps(const Scene& scene, bool* complete, CoplanarCheckLimits limits,
                                                    ShutterEnd end) {
  const Stopwatch clock;
  const bool close = end == ShutterEnd::kClose;
  const float time = close ? 1.0f : 0.0f;
  std::vector<Tri> tris;
  tris.reserve(scene.triangle_count());
  double radius = 0;  // the largest coordinate's magnitude
  for (std::size_t mi = 0; mi < scene.meshes.size(); ++mi) {
    const rt::Mesh& m = scene.meshes[mi];
    const std::vector<rt::Vec3>& positions = close && m.moving() ? m.later_positions.back() : m.positions;
    for (std::size_t t = 0; t < m.triangles(); ++t) {
      Tri tri;
      tri.mesh = unsigned(mi);
      tri.material = m.material[t];
      tri.transmissive = scene.materials[tri.material].type == rt::MaterialType::kDielectric;
      double mag = 0;
      for (int k = 0; k < 3; ++k) {
        tri.p[k] = d3(positions[3 * t + k]);
        for (double c : tri.p[k]) mag = std::max(mag, std::fabs(c));
      }
      const D3 c = cross(sub(tri.p[1], tri.p[0]), sub(tri.p[2], tri.p[0]));
      const double len = norm(c);
      tri.area = 0.5 * len;
      if (!(len > 0) || !std::isfinite(len)) continue;  // degenerate: no face to meet
      tri.n = scaled(c, 1.0 / len);
      if (dot(tri.n, kSide) < 0) tri.n = scaled(tri.n, -1);
      tri.d = dot(tri.n, tri.p[0]);
      // Two faces closer than the rays' offset are one place to a ray that leaves either.
      tri.offset = rt::ray_offset(float(mag));
      for (int i = 0; i < 3; ++i) {
        tri.lo[i] = std::min({tri.p[0][i], tri.p[1][i], tri.p[2][i]}) - tri.offset;
        tri.hi[i] = std::max({tri.p[0][i], tri.p[1][i], tri.p[2][i]}) + tri.offset;
      }
      radius = std::max(radius, mag);
      tris.push_back(tri);
    }
  }
  // Two faces within the tolerances of coplanar() differ in d = dot(n, p) by at most the
  // offset plus the normals' difference times the distance from the origin.
  const double tol_d = 1e-4 * std::max(1.0, radius) + 2 * kNormalTolerance * std::sqrt(3.0) * radius;
  const double cell_n = 0.02, cell_d = 4 * tol_d;

  // Buckets: every triangle into each cell whose key is within the tolerances of its own, per
  // coordinate (at most 2^4 cells, almost always one); a bucket is a run of equal keys after
  // sorting (no allocation per bucket).
  std::vector<Entry> entries;
  entries.reserve(tris.size() + tris.size() / 8);
  for (std::uint32_t i = 0; i < tris.size(); ++i) {
    const Tri& t = tris[i];
    for (int sign : {1, -1}) {
      if (sign < 0 && std::fabs(dot(t.n, kSide)) > kNormalTolerance) break;
      const double x[4] = {sign * t.n[0], sign * t.n[1], sign * t.n[2], sign * t.d};
      std::int64_t options[4][3];
      int count[4] = {};
      for (int c = 0; c < 4; ++c) {
        const double cell = c < 3 ? cell_n : cell_d, tol = c < 3 ? kNormalTolerance : tol_d;
        const auto k = std::int64_t(std::floor(x[c] / cell));
        options[c][count[c]++] = k;
        if (x[c] - double(k) * cell < tol) options[c][count[c]++] = k - 1;
        if (double(k + 1) * cell - x[c] < tol) options[c][count[c]++] = k + 1;
      }
      for (int a = 0; a < count[0]; ++a)
        for (int b = 0; b < count[1]; ++b)
          for (int c = 0; c < count[2]; ++c)
            for (int e = 0; e < count[3]; ++e)
              entries.push_back(Entry{key_hash({options[0][a], options[1][b], options[2][c], options[3][e]}), i});
    }
  }
  tbb::parallel_sort(entries.begin(), entries.end());  // (key, id) pairs are distinct: one order

  // A reversed copy of a triangle (bucketed both ways) compares with its reverse's normal.
  auto aligned = [&](std::uint32_t i, const Tri& other) {
    Tri t = tris[i];
    if (dot(t.n, other.n) < 0) {
      t.n = scaled(t.n, -1);
      t.d = -t.d;
    }
    return t;
  };

  // The overlapping pairs, per pair of (mesh, material).
  struct Candidate {
    double area;
    std::vector<D3> probes;
    D3 n;
    double offset;
  };
  using GroupId = std::tuple<unsigned, unsigned, unsigned, unsigned>;
  std::map<GroupId, std::vector<Candidate>> groups;
  std::unordered_set<std::uint64_t> seen;
  std::uint64_t comparisons = 0;
  bool within_limits = true;
  // What the sweep reads of a triangle, contiguous: a Tri is about 180 bytes, and reading them in
  // the sweep's inner loop would be mostly cache misses.
  struct Box {
    double lo[3], hi[3];
    std::uint32_t id, material;
    bool transmissive;
  };
  std::vector<Box> boxes;
  for (std::size_t first = 0, last = 0; first < entries.size() && within_limits; first = last) {
    last = first + 1;
    while (last < entries.size() && entries[last].key == entries[first].key) ++last;
    if (last - first < 2) continue;
    boxes.clear();
    for (std::size_t e = first; e < last; ++e) {
      const std::uint32_t id = entries[e].id;
      const Tri& t = tris[id];
      boxes.push_back(Box{{t.lo[0], t.lo[1], t.lo[2]}, {t.hi[0], t.hi[1], t.hi[2]}, id, t.material, t.transmissive});
    }
    std::sort(boxes.begin(), boxes.end(), [](const Box& a, const Box& b) { return a.lo[0] < b.lo[0]; });
    for (std::size_t x = 0; x < boxes.size() && within_limits; ++x) {
      const Box& a = boxes[x];
      for (std::size_t y = x + 1; y < boxes.size() && boxes[y].lo[0] <= a.hi[0]; ++y) {
        if (++comparisons > limits.comparisons || seen.size() >= limits.exact_tests) {
          within_limits = false;
          break;
        }
        const Box& b = boxes[y];
        if (a.id == b.id) continue;
        if (!tie_break_matters(a, b)) continue;
        if (b.lo[1] > a.hi[1] || b.hi[1] < a.lo[1] || b.lo[2] > a.hi[2] || b.hi[2] < a.lo[2]) continue;
        const std::uint32_t i = std::min(a.id, b.id), j = std::max(a.id, b.id);
        if (!seen.insert(std::uint64_t(i) << 32 | j).second) continue;
        const Tri ta = tris[i], tb = aligned(j, tris[i]);
        if (!coplanar(ta, tb, tol_d)) continue;
        Candidate c;
        c.area = overlap_area(ta, tb, c.probes);
        const double tiny = kMinAreaOffsets * std::max(ta.offset, tb.offset);
        if (!(c.area > kMinAreaShare * std::min(ta.area, tb.area)) || !(c.area > tiny * tiny)) continue;
        c.n = ta.n;
        c.offset = std::max(ta.offset, tb.offset);
        GroupId id{ta.mesh, ta.material, tb.mesh, tb.material};
        if (std::make_pair(tb.mesh, tb.material) < std::make_pair(ta.mesh, ta.material))
          id = GroupId{tb.mesh, tb.material, ta.mesh, ta.material};
        groups[id].push_back(std::move(c));
      }
    }
  }

  // A group is reported when a camera ray can get to one of its overlaps, from either side.
  // Probed: up to kProbesPerGroup points of its largest overlaps, the groups of largest area
  // first, within the limits' probe budget (a probe traces up to 65 rays, and as many again per
  // glass face they cross).
  constexpr std::size_t kProbesPerGroup = 8;
  std::vector<std::pair<CoplanarOverlap, const std::vector<Candidate>*>> order;
  for (auto& [id, cands] : groups) {
    std::sort(cands.begin(), cands.end(), [](const Candidate& a, const Candidate& b) { return a.area > b.area; });
    CoplanarOverlap o;
    o.at_close = close;
    std::tie(o.mesh_a, o.material_a, o.mesh_b, o.material_b) = id;
    o.pairs = cands.size();
    for (const Candidate& c : cands) o.area += c.area;
    order.emplace_back(o, &cands);
  }
  std::stable_sort(order.begin(), order.end(), [](const auto& a, const auto& b) { return a.first.area > b.first.area; });
  std::vector<CoplanarOverlap> out;
  std::size_t probes = 0;
  for (auto& [o, cands] : order) {
    bool hit = false;
    std::size_t mine = 0;
    for (const Candidate& c : *cands) {
      for (std::size_t q = 0; !hit && q < c.probes.size() && mine < kProbesPerGroup; ++q, ++mine) {
        if (++probes > limits.probes) {
          within_limits = false;
          break;
        }
        const D3& p = c.probes[q];
        hit = reachable(scene, p, c.n, c.offset, time) || reachable(scene, p, scaled(c.n, -1), c.offset, time);
        if (hit) o.where = rt::Vec3(float(p[0]), float(p[1]), float(p[2]));
      }
      if (hit || mine >= kProbesPerGroup || probes > limits.probes) break;
    }
    if (hit) out.push_back(o);
    if (probes > limits.probes) break;
  }
  std::sort(out.begin(), out.end(), [](const CoplanarOverlap& a, const CoplanarOverlap& b) { return a.area > b.area; });
  if (complete) *complete = within_limits;
  spdlog::debug("scene '{}': coplanar faces checked{}: {} triangles, {} comparisons, {} exact tests, {} overlapping "
                "groups, {} reachable{}, {:.3f} s",
                scene.name, close ? " where the shutter closes" : "", tris.size(), comparisons, seen.size(), groups.size(), out.size(),
                within_limits ? "" : " (stopped at the work limit)", clock.seconds());
  return out;
}

std::vector<CoplanarOverlap> find_coplanar_overlaps_over_shutter(const Scene& scene, bool* complete,
                                                                 CoplanarCheckLimits limits) {
  bool open_complete = true, close_complete = true;
  std::vector<CoplanarOverlap> out = find_coplanar_overlaps(scene, &open_complete, limits, ShutterEnd::kOpen);
  const bool moves = std::any_of(scene.meshes.begin(), scene.meshes.end(), [](const rt::Mesh& m) { return m.moving(); });
  if (moves) {
    std::set<std::tuple<unsigned, unsigned, unsigned, unsigned>> at_open;
    for (const CoplanarOverlap& o : out) at_open.insert(o.pair());
    for (const CoplanarOverlap& o : find_coplanar_overlaps(scene, &close_complete, limits, ShutterEnd::kClose))
      if (!at_open.count(o.pair())) out.push_back(o);
  }
  if (complete) *complete = open_complete && close_complete;
  return out;
}

std::string describe(const Scene& scene, const CoplanarOverlap& o) {
  auto mesh = [&](unsigned m) { return scene.meshes[m].name.empty() ? fmt::format("#{}", m) : scene.meshes[m].name; };
  auto material = [&](unsigned m) { return scene.materials[m].name; };
  const std::string what = o.mesh_a == o.mesh_b ? fmt::format("mesh '{}'", mesh(o.mesh_a))
                                                : fmt::format("meshes '{}' and '{}'", mesh(o.mesh_a), mesh(o.mesh_b));
  return fmt::format(
      "scene '{}': {} {} faces of materials '{}' and '{}' in one plane that overlap{} ({} triangle pair{}, area "
      "{:.3g}, e.g. at ({:.4g}, {:.4g}, {:.4g})): which surface a ray meets there is the ray tracer's tie-break, so "
      "images there depend on its kernels and disagree with other renderers; move one off the other (a few "
      "millimetres in a scene in metres)",
      scene.name, what, o.mesh_a == o.mesh_b ? "has" : "have", material(o.material_a), material(o.material_b),
      o.at_close ? " where the shutter closes (as they move)" : "", o.pairs, o.pairs == 1 ? "" : "s", o.area,
      o.where.x, o.where.y, o.where.z);
}

}  // namespace dnb
