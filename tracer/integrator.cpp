#include "tracer/integrator.h"

namespace dnb::rt {
namespace {

float power_heuristic(float a, float b) {
  float a2 = a * a, b2 = b * b;
  return a2 + b2 > 0 ? a2 / (a2 + b2) : 0.0f;
}

// Lobe choice at a vertex (see integrator.h, "coated x").
struct Lobe {
  bool specular = false;
  Vec3 spec_weight;        // weight of the mirror bounce (tint, x Fr / Pc for a coat)
  float base_weight = 0;   // weight of the diffuse base, (1 - Fr) / (1 - Pc) for a coat
  float base_prob = 0;     // probability that the base lobe is chosen (for MIS densities)
};

Lobe choose_lobe(const SurfaceHit& hit, Vec3 wo, Sampler& s) {
  const Material& m = *hit.material;
  Lobe l;
  switch (m.type) {
    case MaterialType::kDiffuse:
      l.base_weight = 1;
      l.base_prob = 1;
      break;
    case MaterialType::kMirror:
      l.specular = true;
      l.spec_weight = m.tint;
      break;
    case MaterialType::kConductor:
    case MaterialType::kDielectric:
    case MaterialType::kPlastic:
      break;  // not through here: decompose_hard() and trace()'s hard branch
    case MaterialType::kCoated: {
      float fr = fresnel_schlick(dot(wo, hit.ns), m.ior);
      float pc = std::clamp(fr, 0.2f, 0.8f);
      l.base_prob = 1 - pc;
      if (s.at(dims::kLobe) < pc) {
        l.specular = true;
        l.spec_weight = m.tint * (fr / pc);
      } else {
        l.base_weight = (1 - fr) / (1 - pc);
      }
      break;
    }
  }
  return l;
}

// A hard material's BSDF at a hit, in the frame of hit.ns (which faces the incoming ray): a
// dielectric's eta is ior when the ray enters through the front and 1 / ior when it leaves.
HardBsdf hard_bsdf_at(const SurfaceHit& hit) {
  const Material& m = *hit.material;
  HardBsdf b;
  b.type = m.type == MaterialType::kConductor ? HardType::kConductor
           : m.type == MaterialType::kDielectric ? HardType::kDielectric
                                                 : HardType::kPlastic;
  b.ggx = Ggx{m.alpha_x * hit.roughness_scale, m.alpha_y * hit.roughness_scale};
  b.eta_c = m.eta_c;
  b.k_c = m.k_c;
  b.schlick = m.schlick;
  b.tint = m.tint;
  b.transmittance = m.transmittance;
  b.eta = (m.type == MaterialType::kDielectric && !m.thin && !hit.front) ? 1.0f / m.ior : m.ior;
  b.thin = m.thin;
  b.albedo = hit.albedo;
  b.base_inner_reflectance = m.base_inner_reflectance;
  b.base_inv_eta2 = 1.0f / (m.ior * m.ior);
  return b;
}

// Beer absorption along a segment that ends on the inside of absorbing glass.
bool absorbs(const SurfaceHit& hit) {
  const Material& m = *hit.material;
  return m.type == MaterialType::kDielectric && !hit.front && !m.thin && !is_black(m.absorption);
}
Vec3 absorption_along(const SurfaceHit& hit) { return beer_transmittance(hit.material->absorption, hit.t); }

// The light a delta bounce of weight `tint` brings from the next level, split as Cycles splits
// it: direct, the emission (or sky) that level's ray meets; indirect, the rest.
void split_specular(const LevelSample& next, Vec3 tint, Vec3& direct, Vec3& indirect) {
  direct = tint * next.emission;
  indirect = tint * ((next.direct + next.indirect) * next.albedo + next.reflection);
}

// The BSDF sample of a hard vertex in world space: false when the sample is lost or the shading
// normal sends it to the other side of the geometric surface than the one it was sampled on.
bool sample_hard(const SurfaceHit& hit, const HardBsdf& b, const Frame& f, Vec3 wo_l, Sampler& s, BsdfSample& bs,
                 Vec3& wi) {
  const float ul = s.at(dims::kLobe), u1 = s.at(dims::kBsdfU), u2 = s.at(dims::kBsdfV);
  if (!b.sample(wo_l, ul, u1, u2, bs)) return false;
  wi = f.to_world(bs.wi);
  return (dot(wi, hit.ng) > 0) == (bs.wi.z > 0);
}

}  // namespace

PathTracer::HardDirect PathTracer::hard_nee(const SurfaceHit& hit, const HardBsdf& b, const Frame& f, Vec3 wo_l,
                                            PathContext& ctx) const {
  HardDirect out;
  if (b.all_delta()) return out;
  Sampler& s = ctx.sampler;
  float u0 = s.at(dims::kLightChoice), u1 = s.at(dims::kLightU), u2 = s.at(dims::kLightV);
  LightSample ls;
  if (!scene_.sample_light(hit.p, hit.ns, u0, u1, u2, ls) || !(ls.pdf > 0)) return out;
  const Vec3 wi_l = f.to_local(ls.wi);
  // The geometric and the shading normal must agree on the side the light is on.
  if (wi_l.z == 0 || (wi_l.z > 0) != (dot(ls.wi, hit.ng) > 0)) return out;
  const BsdfValue v = b.eval(wo_l, wi_l);
  if (is_black(v.diffuse_white) && is_black(v.glossy)) return out;
  if (!visible(hit, ls, ctx)) return out;
  const float k = std::fabs(wi_l.z) * power_heuristic(ls.pdf, b.pdf(wo_l, wi_l)) / ls.pdf;
  out.diffuse_white = ls.radiance * v.diffuse_white * k;
  out.glossy = ls.radiance * v.glossy * k;
  out.transmitted = (wi_l.z > 0) != (wo_l.z > 0);
  return out;
}

bool PathTracer::visible(const SurfaceHit& hit, const LightSample& ls, PathContext& ctx) const {
  ++ctx.rays;
  if (ls.sphere_mesh >= 0) {
    // A sphere light's direction: lit when the first thing along it is that light's front.
    SurfaceHit h;
    Ray r = hit.spawn_ray(ls.wi);
    return scene_.intersect(r, h) && int(h.geom) == ls.sphere_mesh && !is_black(h.emitted());
  }
  Ray shadow = hit.spawn_ray(ls.wi, ls.dist < 1e29f ? ls.dist * (1 - 1e-4f) - hit.offset : 1e30f);
  return !scene_.occluded(shadow);
}

PathTracer::PathTracer(const Scene& scene, Options options) : scene_(scene), opt_(options) {
  opt_.reflection_levels = std::clamp(opt_.reflection_levels, 0, kMaxReflectionLevels);
  opt_.max_depth = std::max(1, opt_.max_depth);
}

Vec3 PathTracer::nee_mis(const SurfaceHit& hit, float lobe_prob, PathContext& ctx) const {
  Sampler& s = ctx.sampler;
  float u0 = s.at(dims::kLightChoice), u1 = s.at(dims::kLightU), u2 = s.at(dims::kLightV);
  LightSample ls;
  if (!scene_.sample_light(hit.p, hit.ns, u0, u1, u2, ls)) return Vec3(0.0f);
  float cos_s = dot(ls.wi, hit.ns);
  if (cos_s <= 0 || dot(ls.wi, hit.ng) <= 0 || !(ls.pdf > 0)) return Vec3(0.0f);
  if (!visible(hit, ls, ctx)) return Vec3(0.0f);
  float bsdf_pdf = lobe_prob * cos_s * kInvPi;
  float w = power_heuristic(ls.pdf, bsdf_pdf);
  return ls.radiance * (kInvPi * cos_s * w / ls.pdf);
}

Vec3 PathTracer::direct_white(const SurfaceHit& hit, PathContext& ctx) const {
  Sampler& s = ctx.sampler;
  float u0 = s.at(dims::kLightChoice), u1 = s.at(dims::kLightU), u2 = s.at(dims::kLightV);
  return direct_white(hit, ctx, u0, u1, u2);
}

bool PathTracer::white_light_term(const SurfaceHit& hit, float u0, float u1, float u2, LightSample& ls, Vec3& c) const {
  if (!scene_.sample_light(hit.p, hit.ns, u0, u1, u2, ls)) return false;
  float cos_s = dot(ls.wi, hit.ns);
  if (cos_s <= 0 || dot(ls.wi, hit.ng) <= 0 || !(ls.pdf > 0)) return false;
  c = ls.radiance * (kInvPi * cos_s / ls.pdf);
  return true;
}

Vec3 PathTracer::direct_white(const SurfaceHit& hit, PathContext& ctx, float u0, float u1, float u2) const {
  LightSample ls;
  Vec3 c;
  if (!white_light_term(hit, u0, u1, u2, ls, c) || !visible(hit, ls, ctx)) return Vec3(0.0f);
  return c;
}

Vec3 PathTracer::direct_white_sum(const SurfaceHit& hit, PathContext& ctx, const std::array<float, 3>* u,
                                  int n) const {
  // Light samples first, their shadow rays traced as one batch, then the sum in sample order
  // (so that it equals the one-by-one sum bit for bit). Sphere-light samples are tested one by
  // one (visible(): the first hit must be the light itself).
  thread_local std::vector<Ray> rays;
  thread_local std::vector<int> ray_of;  // per sample: its index in `rays`, -1 when none
  thread_local std::vector<Vec3> contrib;
  thread_local std::vector<std::uint8_t> hidden;
  rays.clear();
  ray_of.assign(std::size_t(n), -1);
  contrib.assign(std::size_t(n), Vec3(0.0f));
  for (int i = 0; i < n; ++i) {
    LightSample ls;
    Vec3 c;
    if (!white_light_term(hit, u[i][0], u[i][1], u[i][2], ls, c)) continue;
    if (ls.sphere_mesh >= 0) {
      if (visible(hit, ls, ctx)) contrib[std::size_t(i)] = c;
      continue;
    }
    ray_of[std::size_t(i)] = int(rays.size());
    rays.push_back(hit.spawn_ray(ls.wi, ls.dist < 1e29f ? ls.dist * (1 - 1e-4f) - hit.offset : 1e30f));
    contrib[std::size_t(i)] = c;
  }
  hidden.resize(rays.size());
  if (!rays.empty()) scene_.occluded(rays.data(), int(rays.size()), hidden.data());
  ctx.rays += rays.size();
  Vec3 sum(0.0f);
  for (int i = 0; i < n; ++i) {
    const int r = ray_of[std::size_t(i)];
    if (r >= 0 && hidden[std::size_t(r)]) continue;
    sum += contrib[std::size_t(i)];
  }
  return sum;
}

// Out of line, so that trace()'s loop over the diffuse, mirror and coated materials stays compact
// (inlined, it cost the tracer bench 2-6% on scenes without hard materials).
[[gnu::noinline]] bool PathTracer::hard_vertex(const SurfaceHit& hit, Vec3 wo, PathContext& ctx, Vec3& beta,
                                               Vec3& rest, float& prev_pdf, Ray& ray) const {
  const HardBsdf b = hard_bsdf_at(hit);
  const Frame f(hit.ns);
  const Vec3 wo_l = f.to_local(wo);
  const HardDirect d = hard_nee(hit, b, f, wo_l, ctx);
  rest += beta * (d.diffuse_white * hit.albedo + d.glossy);
  BsdfSample bs;
  Vec3 wi;
  if (!sample_hard(hit, b, f, wo_l, ctx.sampler, bs, wi)) return false;
  beta *= bs.weight_diffuse_white * hit.albedo + bs.weight_glossy;
  if (is_black(beta)) return false;
  prev_pdf = bs.delta ? 0.0f : bs.pdf;
  ray = hit.spawn_ray(wi);
  return true;
}

PathRadiance PathTracer::trace(Ray ray, int depth, float prev_pdf, Vec3 prev_n, Vec3 path_weight,
                               PathContext& ctx) const {
  PathRadiance out;
  Vec3 beta(1.0f);
  Vec3* sink = &out.first_emission;
  Sampler& s = ctx.sampler;
  Vec3 prev_p = ray.origin;
  for (;;) {
    SurfaceHit hit;
    ++ctx.rays;
    if (!scene_.intersect(ray, hit)) {
      const bool in_sun = scene_.in_sun(ray.dir);  // once, for the radiance and the density
      Vec3 Le = scene_.escaped_radiance(ray.dir, in_sun);
      if (!is_black(Le)) {
        float w = prev_pdf > 0 ? power_heuristic(prev_pdf, scene_.escaped_light_pdf(ray.dir, prev_n, in_sun)) : 1.0f;
        *sink += beta * Le * w;
      }
      break;
    }
    if (sink == &out.first_emission) out.first_distance = hit.t;
    if (absorbs(hit)) beta *= absorption_along(hit);
    ++depth;
    s.start_vertex(depth);
    Vec3 Le = hit.emitted();
    if (!is_black(Le)) {
      float w = prev_pdf > 0 ? power_heuristic(prev_pdf, scene_.light_pdf(prev_p, hit)) : 1.0f;
      *sink += beta * Le * w;
    }
    sink = &out.rest;
    if (depth >= opt_.max_depth) break;
    // Russian roulette on the whole path's weight, after rr_depth vertices.
    if (depth > opt_.rr_depth) {
      float q = std::min(0.95f, max_component(beta * path_weight));
      if (!(q > 0) || s.at(dims::kRoulette) >= q) break;
      beta *= 1.0f / q;
    }
    Vec3 wo = -ray.dir;
    if (hit.material->is_hard()) {
      if (!hard_vertex(hit, wo, ctx, beta, out.rest, prev_pdf, ray)) break;
      prev_p = hit.p;
      prev_n = hit.ns;
      continue;
    }
    Lobe lobe = choose_lobe(hit, wo, s);
    if (lobe.specular) {
      Vec3 wr = reflect(wo, hit.ns);
      if (dot(wr, hit.ng) <= 0) break;
      beta *= lobe.spec_weight;
      prev_pdf = 0;
      prev_p = hit.p;
      ray = hit.spawn_ray(wr);
      continue;
    }
    Vec3 base = hit.albedo * lobe.base_weight;
    out.rest += beta * base * nee_mis(hit, lobe.base_prob, ctx);
    Frame f(hit.ns);
    float u1 = s.at(dims::kBsdfU), u2 = s.at(dims::kBsdfV);
    Vec3 wi = f.to_world(sample_cosine_hemisphere(u1, u2));
    float cos_i = dot(wi, hit.ns);
    if (cos_i <= 1e-7f || dot(wi, hit.ng) <= 0) break;
    beta *= base;  // f cos / pdf = (albedo / pi) cos / (cos / pi)
    if (is_black(beta)) break;
    prev_pdf = lobe.base_prob * cos_i * kInvPi;
    prev_p = hit.p;
    prev_n = hit.ns;
    ray = hit.spawn_ray(wi);
  }
  return out;
}

PathRadiance PathTracer::incoming(const Ray& ray, PathContext& ctx, int depth) const {
  return trace(ray, depth, 0.0f, Vec3(0.0f), Vec3(1.0f), ctx);
}

void PathTracer::decompose(const Ray& ray, int level, int depth, PathContext& ctx, SampleResult& out) const {
  LevelSample& L = out.level[level];
  L = LevelSample{};
  L.present = true;
  out.levels = std::max(out.levels, level + 1);
  SurfaceHit hit;
  ++ctx.rays;
  if (!scene_.intersect(ray, hit)) {
    L.emission = scene_.escaped_radiance(ray.dir);
    return;
  }
  ++depth;
  ctx.sampler.start_vertex(depth);
  L.normal = hit.ns;
  L.depth = hit.t;
  L.emission = hit.emitted();
  if (absorbs(hit)) L.attenuation = absorption_along(hit);
  const Material& m = *hit.material;
  if (m.type != MaterialType::kMirror) L.albedo = hit.albedo;
  if (depth >= opt_.max_depth) return;
  if (m.is_hard()) {
    decompose_hard(ray, hit, level, depth, ctx, out);
    return;
  }
  Vec3 wo = -ray.dir;
  Lobe lobe = choose_lobe(hit, wo, ctx.sampler);
  SpecularParts* sp = level == 0 ? &out.specular : nullptr;
  if (sp && m.type != MaterialType::kDiffuse) sp->gloss_color = m.tint;  // a mirror's or a coat's glossy lobe
  if (lobe.specular) {
    L.tint = lobe.spec_weight;
    Vec3 wr = reflect(wo, hit.ns);
    if (dot(wr, hit.ng) <= 0) return;  // shading normal sends the mirror ray below the surface
    Ray r = hit.spawn_ray(wr);
    if (level < opt_.reflection_levels) {
      decompose(r, level + 1, depth, ctx, out);
      L.tint *= out.level[level + 1].attenuation;  // exactly 1 outside absorbing glass
      L.reflection = L.tint * out.level[level + 1].color();
      if (sp) split_specular(out.level[level + 1], L.tint, sp->gloss_direct, sp->gloss_indirect);
    } else {
      const PathRadiance pr = trace(r, depth, 0.0f, Vec3(0.0f), L.tint, ctx);
      L.reflection = L.tint * pr.total();
      if (sp) {
        sp->gloss_direct = L.tint * pr.first_emission;
        sp->gloss_indirect = L.tint * pr.rest;
      }
    }
    return;
  }
  // Diffuse base: D and I for a white surface, scaled by the lobe weight (1 for diffuse).
  Vec3 direct = nee_mis(hit, lobe.base_prob, ctx);
  Vec3 indirect(0.0f);
  Frame f(hit.ns);
  float u1 = ctx.sampler.at(dims::kBsdfU), u2 = ctx.sampler.at(dims::kBsdfV);
  Vec3 wi = f.to_world(sample_cosine_hemisphere(u1, u2));
  float cos_i = dot(wi, hit.ns);
  if (cos_i > 1e-7f && dot(wi, hit.ng) > 0) {
    Ray r = hit.spawn_ray(wi);
    PathRadiance pr = trace(r, depth, lobe.base_prob * cos_i * kInvPi, hit.ns, hit.albedo * lobe.base_weight, ctx);
    direct += pr.first_emission;
    indirect = pr.rest;
  }
  L.direct = direct * lobe.base_weight;
  L.indirect = indirect * lobe.base_weight;
}

void PathTracer::decompose_hard(const Ray& ray, const SurfaceHit& hit, int level, int depth, PathContext& ctx,
                                SampleResult& out) const {
  const HardBsdf b = hard_bsdf_at(hit);
  const Frame f(hit.ns);
  const Vec3 wo_l = f.to_local(-ray.dir);
  const HardDirect d = hard_nee(hit, b, f, wo_l, ctx);
  Vec3 direct = d.diffuse_white, indirect(0.0f), glossy = d.glossy, reflection(0.0f), tint(0.0f);
  // R's parts as Cycles names them: [0] reflected, [1] refracted; direct and indirect.
  Vec3 spec_direct[2] = {Vec3(0.0f), Vec3(0.0f)}, spec_indirect[2] = {Vec3(0.0f), Vec3(0.0f)};
  spec_direct[d.transmitted ? 1 : 0] = d.glossy;
  BsdfSample bs;
  Vec3 wi;
  if (sample_hard(hit, b, f, wo_l, ctx.sampler, bs, wi)) {
    const Ray r = hit.spawn_ray(wi);
    const int part = (bs.wi.z > 0) != (wo_l.z > 0) ? 1 : 0;
    Vec3 dir, ind;
    if (bs.delta) {
      // A perfect reflection or refraction: the next level is what it shows (behind glass, the
      // first surface seen through it).
      tint = bs.weight_glossy;
      if (level < opt_.reflection_levels) {
        decompose(r, level + 1, depth, ctx, out);
        tint *= out.level[level + 1].attenuation;
        reflection = tint * out.level[level + 1].color();
        split_specular(out.level[level + 1], tint, dir, ind);
      } else {
        const PathRadiance pr = trace(r, depth, 0.0f, Vec3(0.0f), tint, ctx);
        reflection = tint * pr.total();
        dir = tint * pr.first_emission;
        ind = tint * pr.rest;
      }
    } else {
      const Vec3 weight = bs.weight_diffuse_white * hit.albedo + bs.weight_glossy;
      const PathRadiance pr = trace(r, depth, bs.pdf, hit.ns, weight, ctx);
      direct += bs.weight_diffuse_white * pr.first_emission;
      indirect = bs.weight_diffuse_white * pr.rest;
      glossy += bs.weight_glossy * pr.total();
      dir = bs.weight_glossy * pr.first_emission;
      ind = bs.weight_glossy * pr.rest;
    }
    spec_direct[part] += dir;
    spec_indirect[part] += ind;
  }
  LevelSample& L = out.level[level];
  L.direct = direct;
  L.indirect = indirect;
  L.tint = tint;
  L.reflection = reflection + glossy;
  if (level > 0) return;
  SpecularParts& sp = out.specular;
  sp.gloss_direct = spec_direct[0];
  sp.gloss_indirect = spec_indirect[0];
  sp.trans_direct = spec_direct[1];
  sp.trans_indirect = spec_indirect[1];
  const Material& m = *hit.material;
  sp.gloss_color = m.type == MaterialType::kConductor ? conductor_fresnel(1.0f, m.eta_c, m.k_c, m.schlick, m.tint) : m.tint;
  if (m.type == MaterialType::kDielectric) sp.trans_color = m.transmittance;
}

void PathTracer::sample_layers(const Ray& camera_ray, PathContext& ctx, SampleResult& out) const {
  out.levels = 0;
  out.specular = SpecularParts{};
  decompose(camera_ray, 0, 0, ctx, out);
}

}  // namespace dnb::rt
