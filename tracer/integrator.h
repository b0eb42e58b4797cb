// The path tracer of the shared tracer, and the paper's decomposition of one sample path
// (formula 1, sections 3.1 and 3.2). Used by render.cpp for AOV frames and references, and by
// renderer-type methods (irradiance_cache/) for hemisphere gathers and direct lighting.
//
// Integrator: unidirectional path tracing with next-event estimation (one light sample per
// diffuse vertex, emitter chosen by Scene::sample_light) combined with BSDF sampling by
// multiple importance sampling (power heuristic). Russian roulette after `rr_depth` vertices.
// A path has at most `max_depth` segments (camera ray included): with max_depth = 1 only
// emitters seen directly contribute; a closed furnace of albedo a and emission Le gives
// Le * (1 + a + ... + a^(max_depth-1)).
//
// ---- The decomposition F = (D + I) * T + R + E, per sample path ---------------------------
// For the camera ray (level 0), and for the mirror ray of level k (level k + 1), with first hit
// x (reached along the ray, so its emission has MIS weight 1):
//  * miss (sky):   E = sky + sun radiance along the ray; D = I = T = R = 0; normal = 0, depth = 0.
//  * any hit:      E = radiance x emits towards the ray (front face, or both for two-sided
//                  emitters); normal = shading normal of x facing the ray; depth = distance along
//                  the ray (from the camera at level 0, from the mirror point at level k > 0).
//  * diffuse x:    T = albedo (material x texture); D = direct light reflected by a *white*
//                  Lambertian at x (the MIS-weighted light sample plus the MIS-weighted emission
//                  found by the BSDF-sampled ray); I = everything else that ray brings back
//                  (white-surface weight, i.e. without T); R = 0.
//  * mirror x:     T = D = I = 0; R = tint * L(mirror ray); `tint` (the level's tint) = mirror
//                  tint. When k < reflection_levels, L(mirror ray) is itself decomposed as level
//                  k + 1 and R = tint * ((D' + I') * T' + R' + E') exactly, per sample.
//  * coated x:     T = base albedo always. One lobe is chosen per sample: the coat with
//                  probability Pc = clamp(Fr(cos), 0.2, 0.8) (Fr: Schlick Fresnel of the coat),
//                  else the base.
//                  - coat chosen: D = I = 0; tint = coat tint * Fr / Pc; R = tint * L(mirror ray)
//                    (decomposed as level k + 1 as for a mirror).
//                  - base chosen: D and I as for diffuse x, both times (1 - Fr) / (1 - Pc);
//                    tint = 0, R = 0 (the next level is absent for this sample).
// F is then computed per sample as (D + I) * T + R + E, so the identity holds exactly per
// sample. The frame's pixel means of D and I are albedo-weighted (render.cpp), so that the
// identity also holds for the means of every pixel, edge pixels included.
// Reflection levels in a frame: refl(k).* are means over the samples that reached level k
// (went through k specular bounces), and refl(k).tint is the mean over the samples of level
// k - 1 of the bounce weight into level k (0 for samples that took a diffuse lobe); so
// reflection at level k - 1 = refl(k).tint * ((D + I) * T + R + E at level k), up to the
// product-of-means error where the tint varies inside a pixel (Fresnel weights on curved coats).
// A path reaching max_depth at x stops there: D = I = R = 0 (E and T still set).
//
// ---- Use from a renderer-type method (irradiance cache) -----------------------------------
//   auto scene = load_scene("cornell-box");                  // tracer/render.h
//   rt::PathTracer tracer(*scene, {});                        // max_depth 8
//   rt::Sampler rng(seed, pixel_or_record_id, sample_index);  // counter-based: deterministic
//   rt::PathContext ctx{rng};
//   rt::Ray ray = scene->camera.generate_ray(x + 0.5f, y + 0.5f, width, height);
//   rt::SurfaceHit hit;
//   if (scene->intersect(ray, hit) && !hit.material->is_specular()) {
//     rt::Vec3 direct = tracer.direct_white(hit, ctx);        // E_direct / pi, white surface
//     // Hemisphere gather: cosine-distributed directions about hit.ns, each
//     rt::Ray g = hit.spawn_ray(dir);   // at the hit's time (motion blur)
//     rt::Vec3 L = tracer.incoming(g, ctx, /*depth=*/2).rest;   // indirect only (no emission at
//     // the gathered hit: that light is direct and counted by direct_white)
//     // outgoing radiance = hit.albedo * (direct + mean of L)   (cosine-weighted mean = E / pi)
//   }
// Scene, Camera, SurfaceHit, Material and the light queries are documented in tracer/scene.h.
#pragma once

#include <array>

#include <cstdint>

#include "core/aov_frame.h"
#include "tracer/bsdf.h"
#include "tracer/math.h"
#include "tracer/scene.h"

namespace dnb::rt {

// The largest --reflection-levels accepted.
constexpr int kMaxReflectionLevels = layer::kMaxLevels;

// The layers of one level of one sample path (see the comment at the top).
struct LevelSample {
  Vec3 direct, indirect, albedo, reflection, emission;
  Vec3 normal;
  float depth = 0;
  Vec3 tint;            // weight of the specular bounce into level + 1 (0 when not taken)
  Vec3 attenuation{1.0f};  // absorption along this level's ray (inside coloured glass), folded into the parent's tint
  bool present = false; // level 0: always; level k: the sample went through k specular bounces
  Vec3 color() const { return (direct + indirect) * albedo + reflection + emission; }
};

// Level 0's R split as Cycles splits it: reflected (gloss) and refracted (trans) light, each
// direct or indirect, as radiance (not yet divided by its colour); R = their sum up to rounding.
// The colours are the material's glossy and transmission colours at the hit. Level 0 only (the
// frame's layers), so kept apart from LevelSample, which every level zeroes.
struct SpecularParts {
  Vec3 gloss_direct, gloss_indirect, gloss_color, trans_direct, trans_indirect, trans_color;
};

struct SampleResult {
  LevelSample level[kMaxReflectionLevels + 1];
  int levels = 0;  // number of present levels (level[0 .. levels-1])
  SpecularParts specular;  // of level 0
};

// Radiance along a ray, split into the emission of its first hit (or the escaped sky/sun
// radiance on a miss), with the MIS weight given by how the ray was sampled, and the rest.
struct PathRadiance {
  Vec3 first_emission;
  Vec3 rest;
  float first_distance = 1e30f;  // distance along the ray to its first hit (1e30 on a miss)
  Vec3 total() const { return first_emission + rest; }
};

// Per-thread state of a path: the sample's random numbers and counters for benchmarks.
struct PathContext {
  Sampler& sampler;
  std::uint64_t rays = 0;  // closest-hit and shadow rays traced
};

class PathTracer {
 public:
  struct Options {
    int max_depth = 8;          // path length in segments
    int rr_depth = 3;           // Russian roulette from this many vertices on
    int reflection_levels = 2;  // decomposed levels behind specular first bounces
  };
  PathTracer(const Scene& scene, Options options);

  const Scene& scene() const { return scene_; }
  const Options& options() const { return opt_; }

  // The decomposition of one camera sample (see top of file); out.level[0] is the camera level.
  void sample_layers(const Ray& camera_ray, PathContext& ctx, SampleResult& out) const;

  // Radiance arriving along `ray` (a full path-traced estimate): emission of the first hit with
  // weight 1 (as for a camera ray or a ray leaving a mirror) plus everything scattered there.
  // `depth`: vertices the path already has (the path stops at max_depth segments).
  // Hemisphere gathers of an irradiance cache use total(), or `rest` when they estimate the
  // direct light separately with direct_white().
  PathRadiance incoming(const Ray& ray, PathContext& ctx, int depth = 1) const;

  // Next-event estimate of the radiance a *white* Lambertian at `hit` reflects because of
  // emitters (direct light only): one light sample, visibility tested, no MIS. The direct
  // irradiance is pi times this. Multiply by the albedo for the actual surface.
  Vec3 direct_white(const SurfaceHit& hit, PathContext& ctx) const;
  // The same with the light sample's numbers given: u0 picks the light, (u1, u2) the point on
  // it (for stratified sets of light samples).
  Vec3 direct_white(const SurfaceHit& hit, PathContext& ctx, float u0, float u1, float u2) const;
  // The sum of n such estimates, u[i] = {u0, u1, u2} of sample i, their shadow rays traced
  // together (Scene::occluded on n rays). Equal to summing direct_white(hit, ctx, u[i]...), but
  // for a shadow ray whose blocker is exactly at its end (Scene::occluded on n rays).
  Vec3 direct_white_sum(const SurfaceHit& hit, PathContext& ctx, const std::array<float, 3>* u, int n) const;

 private:
  // A light sample for a white Lambertian at hit and its unshadowed term radiance cos / (pi pdf)
  // in c; false when the sample cannot light the surface (the shadow test is left to the caller).
  bool white_light_term(const SurfaceHit& hit, float u0, float u1, float u2, LightSample& ls, Vec3& c) const;
  // The MIS-weighted light-sample term of direct light at a base (diffuse) lobe chosen with
  // probability lobe_prob, for a white surface.
  Vec3 nee_mis(const SurfaceHit& hit, float lobe_prob, PathContext& ctx) const;
  // Whether the light sample is unoccluded from hit (a shadow ray, or for a sphere light a
  // closest-hit ray that must reach the light).
  bool visible(const SurfaceHit& hit, const LightSample& ls, PathContext& ctx) const;
  // Continues a path along `ray` whose previous vertex sampled it with solid-angle density
  // prev_pdf (0 for a specular bounce or a camera ray: weight 1 for emission found) from a
  // point of shading normal prev_n; path_weight is the path's weight so far (Russian roulette).
  PathRadiance trace(Ray ray, int depth, float prev_pdf, Vec3 prev_n, Vec3 path_weight, PathContext& ctx) const;
  void decompose(const Ray& ray, int level, int depth, PathContext& ctx, SampleResult& out) const;
  // trace()'s step at a hard material: its light sample into `rest`, then the BSDF sample: the
  // path's weight, the next ray and its density; false when the path ends there.
  bool hard_vertex(const SurfaceHit& hit, Vec3 wo, PathContext& ctx, Vec3& beta, Vec3& rest, float& prev_pdf,
                   Ray& ray) const;
  // The level's layers at a hard material (tracer/bsdf.h): the light sample and the BSDF sample,
  // their diffuse parts into D and I, their glossy parts into R; a delta lobe continues the
  // decomposition at level + 1 as a mirror does.
  void decompose_hard(const Ray& ray, const SurfaceHit& hit, int level, int depth, PathContext& ctx, SampleResult& out) const;
  struct HardDirect {
    Vec3 diffuse_white, glossy;
    bool transmitted = false;  // the light sample lit the side the ray did not come from
  };
  // The MIS-weighted light sample at a hard material's vertex (0 when every lobe is a delta).
  HardDirect hard_nee(const SurfaceHit& hit, const HardBsdf& b, const Frame& f, Vec3 wo_local,
                      PathContext& ctx) const;

  const Scene& scene_;
  Options opt_;
};

}  // namespace dnb::rt
