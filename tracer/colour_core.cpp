// The vectorised path tracer of colour_core.h (the go/no-go experiment of docs/speed.md).
// Written with std::experimental::simd (libstdc++'s Parallelism TS 2) so that one
// kernel serves 8 and 16 lanes; Embree's packet entry points trace the lanes' rays.
#include "tracer/colour_core.h"

#include <embree3/rtcore.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <experimental/simd>
#include <stdexcept>

#include "tracer/integrator.h"
#include "tracer/math.h"

namespace dnb {

namespace stdx = std::experimental;

struct ColourCore::Data {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  Data() = default;
  Data(const Data&) = delete;
  Data& operator=(const Data&) = delete;
  ~Data() {  // also when the constructor below throws part-way
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
  std::vector<std::uint32_t> prim_base;   // per mesh: index of its first triangle among all
  std::vector<std::int32_t> material;     // per triangle
  std::vector<float> sel_over_area;       // per triangle: light selection probability / area
  std::vector<float> albedo[3], emission[3], two_sided;  // per material
  // Emissive triangles, in Scene::commit's order and with its selection probabilities.
  std::vector<float> cdf, p0[3], e1[3], e2[3], normal[3], sel_over_area_e, em[3], two_sided_e;
  float total = 0;
};

std::string ColourCore::supported(const Scene& scene) {
  if (scene.sky.enabled || scene.sun.enabled) return "the scene has a sky or a sun";
  if (!scene.sphere_lights.empty()) return "the scene has sphere lights";
  if (scene.camera.timed() || scene.camera.has_lens()) return "the camera has a shutter, motion or a lens";
  for (const rt::Material& m : scene.materials) {
    if (m.type != rt::MaterialType::kDiffuse) return "material '" + m.name + "' is not diffuse";
    if (m.texture >= 0 || m.normal_map >= 0 || m.opacity >= 0 || m.roughness_map >= 0)
      return "material '" + m.name + "' has a texture or map";
    if (!rt::is_black(m.absorption)) return "material '" + m.name + "' absorbs";
  }
  for (const rt::Mesh& mesh : scene.meshes)
    if (mesh.moving()) return "a mesh moves";
  return {};
}

ColourCore::ColourCore(const Scene& scene, const Options& options) : scene_(scene), opt_(options) {
  if (const std::string why = supported(scene); !why.empty())
    throw std::invalid_argument("ColourCore: " + why);
  if (opt_.lanes != 8 && opt_.lanes != 16) throw std::invalid_argument("ColourCore: lanes must be 8 or 16");
  data_ = std::make_unique<Data>();
  Data& d = *data_;
  for (const rt::Material& m : scene.materials) {
    for (int c = 0; c < 3; ++c) {
      d.albedo[c].push_back(m.albedo[c]);
      d.emission[c].push_back(m.emission[c]);
    }
    d.two_sided.push_back(m.two_sided ? 1.0f : 0.0f);
  }
  d.device = rtcNewDevice(opt_.embree_config);
  if (!d.device)
    throw std::invalid_argument(std::string("ColourCore: Embree refused the configuration '") + opt_.embree_config + "'");
  d.scene = rtcNewScene(d.device);
  rtcSetSceneBuildQuality(d.scene, RTC_BUILD_QUALITY_HIGH);  // as Scene::commit
  // Emitters chosen as Scene::commit chooses them: half by power, half uniformly over groups
  // (each mesh with emissive triangles is a group), by power within a group.
  std::vector<double> power, group_power;
  std::vector<int> group;
  std::vector<std::uint32_t> emitter_tri;
  std::uint32_t base = 0;
  for (std::size_t gi = 0; gi < scene.meshes.size(); ++gi) {
    const rt::Mesh& m = scene.meshes[gi];
    d.prim_base.push_back(base);
    const std::size_t n = m.triangles();
    RTCGeometry g = rtcNewGeometry(d.device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 3 * n));
    auto* idx = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), n));
    int grp = -1;
    for (std::size_t t = 0; t < n; ++t) {
      for (int k = 0; k < 3; ++k) {
        const rt::Vec3 p = m.positions[3 * t + std::size_t(k)];
        v[9 * t + 3 * std::size_t(k)] = p.x;
        v[9 * t + 3 * std::size_t(k) + 1] = p.y;
        v[9 * t + 3 * std::size_t(k) + 2] = p.z;
        idx[3 * t + std::size_t(k)] = unsigned(3 * t + std::size_t(k));
      }
      d.material.push_back(std::int32_t(m.material[t]));
      d.sel_over_area.push_back(0.0f);
      const rt::Material& mat = scene.materials[m.material[t]];
      if (!mat.is_emitter()) continue;
      const rt::Vec3 a = m.positions[3 * t], b = m.positions[3 * t + 1], c = m.positions[3 * t + 2];
      const float area = 0.5f * rt::length(rt::cross(b - a, c - a));
      const float w = rt::luminance(mat.emission) * area * rt::kPi * (mat.two_sided ? 2.0f : 1.0f);
      if (!(area > 0) || !(w > 0)) continue;
      if (grp < 0) {
        grp = int(group_power.size());
        group_power.push_back(0);
      }
      power.push_back(w);
      group.push_back(grp);
      group_power[std::size_t(grp)] += w;
      emitter_tri.push_back(base + std::uint32_t(t));
      const rt::Vec3 nrm = rt::normalize(rt::cross(b - a, c - a));
      for (int k = 0; k < 3; ++k) {
        d.p0[k].push_back(a[k]);
        d.e1[k].push_back((b - a)[k]);
        d.e2[k].push_back((c - a)[k]);
        d.normal[k].push_back(nrm[k]);
        d.em[k].push_back(mat.emission[k]);
      }
      d.two_sided_e.push_back(mat.two_sided ? 1.0f : 0.0f);
      d.sel_over_area_e.push_back(area);  // divided below, once the probability is known
    }
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(d.scene, g, unsigned(gi));
    rtcReleaseGeometry(g);
    base += std::uint32_t(n);
  }
  rtcCommitScene(d.scene);
  double total = 0;
  for (double w : power) total += w;
  double acc = 0;
  for (std::size_t i = 0; i < power.size(); ++i) {
    const float p = float(0.5 * power[i] / total + 0.5 / double(group_power.size()) * power[i] /
                                                        group_power[std::size_t(group[i])]);
    acc += p;
    d.cdf.push_back(float(acc));
    d.sel_over_area_e[i] = p / d.sel_over_area_e[i];
    d.sel_over_area[emitter_tri[i]] = d.sel_over_area_e[i];
  }
  d.total = float(acc);
  if (d.cdf.empty()) throw std::invalid_argument("ColourCore: the scene has no emissive triangle");
}

ColourCore::~ColourCore() = default;

namespace {

template <int N>
struct Packet;
template <>
struct Packet<8> {
  using RayHit = RTCRayHit8;
  using Ray = RTCRay8;
  static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) { rtcIntersect8(valid, s, c, r); }
  static void occluded(const int* valid, RTCScene s, RTCIntersectContext* c, Ray* r) { rtcOccluded8(valid, s, c, r); }
};
template <>
struct Packet<16> {
  using RayHit = RTCRayHit16;
  using Ray = RTCRay16;
  static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) { rtcIntersect16(valid, s, c, r); }
  static void occluded(const int* valid, RTCScene s, RTCIntersectContext* c, Ray* r) { rtcOccluded16(valid, s, c, r); }
};

// Random numbers: a counter-based generator, number c of a path being hash(hash(c * golden +
// key_lo) ^ key_hi), with the path's 64-bit key (its seed, pixel and sample index, mixed by
// rt::mix64) and the 32-bit integer hash "lowbias32" (Wellons' hash-prospector: two multiplies,
// three shifts, full avalanche), written once for scalars and vectors. Each path's numbers hang
// on its own 64-bit key, not on a 32-bit generator state: a frame's 5e7 paths on a cycle of 2^32
// states would start some 3e5 pairs of paths on the same state and many more on overlapping
// streams, and its means would scatter more than their standard errors allow (measured).
template <typename T>
[[gnu::always_inline]] inline T lowbias32(T x) {
  x ^= x >> 16u;
  x *= 0x7feb352du;
  x ^= x >> 15u;
  x *= 0x846ca68bu;
  x ^= x >> 16u;
  return x;
}

template <typename T>
[[gnu::always_inline]] inline T draw(T& counter, const T& key_lo, const T& key_hi) {
  const T x = lowbias32(T(lowbias32(T(counter * 0x9e3779b9u + key_lo)) ^ key_hi));
  counter += 1u;
  return x;
}

constexpr std::uint64_t kGolden = 0x9e3779b97f4a7c15ull;  // SplitMix64's increment

// Lane k of a packet's rays as a single ray (Trace::kSingleRays).
template <typename PacketRay>
RTCRay lane_ray(const PacketRay& r, int k) {
  RTCRay one;
  one.org_x = r.org_x[k];
  one.org_y = r.org_y[k];
  one.org_z = r.org_z[k];
  one.dir_x = r.dir_x[k];
  one.dir_y = r.dir_y[k];
  one.dir_z = r.dir_z[k];
  one.tnear = r.tnear[k];
  one.tfar = r.tfar[k];
  one.time = r.time[k];
  one.mask = r.mask[k];
  one.id = r.id[k];
  one.flags = r.flags[k];
  return one;
}

// Where a lane's random numbers come from: at(slot, depth) is each lane's number for `slot`
// (dims::) of its current vertex, start(lane, item, key, jx, jy) begins a path and gives its film
// position inside the pixel.
// Independent numbers (Options::Numbers::kIndependent): number c of a path is draw(c, key), in
// the order the kernel asks (slots are ignored), eight lanes at a time.
template <int N>
struct HashRandom {
  using F = stdx::simd<float, stdx::simd_abi::deduce_t<float, N>>;
  using U = stdx::simd<std::uint32_t, stdx::simd_abi::deduce_t<std::uint32_t, N>>;
  using I = stdx::simd<std::int32_t, stdx::simd_abi::deduce_t<std::int32_t, N>>;
  std::uint64_t seed;
  U counter = 0, lo = 0, hi = 0;
  explicit HashRandom(std::uint64_t s) : seed(s) {}
  void start(int k, std::int64_t, std::uint64_t key, float& jx, float& jy) {
    const std::uint64_t h = rt::mix64((rt::mix64(key + kGolden) ^ seed) + kGolden);
    std::uint32_t c = 0;
    const std::uint32_t l = std::uint32_t(h), u = std::uint32_t(h >> 32);
    jx = float(draw(c, l, u) >> 8) * 0x1p-24f;
    jy = float(draw(c, l, u) >> 8) * 0x1p-24f;
    counter[k] = c;
    lo[k] = l;
    hi[k] = u;
  }
  [[gnu::always_inline]] F at(int, const F&) {
    return stdx::static_simd_cast<F>(stdx::static_simd_cast<I>(draw(counter, lo, hi) >> 8u)) * 0x1p-24f;
  }
};

// The tracer's own numbers (Options::Numbers::kTracer): sample s of pixel p reads what
// rt::Sampler gives it (the Owen-scrambled Sobol' points of render.cpp's top, in the slots
// PathTracer reads), vectorised: a path's start copies the sequence slots of its first two
// vertices from its pixel's SampleTable into the lanes (the table already holds them), and the
// hashed numbers (later vertices, roulette) are rt::Sampler's hash of the sample's key and the
// dimension, eight 64-bit lanes at a time. tests: the case's check that the core's paths are the
// tracer's (every colour value within 1e-4).
template <int N>
struct TableRandom {
  using F = stdx::simd<float, stdx::simd_abi::deduce_t<float, N>>;
  using I = stdx::simd<std::int32_t, stdx::simd_abi::deduce_t<std::int32_t, N>>;
  using Q = stdx::simd<std::uint64_t, stdx::simd_abi::deduce_t<std::uint64_t, N>>;
  static constexpr int kSlots = rt::dims::kSequenceSlots;
  const rt::SampleTable* tables;
  int spp;
  std::vector<std::uint64_t> group_keys;  // per pixel of the call and group
  F seq[2][kSlots];                       // per vertex 1, 2 and slot: each lane's number
  Q sample_key = 0;
  TableRandom(const rt::SampleTable* t, int n, std::uint64_t seed, std::uint64_t pixel0, int count)
      : tables(t), spp(n), group_keys(std::size_t(count) * rt::Sampler::kGroups) {
    for (int p = 0; p < count; ++p) {
      const std::uint64_t pk = rt::Sampler::pixel_key(seed, pixel0 + std::uint64_t(p));
      for (int g = 0; g < rt::Sampler::kGroups; ++g)
        group_keys[std::size_t(p) * rt::Sampler::kGroups + std::size_t(g)] = rt::Sampler::group_key(pk, g);
    }
  }
  void start(int k, std::int64_t item, std::uint64_t, float& jx, float& jy) {
    const std::int64_t p = item / spp, s = item % spp;
    rt::Sampler q = tables[p].sampler(std::uint64_t(s));
    jx = q.next();  // render_pass::sample_position's two numbers
    jy = q.next();
    for (int v = 1; v <= 2; ++v) {
      q.start_vertex(v);
      for (int slot = 0; slot < kSlots; ++slot) seq[v - 1][slot][k] = q.at(slot);
    }
    sample_key[k] = rt::Sampler::sample_key(
        group_keys[std::size_t(p) * rt::Sampler::kGroups + std::size_t(s % rt::Sampler::kGroups)],
        std::uint64_t(s / rt::Sampler::kGroups));
  }
  // rt::Sampler::dimension_value's hashed numbers, for dimension 2 + 8 (depth - 1) + slot.
  F hashed(int slot, const F& depth) const {
    const I d = stdx::static_simd_cast<I>(depth) * rt::dims::kVertexDims + (rt::dims::kFilmDims - rt::dims::kVertexDims + slot);
    Q z = sample_key + stdx::static_simd_cast<Q>(d) * 0xd1b54a32d192ed03ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;  // rt::mix64
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z = z ^ (z >> 31);
    return stdx::static_simd_cast<F>(stdx::static_simd_cast<I>(z >> 40)) * (1.0f / 16777216.0f);
  }
  F at(int slot, const F& depth) const {
    if (slot >= kSlots) return hashed(slot, depth);
    F v = 0;
    if (stdx::any_of(depth > 2.0f)) v = hashed(slot, depth);
    stdx::where(depth == 1.0f, v) = seq[0][slot];
    stdx::where(depth == 2.0f, v) = seq[1][slot];
    return v;
  }
};

// What a path leaves when it ends: its sample's level-0 layers (PathTracer::decompose for a
// diffuse first hit; all zero but the emission where the camera ray escapes).
struct PathEnd {
  float emission[3], direct[3], indirect[3], albedo[3], normal[3], depth;
};

// Traces job.items() paths, N at a time, on the calling thread. Job: items(); start(item, x, y,
// key): the item's pixel and the key of its random numbers; end(item, PathEnd). Random: a
// HashRandom or TableRandom. Returns the rays.
template <int N, typename Job, typename Random>
std::uint64_t run_lanes(const ColourCore::Data& d, const Scene& scene, const ColourCore::Options& opt, Job& job,
                        Random& rnd) {
  // The native vector types of N lanes (fixed_size_simd's element-wise helpers were not inlined
  // by GCC 12 here and cost a fifth of the render).
  using F = stdx::simd<float, stdx::simd_abi::deduce_t<float, N>>;
  using I = stdx::simd<std::int32_t, stdx::simd_abi::deduce_t<std::int32_t, N>>;
  using M = typename F::mask_type;
  using P = Packet<N>;
  static_assert(F::size() == N && I::size() == N);
  const int W = opt.width, H = opt.height;

  // Every lane's index is valid (0 where a lane has nothing to look up), so loads need no mask.
  auto gather = [](const std::vector<float>& v, const I& i) __attribute__((always_inline)) {
    const float* base = v.data();
    return F([&](auto k) { return base[i[k]]; });
  };
  auto power = [](const F& a, const F& b) __attribute__((always_inline)) {
    const F a2 = a * a, s = a2 + b * b;
    F r = a2 / s;
    stdx::where(!(s > 0), r) = 0.0f;
    return r;
  };
  auto add3 = [](const M& m, F* acc, const F& r, const F& g, const F& b) __attribute__((always_inline)) {
    stdx::where(m, acc[0]) = acc[0] + r;
    stdx::where(m, acc[1]) = acc[1] + g;
    stdx::where(m, acc[2]) = acc[2] + b;
  };

  const std::int64_t items = job.items();
  std::int64_t next = 0;
  std::uint64_t rays = 0;
  // Per lane: the ray, the throughput past the first hit (beta: white at the first hit, as the
  // tracer's D and I are), the first hit's albedo, normal and distance, and the three sums.
  F ox = 0, oy = 0, oz = 0, dx = 0, dy = 0, dz = 1, prev_pdf = 0;
  F prev_x = 0, prev_y = 0, prev_z = 0;  // the previous vertex's point (the path's last hit)
  F beta[3] = {1, 1, 1}, a1[3] = {0, 0, 0}, n1[3] = {0, 0, 0}, t1 = 0;
  F em[3] = {0, 0, 0}, dir[3] = {0, 0, 0}, ind[3] = {0, 0, 0};
  F depth = 0;  // vertices so far (small whole numbers: exact in floats, and no mask conversions)
  M active(false);
  std::int64_t item[N] = {};
  alignas(64) typename P::RayHit rh;
  alignas(64) typename P::Ray sh;
  alignas(64) int valid[N];
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);

  auto finish = [&](const M& m) {
    for (int k = 0; k < N; ++k) {
      if (!m[k]) continue;
      PathEnd e;
      for (int c = 0; c < 3; ++c) {
        e.emission[c] = em[c][k];
        e.direct[c] = dir[c][k];
        e.indirect[c] = ind[c][k];
        e.albedo[c] = a1[c][k];
        e.normal[c] = n1[c][k];
      }
      e.depth = t1[k];
      job.end(item[k], e);
    }
    active = active && !m;
  };

  for (;;) {
    // Regenerate: every idle lane starts the next path.
    for (int k = 0; k < N && next < items; ++k) {
      if (active[k]) continue;
      const std::int64_t it = next++;
      item[k] = it;
      int x = 0, y = 0;
      std::uint64_t key = 0;
      job.start(it, x, y, key);
      float jx, jy;
      rnd.start(k, it, key, jx, jy);
      const rt::Ray r = scene.camera.generate_ray(float(x) + jx, float(y) + jy, W, H);
      ox[k] = r.origin.x;
      oy[k] = r.origin.y;
      oz[k] = r.origin.z;
      dx[k] = r.dir.x;
      dy[k] = r.dir.y;
      dz[k] = r.dir.z;
      for (int c = 0; c < 3; ++c) {
        beta[c][k] = 1.0f;
        a1[c][k] = n1[c][k] = em[c][k] = dir[c][k] = ind[c][k] = 0.0f;
      }
      t1[k] = 0.0f;
      prev_pdf[k] = 0.0f;
      depth[k] = 0;
      active[k] = true;
    }
    if (stdx::none_of(active)) break;

    // Closest hits of the active lanes' rays.
    for (int k = 0; k < N; ++k) valid[k] = active[k] ? -1 : 0;
    ox.copy_to(rh.ray.org_x, stdx::element_aligned);
    oy.copy_to(rh.ray.org_y, stdx::element_aligned);
    oz.copy_to(rh.ray.org_z, stdx::element_aligned);
    dx.copy_to(rh.ray.dir_x, stdx::element_aligned);
    dy.copy_to(rh.ray.dir_y, stdx::element_aligned);
    dz.copy_to(rh.ray.dir_z, stdx::element_aligned);
    for (int k = 0; k < N; ++k) {
      rh.ray.tnear[k] = 0.0f;
      rh.ray.tfar[k] = 1e30f;
      rh.ray.time[k] = 0.0f;
      rh.ray.mask[k] = ~0u;
      rh.ray.id[k] = 0;
      rh.ray.flags[k] = 0;
      rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
    }
    rays += std::uint64_t(stdx::popcount(active));
    if (opt.trace == ColourCore::Trace::kPackets) {
      P::intersect(valid, d.scene, &ctx, &rh);
    } else {
      for (int k = 0; k < N; ++k) {
        if (!valid[k]) continue;
        RTCRayHit one;
        one.ray = lane_ray(rh.ray, k);
        one.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(d.scene, &ctx, &one);
        rh.ray.tfar[k] = one.ray.tfar;
        rh.hit.Ng_x[k] = one.hit.Ng_x;
        rh.hit.Ng_y[k] = one.hit.Ng_y;
        rh.hit.Ng_z[k] = one.hit.Ng_z;
        rh.hit.primID[k] = one.hit.primID;
        rh.hit.geomID[k] = one.hit.geomID;
      }
    }
    F t;
    t.copy_from(rh.ray.tfar, stdx::element_aligned);
    const M hit = active && t < 1e30f;  // Embree leaves tfar as it was on a miss
    finish(active && !hit);             // escaped: the core's scenes have no sky
    if (stdx::none_of(hit)) continue;

    const I tri([&](auto k) { return hit[k] ? int(d.prim_base[rh.hit.geomID[k]] + rh.hit.primID[k]) : 0; });
    const I mat([&](auto k) { return hit[k] ? d.material[std::size_t(tri[k])] : 0; });
    F nx, ny, nz;
    nx.copy_from(rh.hit.Ng_x, stdx::element_aligned);
    ny.copy_from(rh.hit.Ng_y, stdx::element_aligned);
    nz.copy_from(rh.hit.Ng_z, stdx::element_aligned);
    const F inv_len = 1.0f / stdx::sqrt(nx * nx + ny * ny + nz * nz);
    nx *= inv_len;
    ny *= inv_len;
    nz *= inv_len;
    const F cos_o = nx * dx + ny * dy + nz * dz;  // < 0: the front (winding) side
    const M front = cos_o < 0;
    stdx::where(!front, nx) = -nx;  // facing the ray's origin
    stdx::where(!front, ny) = -ny;
    stdx::where(!front, nz) = -nz;
    const F px = ox + t * dx, py = oy + t * dy, pz = oz + t * dz;
    depth += 1;
    const M first = hit && depth == 1.0f;  // the first hit: level 0's vertex
    stdx::where(first, n1[0]) = nx;
    stdx::where(first, n1[1]) = ny;
    stdx::where(first, n1[2]) = nz;
    stdx::where(first, t1) = t;

    // Emission: the first hit's is E (no weight); later, weighted against the light sample that
    // could have found it, into D at the second vertex (the continuation's first emission) and
    // I after.
    {
      const F er = gather(d.emission[0], mat), eg = gather(d.emission[1], mat), eb = gather(d.emission[2], mat);
      const M seen = hit && (front || gather(d.two_sided, mat) > 0) && (er + eg + eb > 0);
      if (stdx::any_of(seen)) {
        const F sel = F([&](auto k) { return seen[k] ? d.sel_over_area[std::size_t(tri[k])] : 0.0f; });
        // From the previous vertex's point as PathTracer::trace keeps it (below), not the ray's
        // origin: they differ by the offset, which shows where a light is a centimetre from a wall.
        const F qx = px - prev_x, qy = py - prev_y, qz = pz - prev_z;
        const F dist2 = qx * qx + qy * qy + qz * qz;
        const F light_pdf = sel * dist2 / (stdx::abs(nx * qx + ny * qy + nz * qz) / stdx::sqrt(dist2));
        F w = power(prev_pdf, light_pdf);
        stdx::where(!(prev_pdf > 0), w) = 1.0f;
        const F wr = beta[0] * er * w, wg = beta[1] * eg * w, wb = beta[2] * eb * w;
        add3(seen && first, em, wr, wg, wb);
        add3(seen && depth == 2.0f, dir, wr, wg, wb);
        add3(seen && depth > 2.0f, ind, wr, wg, wb);
      }
    }
    M alive = hit && depth < float(opt.max_depth);
    finish(hit && !alive);
    const F ar = gather(d.albedo[0], mat), ag = gather(d.albedo[1], mat), ab = gather(d.albedo[2], mat);
    stdx::where(first, a1[0]) = ar;
    stdx::where(first, a1[1]) = ag;
    stdx::where(first, a1[2]) = ab;
    // Russian roulette after rr_depth vertices, on the whole path's throughput (the first
    // albedo included, as PathTracer::trace's path_weight).
    {
      const M rr = alive && depth > float(opt.rr_depth);
      if (stdx::any_of(rr)) {
        const F u = rnd.at(rt::dims::kRoulette, depth);
        const F q = stdx::min(F(0.95f), stdx::max(beta[0] * a1[0], stdx::max(beta[1] * a1[1], beta[2] * a1[2])));
        const M killed = rr && (!(q > 0) || u >= q);
        finish(killed);
        alive = alive && !killed;
        const M kept = rr && !killed;
        for (int c = 0; c < 3; ++c) stdx::where(kept, beta[c]) = beta[c] / q;
      }
    }
    if (stdx::none_of(alive)) continue;

    // The surface's weight on this vertex's light: white at the first hit (D and I are for a
    // white surface), the albedo after.
    F fr = ar, fg = ag, fb = ab;
    stdx::where(first, fr) = 1.0f;
    stdx::where(first, fg) = 1.0f;
    stdx::where(first, fb) = 1.0f;
    const F off = 1e-4f * stdx::max(F(1.0f), stdx::max(stdx::abs(px), stdx::max(stdx::abs(py), stdx::abs(pz))));
    // Next-event estimation: one emissive triangle, one point on it; into D at the first hit,
    // I after.
    const F u0 = rnd.at(rt::dims::kLightChoice, depth), u1 = rnd.at(rt::dims::kLightU, depth),
            u2 = rnd.at(rt::dims::kLightV, depth);
    // The emitter: the first whose cumulative probability exceeds u0 * total (upper_bound), by
    // counting the entries at or below the target where they are few.
    I e = 0;
    {
      const F target = u0 * d.total;
      const int ne = int(d.cdf.size());
      if (ne <= 16) {
        F count = 0;
        for (int j = 0; j < ne - 1; ++j) stdx::where(target >= d.cdf[std::size_t(j)], count) = count + 1.0f;
        e = stdx::static_simd_cast<I>(count);
      } else {
        e = I([&](auto k) {
          const std::size_t i = std::size_t(std::upper_bound(d.cdf.begin(), d.cdf.end(), float(target[k])) - d.cdf.begin());
          return int(std::min(i, d.cdf.size() - 1));
        });
      }
    }
    const F su = stdx::sqrt(u1), b1 = 1.0f - su, b2 = u2 * su;
    const F qx = gather(d.p0[0], e) + gather(d.e1[0], e) * b1 + gather(d.e2[0], e) * b2;
    const F qy = gather(d.p0[1], e) + gather(d.e1[1], e) * b1 + gather(d.e2[1], e) * b2;
    const F qz = gather(d.p0[2], e) + gather(d.e1[2], e) * b1 + gather(d.e2[2], e) * b2;
    F wx = qx - px, wy = qy - py, wz = qz - pz;
    const F dist2 = wx * wx + wy * wy + wz * wz, dist = stdx::sqrt(dist2);
    wx /= dist;
    wy /= dist;
    wz /= dist;
    F cos_l = -(gather(d.normal[0], e) * wx + gather(d.normal[1], e) * wy + gather(d.normal[2], e) * wz);
    stdx::where(cos_l < 0 && gather(d.two_sided_e, e) > 0, cos_l) = -cos_l;
    const F cos_s = wx * nx + wy * ny + wz * nz;
    const M lit = alive && dist2 > 0 && cos_l >= 1e-7f && cos_s > 0;
    if (stdx::any_of(lit)) {
      const F pdf = gather(d.sel_over_area_e, e) * dist2 / cos_l;
      const F bsdf_pdf = cos_s * rt::kInvPi;
      const F k = cos_s * rt::kInvPi * power(pdf, bsdf_pdf) / pdf;
      const F cr = beta[0] * fr * gather(d.em[0], e) * k, cg = beta[1] * fg * gather(d.em[1], e) * k,
              cb = beta[2] * fb * gather(d.em[2], e) * k;
      for (int k2 = 0; k2 < N; ++k2) valid[k2] = lit[k2] ? -1 : 0;
      (px + nx * off).copy_to(sh.org_x, stdx::element_aligned);
      (py + ny * off).copy_to(sh.org_y, stdx::element_aligned);
      (pz + nz * off).copy_to(sh.org_z, stdx::element_aligned);
      wx.copy_to(sh.dir_x, stdx::element_aligned);
      wy.copy_to(sh.dir_y, stdx::element_aligned);
      wz.copy_to(sh.dir_z, stdx::element_aligned);
      (dist * (1 - 1e-4f) - off).copy_to(sh.tfar, stdx::element_aligned);
      for (int k2 = 0; k2 < N; ++k2) {
        sh.tnear[k2] = 0.0f;
        sh.time[k2] = 0.0f;
        sh.mask[k2] = ~0u;
        sh.id[k2] = 0;
        sh.flags[k2] = 0;
      }
      rays += std::uint64_t(stdx::popcount(lit));
      if (opt.trace == ColourCore::Trace::kPackets) {
        P::occluded(valid, d.scene, &ctx, &sh);
      } else {
        for (int k2 = 0; k2 < N; ++k2) {
          if (!valid[k2]) continue;
          RTCRay one = lane_ray(sh, k2);
          rtcOccluded1(d.scene, &ctx, &one);
          sh.tfar[k2] = one.tfar;
        }
      }
      F tf;
      tf.copy_from(sh.tfar, stdx::element_aligned);
      const M seen = lit && tf >= 0;  // Embree sets tfar to -inf where the ray is blocked
      add3(seen && first, dir, cr, cg, cb);
      add3(seen && !first, ind, cr, cg, cb);
    }
    // The next direction: cosine-weighted about the facing normal (f cos / pdf = albedo).
    const F v1 = rnd.at(rt::dims::kBsdfU, depth), v2 = rnd.at(rt::dims::kBsdfV, depth);
    const F r = stdx::sqrt(v1), phi = 2.0f * rt::kPi * v2;
    const F lx = r * stdx::cos(phi), ly = r * stdx::sin(phi), lz = stdx::sqrt(stdx::max(F(0.0f), 1.0f - v1));
    F sign = 1.0f;
    stdx::where(stdx::signbit(nz), sign) = -1.0f;  // rt::Frame's copysign
    const F a = -1.0f / (sign + nz), bxy = nx * ny * a;
    const F tx = 1.0f + sign * nx * nx * a, ty = sign * bxy, tz = -sign * nx;
    const F sx = bxy, sy = sign + ny * ny * a, sz = -ny;
    const F nwx = tx * lx + sx * ly + nx * lz, nwy = ty * lx + sy * ly + ny * lz, nwz = tz * lx + sz * ly + nz * lz;
    stdx::where(alive, beta[0]) = beta[0] * fr;
    stdx::where(alive, beta[1]) = beta[1] * fg;
    stdx::where(alive, beta[2]) = beta[2] * fb;
    // A black throughput ends the path; the first hit's albedo is not part of it (D and I are
    // for a white surface, also on a black one), as in PathTracer::trace.
    const M ended = alive && (lz <= 1e-7f || (beta[0] <= 0 && beta[1] <= 0 && beta[2] <= 0));
    finish(ended);
    alive = alive && !ended;
    stdx::where(alive, prev_pdf) = lz * rt::kInvPi;
    // PathTracer::trace starts its previous point at the continuation's ray origin (the first
    // hit's point offset off the surface) and moves it to each hit's point after: the same here.
    stdx::where(alive, prev_x) = px;
    stdx::where(alive, prev_y) = py;
    stdx::where(alive, prev_z) = pz;
    stdx::where(alive && first, prev_x) = px + nx * off;
    stdx::where(alive && first, prev_y) = py + ny * off;
    stdx::where(alive && first, prev_z) = pz + nz * off;
    stdx::where(alive, ox) = px + nx * off;
    stdx::where(alive, oy) = py + ny * off;
    stdx::where(alive, oz) = pz + nz * off;
    stdx::where(alive, dx) = nwx;
    stdx::where(alive, dy) = nwy;
    stdx::where(alive, dz) = nwz;
  }
  return rays;
}

template <template <int> class Random, typename Job, typename... A>
std::uint64_t run_lanes_n(int lanes, const ColourCore::Data& d, const Scene& scene, const ColourCore::Options& opt,
                          Job& job, A... random_args) {
  if (lanes == 16) {
    Random<16> rnd(random_args...);
    return run_lanes<16>(d, scene, opt, job, rnd);
  }
  Random<8> rnd(random_args...);
  return run_lanes<8>(d, scene, opt, job, rnd);
}

}  // namespace

std::vector<float> ColourCore::render(double* rays_out) const {
  if (opt_.numbers != Numbers::kIndependent)
    throw std::invalid_argument("ColourCore::render: independent numbers only (the tracer's are per pixel)");
  const int W = opt_.width, H = opt_.height, spp = opt_.spp;
  std::vector<float> img(std::size_t(W) * std::size_t(H) * 3, 0.0f);
  constexpr int kRows = 4;  // rows per task: a fixed split, so the image does not depend on threads
  const int blocks = (H + kRows - 1) / kRows;
  std::atomic<std::uint64_t> ray_total{0};
  const float inv_spp = 1.0f / float(spp);
  // The paths of a block of rows, in pixel order, spp to a pixel; each ends in its pixel's colour.
  struct RowsJob {
    int W, spp, y0, y1;
    float inv_spp;
    float* img;
    std::int64_t items() const { return std::int64_t(y1 - y0) * W * spp; }
    void start(std::int64_t it, int& x, int& y, std::uint64_t& key) const {
      const std::int64_t pix = it / spp;
      x = int(pix % W);
      y = y0 + int(pix / W);
      key = (std::uint64_t(y) * std::uint64_t(W) + std::uint64_t(x)) * std::uint64_t(spp) + std::uint64_t(it % spp);
    }
    void end(std::int64_t it, const PathEnd& e) const {
      float* px = img + 3 * (std::size_t(y0) * std::size_t(W) + std::size_t(it / spp));
      for (int c = 0; c < 3; ++c)
        px[c] += ((e.direct[c] + e.indirect[c]) * e.albedo[c] + e.emission[c]) * inv_spp;  // LevelSample::color
    }
  };
  tbb::parallel_for(0, blocks, [&](int block) {
    RowsJob job{W, spp, block * kRows, std::min(H, block * kRows + kRows), inv_spp, img.data()};
    ray_total += run_lanes_n<HashRandom>(opt_.lanes, *data_, scene_, opt_, job, opt_.seed);
  });
  if (rays_out) *rays_out = double(ray_total.load());
  return img;
}

std::uint64_t ColourCore::trace_pixels(int x0, int y, int count, int spp, rt::SampleResult* out) const {
  // Samples s of pixels x0 .. x0 + count - 1 of row y, in that order; each ends in its SampleResult.
  struct PixelsJob {
    int W, x0, y, count, spp;
    rt::SampleResult* out;
    std::int64_t items() const { return std::int64_t(count) * spp; }
    void start(std::int64_t it, int& x, int& yy, std::uint64_t& key) const {
      x = x0 + int(it / spp);
      yy = y;
      key = (std::uint64_t(y) * std::uint64_t(W) + std::uint64_t(x)) * std::uint64_t(spp) + std::uint64_t(it % spp);
    }
    void end(std::int64_t it, const PathEnd& e) const {
      // Only what render_frame reads of a one-level sample: level 0, `levels` and the specular
      // parts (a whole SampleResult, nine levels, is over a kilobyte).
      rt::SampleResult& r = out[it];
      r.levels = 1;
      r.specular = rt::SpecularParts{};
      rt::LevelSample& l = r.level[0];
      l = rt::LevelSample{};
      l.present = true;
      l.direct = {e.direct[0], e.direct[1], e.direct[2]};
      l.indirect = {e.indirect[0], e.indirect[1], e.indirect[2]};
      l.albedo = {e.albedo[0], e.albedo[1], e.albedo[2]};
      l.emission = {e.emission[0], e.emission[1], e.emission[2]};
      l.normal = {e.normal[0], e.normal[1], e.normal[2]};
      l.depth = e.depth;
    }
  };
  PixelsJob job{opt_.width, x0, y, count, spp, out};
  if (opt_.numbers == Numbers::kIndependent)
    return run_lanes_n<HashRandom>(opt_.lanes, *data_, scene_, opt_, job, opt_.seed);
  if (spp > rt::SampleTable::kMaxSamples)
    throw std::invalid_argument("ColourCore: the tracer's numbers need spp <= " +
                                std::to_string(rt::SampleTable::kMaxSamples));
  thread_local std::vector<rt::SampleTable> tables;
  if (tables.size() < std::size_t(count)) tables.resize(std::size_t(count));
  for (int p = 0; p < count; ++p)
    tables[std::size_t(p)].prepare(opt_.seed, std::uint64_t(y) * std::uint64_t(opt_.width) + std::uint64_t(x0 + p), 0,
                                   std::uint64_t(spp));
  return run_lanes_n<TableRandom>(opt_.lanes, *data_, scene_, opt_, job, tables.data(), spp, opt_.seed,
                                  std::uint64_t(y) * std::uint64_t(opt_.width) + std::uint64_t(x0), count);
}

}  // namespace dnb
