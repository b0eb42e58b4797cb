#include "tracer/scene.h"

#include <algorithm>

#include <fmt/format.h>

#include "core/errors.h"

namespace dnb {
using namespace rt;

namespace rt {

Vec3 Mesh::normal_at(unsigned prim, float b1, float b2, float time) const {
  // The normals of the two time steps around `time`, interpolated as Embree interpolates the
  // positions (linearly in time between steps), then across the triangle (not normalised).
  const float steps = float(time_steps() - 1);
  const float x = std::clamp(time, 0.0f, 1.0f) * steps;
  const int k = std::min(int(x), int(time_steps()) - 2);
  const float f = x - float(k);
  const std::vector<Vec3>& a = k == 0 ? normals : later_normals[k - 1];
  const std::vector<Vec3>& b = later_normals[k];
  const float b0 = 1.0f - b1 - b2;
  auto corner = [&](int c) { return a[3 * prim + c] * (1 - f) + b[3 * prim + c] * f; };
  return corner(0) * b0 + corner(1) * b1 + corner(2) * b2;
}

Vec3 SurfaceHit::spawn_origin(Vec3 dir) const {
  return p + ng * (dot(dir, ng) >= 0 ? offset : -offset);
}

Ray Camera::generate_moving_ray(float fx, float fy, int width, int height, float u1, float u2, float time) const {
  // The camera's pose at `time`: eye and look_at interpolated, the frame made from them.
  Camera c = *this;
  c.moving = false;
  c.eye = eye + (eye_end - eye) * time;
  c.look_at = look_at + (look_at_end - look_at) * time;
  c.prepare();
  Ray r = c.generate_ray(fx, fy, width, height, u1, u2);
  r.time = time;
  return r;
}

void Camera::prepare() {
  forward_ = normalize(look_at - eye);
  right_ = normalize(cross(forward_, up));
  up_ = cross(right_, forward_);
  tan_half_ = std::tan(vfov_degrees * kPi / 360.0f);
}

void Sky::average_gradient() {
  Vec3 sum(0.0f);
  const int n = 512;
  for (int i = 0; i < n; ++i) {
    float c = -1 + 2 * (i + 0.5f) / n;
    Vec3 d = up * c;  // only dot(d, up) matters
    d = d + Frame(up).t * std::sqrt(std::max(0.0f, 1 - c * c));
    sum += radiance(normalize(d));
  }
  average = sum / float(n);
}

Vec3 Sky::radiance(Vec3 dir) const {
  if (!enabled) return Vec3(0.0f);
  if (!gradient) return color;
  float c = dot(dir, up);
  if (c >= 0) {
    float w = std::pow(c, 0.5f);  // a bright band near the horizon, as real skies have
    return horizon * (1 - w) + zenith * w;
  }
  float w = std::min(1.0f, -c * 4.0f);
  return horizon * (1 - w) + ground * w;
}

}  // namespace rt

// Embree's device, its kernels capped at AVX2 (Scene::kEmbreeConfig). Embree picks its traversal and
// triangle kernels by the processor at run time, and its AVX-512 kernels compute hits that differ
// from the AVX2 kernels' in the last bits, so without a cap an AVX-512 machine rendered other
// images than an AVX2 machine from the same seed (docs/cluster.md). Capped, both run the same
// kernels. The cap also costs nothing here: on this project's AMD EPYC (Zen 4) development
// machine the AVX2 kernels made whole renders 3-6% faster than the AVX-512 ones (2026-12-07,
// docs/speed.md). Machines below AVX2 still get their own (SSE/AVX) kernels.
Scene::Scene() {
  device_ = rtcNewDevice(kEmbreeConfig);
  if (!device_) throw WorkError(fmt::format("cannot create an Embree device (error {})", int(rtcGetDeviceError(nullptr))));
}

Scene::~Scene() {
  if (rtc_) rtcReleaseScene(rtc_);
  if (device_) rtcReleaseDevice(device_);
}

std::size_t Scene::triangle_count() const {
  std::size_t n = 0;
  for (const auto& m : meshes) n += m.triangles();
  return n;
}

// The alpha cut-out test of Embree's filter functions (Scene::commit attaches it to the meshes
// whose materials have an opacity texture): a candidate hit where the opacity at its texture
// coordinates is under 0.5 is rejected, and Embree goes on to the next surface along the ray.
// Called for single rays and for packets alike (the shadow rays' packets of 16).
void Scene::cutout_filter(const RTCFilterFunctionNArguments* args) {
  const auto& c = *static_cast<const Cutout*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
    const Material& mat = c.scene->materials[c.mesh->material[prim]];
    if (mat.opacity < 0) continue;
    const float b1 = RTCHitN_u(args->hit, args->N, i), b2 = RTCHitN_v(args->hit, args->N, i);
    float u, v;
    c.mesh->uv_at(prim, b1, b2, u, v);
    if (c.scene->textures[mat.opacity]->opacity(u, v) < 0.5f) args->valid[i] = 0;
  }
}

void Scene::commit() {
  camera.prepare();
  // Cut-outs: the meshes with a triangle of a material that has an opacity texture.
  cutout_.clear();
  cutout_.resize(meshes.size());
  for (std::size_t gi = 0; gi < meshes.size(); ++gi)
    for (std::uint32_t mi : meshes[gi].material)
      if (materials[mi].opacity >= 0) {
        cutout_[gi] = std::make_unique<Cutout>(Cutout{this, &meshes[gi]});
        break;
      }
  rtc_ = rtcNewScene(device_);
  rtcSetSceneBuildQuality(rtc_, RTC_BUILD_QUALITY_HIGH);
  bmin_ = Vec3(1e30f);
  bmax_ = Vec3(-1e30f);
  for (std::size_t gi = 0; gi < meshes.size(); ++gi) {
    const Mesh& m = meshes[gi];
    RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
    const std::size_t nv = m.positions.size();
    if (m.moving()) rtcSetGeometryTimeStepCount(g, unsigned(m.time_steps()));
    for (std::size_t step = 0; step < m.time_steps(); ++step) {
      const std::vector<Vec3>& pos = step == 0 ? m.positions : m.later_positions[step - 1];
      auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, unsigned(step),
                                                             RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
      for (std::size_t i = 0; i < nv; ++i) {
        vb[3 * i] = pos[i].x;
        vb[3 * i + 1] = pos[i].y;
        vb[3 * i + 2] = pos[i].z;
        bmin_ = vmin(bmin_, pos[i]);
        bmax_ = vmax(bmax_, pos[i]);
      }
    }
    if (cutout_[gi]) {
      rtcSetGeometryUserData(g, cutout_[gi].get());
      rtcSetGeometryIntersectFilterFunction(g, &cutout_filter);
      rtcSetGeometryOccludedFilterFunction(g, &cutout_filter);
    }
    auto* ib = static_cast<unsigned*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), nv / 3));
    for (std::size_t i = 0; i < nv; ++i) ib[i] = unsigned(i);
    rtcCommitGeometry(g);
    unsigned id = rtcAttachGeometry(rtc_, g);
    rtcReleaseGeometry(g);
    if (id != gi) throw WorkError("Embree assigned an unexpected geometry id");
  }
  rtcCommitScene(rtc_);
  if (meshes.empty()) bmin_ = bmax_ = Vec3(0.0f);

  // Emitter distribution. Light groups are the emissive meshes, the sun and the sky; an
  // emitter is chosen with probability 1/2 (its share of the estimated power) + 1/2 (a uniform
  // choice of its group, then its share of the group's power). Power alone starves small
  // lights beside a bright but mostly occluded one (a lamp beside the sun behind a window);
  // the uniform half keeps every group sampled. Estimated power: luminance x area x pi per
  // emitting side for triangles; for sun and sky, what they send through a disc of the scene's
  // bounding radius. Any positive probabilities keep the estimator unbiased.
  emitters_.clear();
  emitter_cdf_.clear();
  select_prob_.assign(meshes.size(), {});
  std::vector<float> power;                  // per emitter, then sun, then sky
  std::vector<int> group;                    // group of each entry
  std::vector<double> group_power;
  sphere_of_mesh_.assign(meshes.size(), -1);
  for (std::size_t i = 0; i < sphere_lights.size(); ++i) sphere_of_mesh_[sphere_lights[i].mesh] = int(i);
  std::vector<float> sphere_power(sphere_lights.size(), 0.0f);
  for (std::size_t gi = 0; gi < meshes.size(); ++gi) {
    const Mesh& m = meshes[gi];
    int g = -1;
    for (std::size_t t = 0; t < m.triangles(); ++t) {
      const Material& mat = materials[m.material[t]];
      if (!mat.is_emitter()) continue;
      Vec3 a = m.positions[3 * t], b = m.positions[3 * t + 1], c = m.positions[3 * t + 2];
      float area = 0.5f * length(cross(b - a, c - a));
      if (!(area > 0)) continue;
      float w = luminance(mat.emission) * area * kPi * (mat.two_sided ? 2.0f : 1.0f);
      if (!(w > 0)) continue;
      if (sphere_of_mesh_[gi] >= 0) {  // sampled as a whole sphere, below
        sphere_power[sphere_of_mesh_[gi]] += w;
        continue;
      }
      if (g < 0) {
        g = int(group_power.size());
        group_power.push_back(0);
      }
      emitters_.push_back({unsigned(gi), unsigned(t), area, a, b - a, c - a, normalize(cross(b - a, c - a)), &mat});
      power.push_back(w);
      group.push_back(g);
      group_power[g] += w;
    }
  }
  Vec3 ext = bmax_ - bmin_;
  float radius = 0.5f * length(ext);
  float disc = kPi * radius * radius;
  float sun_w = sun.enabled ? luminance(sun.radiance) * sun.solid_angle() * disc : 0.0f;
  float sky_w = sky.enabled ? luminance(sky.average) * kPi * disc : 0.0f;
  for (float w : sphere_power) {
    power.push_back(w);
    group.push_back(w > 0 ? int(group_power.size()) : -1);
    if (w > 0) group_power.push_back(w);
  }
  for (float w : {sun_w, sky_w}) {
    power.push_back(w);
    if (w > 0) {
      group.push_back(int(group_power.size()));
      group_power.push_back(w);
    } else {
      group.push_back(-1);
    }
  }
  double total = 0;
  for (float w : power) total += w;
  const double ngroups = double(group_power.size());
  std::vector<float> prob(power.size(), 0.0f);
  for (std::size_t i = 0; i < power.size(); ++i)
    if (power[i] > 0 && total > 0)
      prob[i] = float(0.5 * power[i] / total + 0.5 / ngroups * power[i] / group_power[group[i]]);
  double acc = 0;
  for (float p : prob) {
    acc += p;
    emitter_cdf_.push_back(float(acc));
  }
  total_light_weight_ = total > 0 ? float(acc) : 0.0f;
  tri_select_.assign(prob.begin(), prob.begin() + emitters_.size());
  for (std::size_t i = 0; i < emitters_.size(); ++i) {
    auto& v = select_prob_[emitters_[i].mesh];
    if (v.empty()) v.assign(meshes[emitters_[i].mesh].triangles(), 0.0f);
    v[emitters_[i].prim] = tri_select_[i];
  }
  const std::size_t ns = sphere_lights.size();
  sphere_select_.assign(prob.begin() + emitters_.size(), prob.begin() + emitters_.size() + ns);
  sun_select_ = prob[emitters_.size() + ns];
  sky_select_ = prob[emitters_.size() + ns + 1];
}

void Scene::apply_normal_map(const Mesh& m, unsigned prim, const Texture& map, SurfaceHit& hit) {
  // The tangent frame of the triangle from its positions and texture coordinates (dp/du, dp/dv;
  // time 0's positions for a moving mesh), about the front-facing shading normal, so that the map
  // means the same whichever side the ray comes from; then flipped to the ray's side as the
  // shading normal is.
  const Vec3 p0 = m.positions[3 * prim], e1 = m.positions[3 * prim + 1] - p0, e2 = m.positions[3 * prim + 2] - p0;
  float du1 = 1, dv1 = 0, du2 = 0, dv2 = 1;  // no uvs: the barycentrics are (u, v)
  if (!m.uvs.empty()) {
    const float* uv = &m.uvs[6 * prim];
    du1 = uv[2] - uv[0], dv1 = uv[3] - uv[1], du2 = uv[4] - uv[0], dv2 = uv[5] - uv[1];
  }
  const float det = du1 * dv2 - du2 * dv1;
  if (!(std::fabs(det) > 1e-12f)) return;  // degenerate texture coordinates: no frame
  const Vec3 dpdu = (e1 * dv2 - e2 * dv1) * (1.0f / det), dpdv = (e2 * du1 - e1 * du2) * (1.0f / det);
  const Vec3 n = hit.front ? hit.ns : -hit.ns;
  Vec3 t = dpdu - n * dot(n, dpdu);
  if (!(length(t) > 0)) return;
  t = normalize(t);
  Vec3 b = cross(n, t);
  if (dot(b, dpdv) < 0) b = -b;  // mirrored texture coordinates
  const Vec3 c = map.eval(hit.u, hit.v) * 2.0f - Vec3(1.0f);
  Vec3 mapped = t * c.x + b * c.y + n * c.z;
  if (!(length(mapped) > 0)) return;
  mapped = normalize(hit.front ? mapped : -mapped);
  // A mapped normal on the other side of the surface than the ray is not a shading normal the
  // integrator can use (its samples would go below the surface): the unmapped one stays.
  if (dot(mapped, hit.ng) > 0) hit.ns = mapped;
}

void Scene::fill_hit(const Ray& ray, const RTCRayHit& rh, SurfaceHit& hit) const {
  const Mesh& m = meshes[rh.hit.geomID];
  const unsigned prim = rh.hit.primID;
  const float b1 = rh.hit.u, b2 = rh.hit.v, b0 = 1.0f - b1 - b2;
  hit.t = rh.ray.tfar;
  hit.geom = rh.hit.geomID;
  hit.prim = prim;
  hit.p = ray.origin + ray.dir * hit.t;
  Vec3 ng = normalize(Vec3(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z));
  hit.front = dot(ng, ray.dir) < 0;
  if (!hit.front) ng = -ng;
  hit.ng = ng;
  hit.time = ray.time;
  if (!m.normals.empty()) {
    Vec3 ns = m.later_normals.empty() ? m.normals[3 * prim] * b0 + m.normals[3 * prim + 1] * b1 + m.normals[3 * prim + 2] * b2
                                      : m.normal_at(prim, b1, b2, ray.time);
    ns = normalize(ns);
    if (dot(ns, ng) < 0) ns = -ns;
    hit.ns = ns;
  } else {
    hit.ns = ng;
  }
  m.uv_at(prim, b1, b2, hit.u, hit.v);
  hit.material = &materials[m.material[prim]];
  const Material& mat = *hit.material;
  if (mat.normal_map >= 0) apply_normal_map(m, prim, *textures[std::size_t(mat.normal_map)], hit);
  if (mat.roughness_map >= 0)
    hit.roughness_scale = std::clamp(textures[std::size_t(mat.roughness_map)]->eval(hit.u, hit.v).x, 0.0f, 1.0f);
  if (mat.type == MaterialType::kMirror || mat.type == MaterialType::kConductor || mat.type == MaterialType::kDielectric) {
    hit.albedo = Vec3(0.0f);
  } else {
    hit.albedo = mat.albedo;
    if (mat.texture >= 0) hit.albedo *= textures[mat.texture]->eval(hit.u, hit.v);
  }
  float mag = std::max(std::max(std::fabs(hit.p.x), std::fabs(hit.p.y)), std::fabs(hit.p.z));
  hit.offset = ray_offset(mag);
}

bool Scene::intersect(const Ray& ray, SurfaceHit& hit) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRayHit rh;
  rh.ray.org_x = ray.origin.x;
  rh.ray.org_y = ray.origin.y;
  rh.ray.org_z = ray.origin.z;
  rh.ray.dir_x = ray.dir.x;
  rh.ray.dir_y = ray.dir.y;
  rh.ray.dir_z = ray.dir.z;
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = ray.tmax;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.flags = 0;
  rh.ray.time = ray.time;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(rtc_, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
  fill_hit(ray, rh, hit);
  return true;
}

namespace {

// Rays [first, first + m) of `rays` (m <= 16) as an Embree packet: lane i < m holds ray
// first + i, the lanes past m repeat the last ray and are masked off in `valid`.
void load_packet(const Ray* rays, int first, int m, RTCRay16& r, int (&valid)[16]) {
  for (int i = 0; i < 16; ++i) {
    const Ray& ray = rays[first + std::min(i, m - 1)];
    valid[i] = i < m ? -1 : 0;
    r.org_x[i] = ray.origin.x;
    r.org_y[i] = ray.origin.y;
    r.org_z[i] = ray.origin.z;
    r.dir_x[i] = ray.dir.x;
    r.dir_y[i] = ray.dir.y;
    r.dir_z[i] = ray.dir.z;
    r.tnear[i] = 0.0f;
    r.tfar[i] = ray.tmax;
    r.mask[i] = 0xFFFFFFFFu;
    r.id[i] = unsigned(i);
    r.flags[i] = 0;
    r.time[i] = ray.time;
  }
}

}  // namespace

void Scene::intersect(const Ray* rays, int n, SurfaceHit* hits, std::uint8_t* found) const {
  for (int first = 0; first < n; first += 16) {
    const int m = std::min(16, n - first);
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);  // not COHERENT: see occluded(rays, n, hidden) below
    alignas(64) RTCRayHit16 rh;
    alignas(64) int valid[16];
    load_packet(rays, first, m, rh.ray, valid);
    for (int i = 0; i < 16; ++i) {
      rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
    }
    rtcIntersect16(valid, rtc_, &ctx, &rh);
    for (int i = 0; i < m; ++i) {
      found[first + i] = rh.hit.geomID[i] != RTC_INVALID_GEOMETRY_ID ? 1 : 0;
      if (!found[first + i]) continue;
      RTCRayHit one;  // lane i as fill_hit reads a single ray's hit
      one.ray.tfar = rh.ray.tfar[i];
      one.hit.u = rh.hit.u[i];
      one.hit.v = rh.hit.v[i];
      one.hit.Ng_x = rh.hit.Ng_x[i];
      one.hit.Ng_y = rh.hit.Ng_y[i];
      one.hit.Ng_z = rh.hit.Ng_z[i];
      one.hit.geomID = rh.hit.geomID[i];
      one.hit.primID = rh.hit.primID[i];
      fill_hit(rays[first + i], one, hits[first + i]);
    }
  }
}

bool Scene::occluded(const Ray& ray) const {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  RTCRay r;
  r.org_x = ray.origin.x;
  r.org_y = ray.origin.y;
  r.org_z = ray.origin.z;
  r.dir_x = ray.dir.x;
  r.dir_y = ray.dir.y;
  r.dir_z = ray.dir.z;
  r.tnear = 0.0f;
  r.tfar = ray.tmax;
  r.mask = 0xFFFFFFFFu;
  r.flags = 0;
  r.time = ray.time;
  rtcOccluded1(rtc_, &ctx, &r);
  return r.tfar < 0;  // Embree sets tfar = -inf on a hit
}

void Scene::occluded(const rt::Ray* rays, int n, std::uint8_t* hidden) const {
  for (int first = 0; first < n; first += 16) {
    const int m = std::min(16, n - first);
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    // Not RTC_INTERSECT_CONTEXT_FLAG_COHERENT: with it Embree 3.13.5 reported some unoccluded
    // lanes as occluded when the packet mixed hidden and visible light samples (caught by
    // DirectLight.BatchedShadowRaysEqualOneByOne).
    RTCRay16 r;
    int valid[16];
    load_packet(rays, first, m, r, valid);
    rtcOccluded16(valid, rtc_, &ctx, &r);
    for (int i = 0; i < m; ++i) hidden[first + i] = r.tfar[i] < 0 ? 1 : 0;
  }
}

bool Scene::in_sun(Vec3 dir) const { return sun.enabled && dot(dir, sun.direction) >= sun.cos_max; }

Vec3 Scene::escaped_radiance(Vec3 dir, bool in_sun) const {
  Vec3 L = sky.radiance(dir);
  if (in_sun) L += sun.radiance;
  return L;
}

bool Scene::sample_light(Vec3 p, Vec3 n, float u0, float u1, float u2, LightSample& out) const {
  if (total_light_weight_ <= 0) return false;
  const float target = u0 * total_light_weight_;
  const std::size_t ntri = emitters_.size();
  std::size_t idx = std::size_t(std::upper_bound(emitter_cdf_.begin(), emitter_cdf_.end(), target) -
                                emitter_cdf_.begin());
  // upper_bound never lands on a zero-weight entry (its cdf equals the previous one) unless
  // u0 * total rounded up to total: then take the last entry of positive weight.
  if (idx >= emitter_cdf_.size()) {
    idx = emitter_cdf_.size() - 1;
    while (idx > 0 && emitter_cdf_[idx] == emitter_cdf_[idx - 1]) --idx;
  }
  if (idx < ntri) {
    const EmissiveTriangle& e = emitters_[idx];
    // Uniform point on the triangle.
    float su = std::sqrt(u1);
    float b1 = 1 - su, b2 = u2 * su;
    Vec3 q = e.p0 + e.e1 * b1 + e.e2 * b2;
    Vec3 d = q - p;
    float dist2 = dot(d, d);
    if (!(dist2 > 0)) return false;
    float dist = std::sqrt(dist2);
    Vec3 wi = d / dist;
    float cos_l = -dot(e.normal, wi);
    const Material& mat = *e.material;
    if (cos_l <= 0) {
      if (!mat.two_sided) return false;
      cos_l = -cos_l;
    }
    if (cos_l < 1e-7f) return false;
    out.wi = wi;
    out.dist = dist;
    out.radiance = mat.emission;
    out.pdf = tri_select_[idx] * dist2 / (cos_l * e.area);
    return true;
  }
  const std::size_t nsph = sphere_lights.size();
  if (idx < ntri + nsph) {
    const SphereLight& l = sphere_lights[idx - ntri];
    float pdf = sphere_pdf(l, p);
    if (!(pdf > 0)) return false;
    Vec3 d = l.center - p;
    float dist = length(d);
    float cos_max = std::sqrt(std::max(0.0f, 1 - (l.radius * l.radius) / (dist * dist)));
    out.wi = Frame(d / dist).to_world(sample_cone(u1, u2, cos_max));
    out.dist = 1e30f;
    out.radiance = materials[meshes[l.mesh].material[0]].emission;
    out.pdf = sphere_select_[idx - ntri] * pdf;
    out.sphere_mesh = int(l.mesh);
    return true;
  }
  if (idx == ntri + nsph) {
    Frame f(sun.direction);
    out.wi = f.to_world(sample_cone(u1, u2, sun.cos_max));
    out.dist = 1e30f;
    // The disc's radiance only where the direction is in the disc by the test every other use
    // makes: a sample that rounded to just outside it is a sky direction, with the sky's density.
    const bool inside = in_sun(out.wi);
    out.radiance = escaped_radiance(out.wi, inside);
    out.pdf = escaped_light_pdf(out.wi, n, inside);
    return true;
  }
  out.wi = Frame(n).to_world(sample_cosine_hemisphere(u1, u2));
  out.dist = 1e30f;
  const bool inside = in_sun(out.wi);
  out.radiance = escaped_radiance(out.wi, inside);
  out.pdf = escaped_light_pdf(out.wi, n, inside);
  return out.pdf > 0;
}

float Scene::sphere_pdf(const SphereLight& l, Vec3 from) const {
  // Uniform in the cone of the bounding sphere; from inside it there is no cone (such points
  // get no light sample from this sphere, only BSDF hits, weighted 1 by MIS).
  Vec3 d = l.center - from;
  float d2 = dot(d, d), r2 = l.radius * l.radius;
  if (d2 <= r2 * 1.0001f) return 0;
  float cos_max = std::sqrt(1 - r2 / d2);
  return 1.0f / (2 * kPi * (1 - cos_max));
}

float Scene::light_pdf(Vec3 from, const SurfaceHit& hit) const {
  if (int si = sphere_of_mesh_[hit.geom]; si >= 0) {
    if (!hit.front && !hit.material->two_sided) return 0;
    return sphere_select_[si] * sphere_pdf(sphere_lights[si], from);
  }
  const auto& v = select_prob_[hit.geom];
  if (v.empty()) return 0;
  float sel = v[hit.prim];
  if (sel <= 0) return 0;
  if (!hit.front && !hit.material->two_sided) return 0;
  const Mesh& m = meshes[hit.geom];
  Vec3 a = m.positions[3 * hit.prim], b = m.positions[3 * hit.prim + 1], c = m.positions[3 * hit.prim + 2];
  Vec3 cr = cross(b - a, c - a);
  float area = 0.5f * length(cr);
  Vec3 d = hit.p - from;
  float dist2 = dot(d, d);
  float cos_l = std::fabs(dot(normalize(cr), normalize(d)));
  if (cos_l < 1e-7f) return 0;
  return sel * dist2 / (cos_l * area);
}

float Scene::escaped_light_pdf(Vec3 dir, Vec3 n, bool in_sun) const {
  // The sun and the sky are both sampled, and both contribute along a direction inside the
  // sun's disc: the density is the sum over the two strategies' choices.
  float pdf = 0;
  if (sun_select_ > 0 && in_sun) pdf += sun_select_ / sun.solid_angle();
  if (sky_select_ > 0) pdf += sky_select_ * std::max(0.0f, dot(dir, n)) * kInvPi;
  return pdf;
}

}  // namespace dnb
