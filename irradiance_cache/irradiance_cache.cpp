// irradiance_cache: a renderer-type method (the paper's "irradiance cache" column; Pharr and
// Humphreys' Ward-style cache with error-driven record spacing), rendering the scene itself
// with the shared tracer:
//   F = (D + I) * T + R + E
// - D: next-event estimation of direct light at the first diffuse hit, `direct_samples` light
//   samples per pixel sample (PathTracer::direct_white), like the tracer's D, stratified over
//   the lights and their surfaces (ic::LightStrata).
// - I: indirect diffuse light from the irradiance cache (irradiance_cache/cache.h): records from
//   stratified hemisphere gathers of paths traced by PathTracer::incoming (their first-hit
//   emission excluded: that light is in D), interpolated with gradients.
// - R: mirrors and coats are followed as in the path tracer; a coat's two lobes are both
//   followed with their Fresnel weights (the path tracer picks one at random: same expectation).
// - E: emission seen directly or through specular bounces.
//
// Passes (each reported as a phase):
//  1. overture: pixel centres on grids of stride overture_stride, /2, ... down to
//     overture_min_stride. In each pass the uncovered points gather in parallel against the
//     frozen cache, then are inserted one by one in pixel order (a point that an earlier
//     record of the same pass covers is dropped, its gather counted as wasted).
//  2. final: every pixel sample interpolates; a point that no record covers gathers a new
//     record kept in its tile's own cache (16 x 16 pixels), visible to that tile only.
// Determinism: every random number is a function of (seed, pixel or record key, sample), the
// overture inserts in a fixed order and the final pass reads the shared cache only, so the
// image is bit-identical for any thread count (tiles are fixed by the image size).
//
// Parameters: the ParamSpec list at the end of this file, the only place they are documented
// (`denoisebench list methods` prints it); how the defaults were chosen: docs/method-defaults.md.
#include <algorithm>
#include <atomic>
#include <cmath>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"
#include "denoisers/method.h"
#include "irradiance_cache/cache.h"
#include "irradiance_cache/irradiance_cache.h"
#include "tracer/bsdf.h"
#include "tracer/integrator.h"
#include "tracer/render.h"
#include "tracer/scene.h"

namespace dnb {
namespace {

using ic::IrradianceCache;
using rt::Ray;
using rt::SurfaceHit;
using rt::Vec3;

constexpr int kTile = 16;

// A diffuse (base-lobe) point reached from the camera, with the weight the camera sees it by.
struct ShadePoint {
  SurfaceHit hit;
  Vec3 weight;           // product of specular weights and the base lobe's weight (not the albedo)
  float path_length = 0; // distance from the camera along the (possibly reflected) path
};

class IrradianceCacheRenderer final : public Method {
 public:
  explicit IrradianceCacheRenderer(const Params& p)
      : pixel_samples_(p.i("pixel_samples")),
        direct_samples_(p.i("direct_samples")),
        M_(p.i("gather_theta_cells")),
        N_(p.i("gather_phi_cells")),
        min_spacing_(float(p.f("min_pixel_spacing"))),
        max_spacing_(float(p.f("max_pixel_spacing"))),
        stride_(p.i("overture_stride")),
        min_stride_(p.i("overture_min_stride")),
        max_depth_(p.i("max_depth")),
        gather_clamp_(float(p.f("gather_clamp"))) {
    cache_.kappa = float(p.f("kappa"));
    cache_.max_angle_degrees = float(p.f("max_angle_degrees"));
    cache_.use_gradients = p.b("gradients");
    cache_.neighbor_clamp = p.b("neighbor_clamp");
    cache_.validate();
    if (min_spacing_ > max_spacing_)
      throw InputError(fmt::format("irradiance_cache: parameter 'min_pixel_spacing' ({}) must not exceed "
                                   "'max_pixel_spacing' ({})", min_spacing_, max_spacing_));
    if (min_stride_ > stride_)
      throw InputError(fmt::format("irradiance_cache: parameter 'overture_min_stride' ({}) must not exceed "
                                   "'overture_stride' ({})", min_stride_, stride_));
  }

  std::vector<std::string> required_layers() const override { return {}; }

  MethodResult execute(const MethodInput& in) override {
    if (!in.scene)
      throw InputError("irradiance_cache renders the scene itself and got none (denoise: the frame's scene "
                       "metadata or --scene names it)");
    const Scene& scene = *in.scene;
    const int W = in.frame ? in.frame->width() : in.width, H = in.frame ? in.frame->height() : in.height;
    Image::check_size(W, H, 3, "irradiance_cache image size");
    rt::PathTracer::Options opt;
    opt.max_depth = max_depth_;
    const rt::PathTracer tracer(scene, opt);
    Render run(scene, tracer, W, H, in.seed, cache_);

    MethodResult result;
    {
      ScopedPhase phase(result.stats, "overture");
      overture(run);
    }
    {
      ScopedPhase phase(result.stats, "final");
      result.image = final_pass(run);
    }
    auto& c = result.stats.counters;
    c["records"] = double(run.overture_records + run.final_records.load());
    c["records_overture"] = double(run.overture_records);
    c["records_final"] = double(run.final_records.load());
    c["gathers"] = double(run.gathers.load());
    c["gather_cells_clamped"] = double(run.clamped_cells.load());
    c["gathers_wasted"] = double(run.wasted.load());
    c["gather_and_shadow_rays"] = double(run.rays.load());
    return result;
  }

 private:
  // One render: the scene and tracer, the shared (overture) cache and the counters.
  struct Render {
    Render(const Scene& s, const rt::PathTracer& t, int w, int h, std::uint64_t seed_, const ic::CacheSettings& cs)
        : scene(s), tracer(t), W(w), H(h), seed(seed_), global(s.bounds_min(), s.bounds_max(), cs) {
      // World size of one pixel at unit distance from the camera (angle between neighbour rays).
      const Ray r0 = scene.camera.generate_ray(W * 0.5f, H * 0.5f, W, H);
      const Ray r1 = scene.camera.generate_ray(W * 0.5f + 1, H * 0.5f, W, H);
      pixel_angle = rt::length(r1.dir - r0.dir);
    }
    const Scene& scene;
    const rt::PathTracer& tracer;
    int W, H;
    std::uint64_t seed;
    float pixel_angle = 0;
    IrradianceCache global;
    std::atomic<std::int64_t> gathers{0}, wasted{0}, rays{0}, clamped_cells{0}, final_records{0};
    std::int64_t overture_records = 0;
  };

  // One record's gather at a diffuse point; `key` makes its random numbers unique.
  ic::GatherResult gather_at(Render& run, const ShadePoint& sp, std::uint64_t key) const {
    std::uint64_t local_rays = 0;
    int cut = 0;
    const std::uint64_t seed = run.seed;
    ic::GatherResult g = ic::gather(
        sp.hit.ns, M_, N_,
        [&](Vec3 dir, int cell) -> ic::GatherSample {
          if (rt::dot(dir, sp.hit.ng) <= 0) return {Vec3(0.0f), 1e30f};  // below the true surface
          rt::Sampler rng(seed ^ 0x6a09e667f3bcc909ULL, key, std::uint64_t(cell));
          rt::PathContext ctx{rng};
          rt::PathRadiance pr = run.tracer.incoming(sp.hit.spawn_ray(dir), ctx, 1);
          local_rays += ctx.rays;
          // First-hit emission is direct light, estimated by next-event estimation instead.
          Vec3 L = rt::is_finite(pr.rest) ? pr.rest : Vec3(0.0f);
          return {L, pr.first_distance};
        },
        [&](int cell) {
          rt::Sampler rng(seed ^ 0xbb67ae8584caa73bULL, key, std::uint64_t(cell));
          return std::array<float, 2>{rng.next(), rng.next()};
        },
        gather_clamp_, &cut);
    ++run.gathers;
    run.clamped_cells += cut;
    run.rays += std::int64_t(local_rays);
    return g;
  }

  ic::RadiusBounds bounds_at(const Render& run, const ShadePoint& sp) const {
    const float fp = run.pixel_angle * sp.path_length;
    return ic::RadiusBounds{min_spacing_ * fp, max_spacing_ * fp};
  }

  // Pass 1, the overture: pixel centres on grids of stride overture_stride, /2, ... The
  // uncovered points of a pass gather in parallel against the frozen cache, then are inserted
  // in pixel order (a point an earlier record of the pass covers is dropped, counted as wasted).
  void overture(Render& run) const {
    struct Candidate {
      ShadePoint sp;
      ic::GatherResult g;
      bool needed = false;
    };
    const int W = run.W, H = run.H;
    int pass = 0;
    for (int s = stride_; s >= min_stride_; s /= 2, ++pass) {
      const int nx = (W + s - 1) / s, ny = (H + s - 1) / s;
      std::vector<std::vector<Candidate>> cand(std::size_t(nx) * ny);
      tbb::parallel_for(0, nx * ny, [&](int c) {
        rt::enable_flush_to_zero();
        const int x = std::min(W - 1, (c % nx) * s + s / 2), y = std::min(H - 1, (c / nx) * s + s / 2);
        std::vector<ShadePoint> pts;
        // With motion blur, the overture's records at the middle of the shutter interval.
        const rt::Camera& cam = run.scene.camera;
        follow(run.scene,
               cam.timed() ? cam.generate_ray_at(x + 0.5f, y + 0.5f, W, H, 0.5f, 0.5f, cam.time_at(0.5f))
                     : cam.generate_ray(x + 0.5f, y + 0.5f, W, H),
               Vec3(1.0f), 0.0f, 0, pts);
        for (std::size_t i = 0; i < pts.size(); ++i) {
          Vec3 e;
          if (run.global.interpolate(pts[i].hit.p, pts[i].hit.ns, e)) continue;
          const std::uint64_t key = key_of(1 + pass, std::uint64_t(y) * W + x, 0, i);
          cand[c].push_back({pts[i], gather_at(run, pts[i], key), true});
        }
      });
      for (auto& list : cand)  // in pixel order: the cache does not depend on thread timing
        for (Candidate& k : list) {
          Vec3 e;
          if (run.global.interpolate(k.sp.hit.p, k.sp.hit.ns, e)) {
            ++run.wasted;
            continue;
          }
          run.global.insert(k.sp.hit.p, k.sp.hit.ns, k.g, bounds_at(run, k.sp));
          ++run.overture_records;
        }
      if (s == 1) break;
    }
  }

  // What one tile of the final pass keeps: its own cache (records only it sees) and buffers.
  struct Tile {
    Tile(const Scene& scene, const ic::CacheSettings& cs, int direct_samples)
        : local(scene.bounds_min(), scene.bounds_max(), cs), strata(direct_samples) {}
    IrradianceCache local;
    std::vector<ShadePoint> pts;
    ic::LightStrata strata;  // direct light: stratified light samples
    std::vector<std::array<float, 3>> light_u;
    std::uint64_t rays = 0;
  };

  // Pass 2, final: every pixel sample interpolates; a point no record covers gathers a new
  // record kept in its tile's own cache (kTile x kTile pixels).
  Image final_pass(Render& run) const {
    const int W = run.W, H = run.H;
    Image out(W, H, 3);
    const int tx = (W + kTile - 1) / kTile, ty = (H + kTile - 1) / kTile;
    tbb::parallel_for(0, tx * ty, [&](int t) {
      rt::enable_flush_to_zero();
      Tile tile(run.scene, cache_, direct_samples_);
      const int x0 = (t % tx) * kTile, y0 = (t / tx) * kTile;
      for (int y = y0; y < std::min(H, y0 + kTile); ++y)
        for (int x = x0; x < std::min(W, x0 + kTile); ++x) {
          const Vec3 sum = pixel_radiance(run, tile, x, y);
          float* px = out.pixel(x, y);
          px[0] = sum.x;
          px[1] = sum.y;
          px[2] = sum.z;
        }
      run.rays += std::int64_t(tile.rays);
    });
    return out;
  }

  // The mean over pixel (x, y)'s camera samples (stratified jitter, as the tracer's).
  Vec3 pixel_radiance(Render& run, Tile& tile, int x, int y) const {
    const int grid = std::max(1, int(std::floor(std::sqrt(double(pixel_samples_)))));
    const std::uint64_t pixel = std::uint64_t(y) * run.W + x;
    Vec3 sum(0.0f);
    for (int s = 0; s < pixel_samples_; ++s) {
      rt::Sampler rng(run.seed, pixel, std::uint64_t(s));
      float u = rng.next(), v = rng.next(), fx = u, fy = v;
      if (s < grid * grid) {
        fx = (float(s % grid) + u) / float(grid);
        fy = (float(s / grid) + v) / float(grid);
      }
      tile.pts.clear();
      const rt::Camera& cam = run.scene.camera;
      Ray camera_ray = cam.generate_ray(x + fx, y + fy, run.W, run.H);
      float lu = 0, lv = 0;
      if (cam.has_lens()) {
        lu = rng.next(), lv = rng.next();
        camera_ray = cam.generate_ray(x + fx, y + fy, run.W, run.H, lu, lv);
      }
      // Motion blur: the sample's time, drawn as the tracer draws it; the records its path
      // creates or reads are where the geometry is then (a record is reused at other times: the
      // cache's own interpolation error, as across space).
      if (cam.timed()) {
        const float time = cam.has_shutter() ? cam.time_at(rng.next()) : cam.shutter_open;
        camera_ray = cam.generate_ray_at(x + fx, y + fy, run.W, run.H, lu, lv, time);
      }
      Vec3 c = follow(run.scene, camera_ray, Vec3(1.0f), 0.0f, 0, tile.pts);
      for (std::size_t i = 0; i < tile.pts.size(); ++i) shade(run, tile, tile.pts[i], rng, pixel, s, i, c);
      if (rt::is_finite(c)) sum += c;
    }
    sum *= 1.0f / float(pixel_samples_);
    return sum;
  }

  // Adds to c the light diffuse point `i` of sample s of `pixel` reflects: D by next-event
  // estimation, I from the caches (a new record in the tile's cache when none covers it).
  void shade(Render& run, Tile& tile, const ShadePoint& sp, rt::Sampler& rng, std::uint64_t pixel, int s,
             std::size_t i, Vec3& c) const {
    rt::PathContext ctx{rng};
    tile.light_u.resize(std::size_t(direct_samples_));
    for (int d = 0; d < direct_samples_; ++d) {
      const ic::LightStrata::Numbers u = tile.strata.next(d, [&] { return rng.next(); });
      tile.light_u[std::size_t(d)] = {u.u0, u.u1, u.u2};
    }
    Vec3 direct = run.tracer.direct_white_sum(sp.hit, ctx, tile.light_u.data(), direct_samples_);
    direct *= 1.0f / float(direct_samples_);
    tile.rays += ctx.rays;
    Vec3 wsum(0.0f), e;
    float w = 0;
    run.global.accumulate(sp.hit.p, sp.hit.ns, wsum, w);
    tile.local.accumulate(sp.hit.p, sp.hit.ns, wsum, w);
    if (w > 0) {
      e = wsum / w;
    } else {
      const std::uint64_t key = key_of(0, pixel, std::uint64_t(s), i);
      std::size_t k = tile.local.insert(sp.hit.p, sp.hit.ns, gather_at(run, sp, key), bounds_at(run, sp));
      e = tile.local.records()[k].irradiance;
      ++run.final_records;
    }
    // The cache holds irradiance; a white Lambertian reflects E / pi.
    c += sp.weight * sp.hit.albedo * (direct + e * rt::kInvPi);
  }

  static std::uint64_t key_of(int phase, std::uint64_t pixel, std::uint64_t sample, std::size_t point) {
    return rt::mix64(rt::mix64(rt::mix64(std::uint64_t(phase) + 1) ^ pixel) ^ (sample * 64 + point));
  }

  // Follows `ray` through specular bounces (both lobes of a coat, with its Fresnel weights),
  // appends every diffuse point reached to `pts` and returns the emission found on the way.
  Vec3 follow(const Scene& scene, Ray ray, Vec3 weight, float path_length, int depth,
              std::vector<ShadePoint>& pts) const {
    SurfaceHit hit;
    if (!scene.intersect(ray, hit)) return weight * scene.escaped_radiance(ray.dir);
    ++depth;
    Vec3 out = weight * hit.emitted();
    if (depth >= max_depth_) return out;
    const float len = path_length + hit.t;
    const Vec3 wo = -ray.dir;
    const rt::Material& m = *hit.material;
    Vec3 spec(0.0f);
    float base = 0;
    switch (m.type) {
      case rt::MaterialType::kDiffuse: base = 1; break;
      case rt::MaterialType::kMirror: spec = m.tint; break;
      case rt::MaterialType::kCoated: {
        float fr = rt::fresnel_schlick(rt::dot(wo, hit.ns), m.ior);
        spec = m.tint * fr;
        base = 1 - fr;
        break;
      }
      // The hard materials as their smooth counterparts: this renderer follows specular chains
      // deterministically, so a rough lobe is rendered as a mirror (or a clear refraction).
      case rt::MaterialType::kConductor:
        spec = rt::conductor_fresnel(rt::dot(wo, hit.ns), m.eta_c, m.k_c, m.schlick, m.tint);
        break;
      case rt::MaterialType::kPlastic: {
        const float fr = rt::fresnel_dielectric(rt::dot(wo, hit.ns), m.ior);
        spec = m.tint * fr;
        base = 1 - fr;
        break;
      }
      case rt::MaterialType::kDielectric: {
        const float eta = (m.thin || hit.front) ? m.ior : 1.0f / m.ior;
        float cos_t = 0;
        const float cos_o = rt::dot(wo, hit.ns);
        float fr = rt::fresnel_dielectric(cos_o, eta, &cos_t);
        if (m.thin) fr = rt::thin_sheet_reflectance(fr);
        spec = m.tint * fr;
        rt::Vec3 tw = weight * m.transmittance * ((1 - fr) / (m.thin ? 1.0f : eta * eta));
        if (!m.thin && !hit.front) tw *= rt::beer_transmittance(m.absorption, hit.t);
        if (rt::max_component(tw) > 1e-4f) {
          const rt::Vec3 wt = m.thin ? -wo : rt::refract_dir(wo, hit.ns, eta, cos_t);
          if (rt::dot(wt, hit.ng) < 0) out += follow(scene, hit.spawn_ray(wt), tw, len, depth, pts);
        }
        break;
      }
    }
    if (base > 0 && !rt::is_black(hit.albedo)) pts.push_back({hit, weight * base, len});
    // Specular chains whose weight fell below 1e-4 are cut: their share of the pixel is below
    // the 8-bit quantum even next to a light of radiance 10.
    const Vec3 sw = weight * spec;
    if (rt::max_component(sw) > 1e-4f) {
      Vec3 wr = rt::reflect(wo, hit.ns);
      if (rt::dot(wr, hit.ng) > 0) out += follow(scene, hit.spawn_ray(wr), sw, len, depth, pts);
    }
    return out;
  }

  int pixel_samples_, direct_samples_, M_, N_;
  float min_spacing_, max_spacing_;
  int stride_, min_stride_, max_depth_;
  float gather_clamp_;
  ic::CacheSettings cache_;
};

}  // namespace

MethodInfo irradiance_cache_method() {
  return {
      .name = "irradiance_cache",
      .description = "Ward-style irradiance cache renderer with gradients (renders the scene itself; paper's IC column)",
      .kind = MethodKind::Renderer,
      .params =
          {
              {"pixel_samples", ParamType::Int, "64", "camera samples per pixel (anti-aliasing)", 1.0, 65536.0},
              {"direct_samples", ParamType::Int, "16", "light samples per camera sample for direct light", 1.0, 4096.0},
              {"gather_theta_cells", ParamType::Int, "48", "M: polar strata of a record's hemisphere gather", 1.0, 1024.0},
              {"gather_phi_cells", ParamType::Int, "144", "N: azimuthal strata of a record's hemisphere gather", 1.0, 4096.0},
              {"kappa", ParamType::Float, "1", "Tabellion-Lamorlette accuracy (higher: more records)", 1e-3, 1e3},
              {"max_angle_degrees", ParamType::Float, "10", "normal deviation (degrees) at which the angle error is 1/kappa", 0.1, 90.0},
              {"min_pixel_spacing", ParamType::Float, "2.5", "lower bound of a record's radius, in projected pixels", 0.0, 1e4},
              {"max_pixel_spacing", ParamType::Float, "15", "upper bound of a record's radius, in projected pixels", 0.0, 1e6},
              {"overture_stride", ParamType::Int, "32", "pixel stride of the first overture pass", 1.0, 4096.0},
              {"overture_min_stride", ParamType::Int, "4", "pixel stride of the last overture pass (strides halve)", 1.0, 4096.0},
              {"max_depth", ParamType::Int, "8", "path length of gather paths and specular chains", 1.0, 64.0},
              {"gather_clamp", ParamType::Float, "300", "cut gather cells brighter than this times the gather's mean; 0: off", 0.0, 1e9},
              {"gradients", ParamType::Bool, "true", "extrapolate with rotational and translational gradients"},
              {"neighbor_clamp", ParamType::Bool, "true", "clamp radii against neighbouring records"},
          },
      .create = [](const Params& p) { return std::make_unique<IrradianceCacheRenderer>(p); },
  };
}

}  // namespace dnb
