// The scene as the tracer and renderer-type methods (irradiance_cache/) see it: camera,
// triangle meshes in one Embree 3 scene, materials, emitters (emissive triangles, a sun, a sky),
// and the queries a renderer needs: primary rays, closest hit with full surface data, shadow
// rays, and light sampling for next-event estimation.
//
// Conventions
// - World units are whatever the scene file uses (metres in the built-in scenes); y is up in
//   the built-in scenes, but nothing depends on it except the sky gradient's `up`.
// - Every surface is a triangle. Primitives (quad, box, sphere, cylinder) are tessellated at
//   load time; spheres and cylinders carry interpolated shading normals.
// - The *front* of a triangle is the side its counter-clockwise winding faces
//   (cross(p1 - p0, p2 - p0)). Emitters emit from the front only unless their material says
//   `two_sided = true`. Diffuse, mirror and coated surfaces reflect on both sides.
// - Radiance is linear RGB.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <embree3/rtcore.h>

#include "tracer/math.h"
#include "tracer/texture.h"

namespace dnb {

namespace rt {

struct Ray {
  Vec3 origin;
  Vec3 dir;  // unit length
  float tmax = 1e30f;
  float time = 0;  // in the frame interval [0, 1]: where moving geometry is (Camera's shutter)
};

enum class MaterialType : std::uint8_t {
  kDiffuse,  // Lambertian, albedo = `albedo` x texture
  kMirror,   // perfect mirror, reflectance `tint`
  kCoated,   // Lambertian base (as kDiffuse) under a smooth dielectric coat of index `ior`: the coat
             // reflects a Fresnel (Schlick) fraction Fr(cos) as a perfect mirror (times `tint`),
             // the base receives 1 - Fr(cos). (Energy is not exactly conserved at grazing
             // angles; the usual simplification of a "plastic" material.)
  // The hard materials (tracer/bsdf.h; their lobes are sampled, evaluated and light-sampled):
  kConductor,   // GGX metal: complex index eta_c + i k_c (or a Schlick tint), roughness alpha_x/y
  kDielectric,  // glass: smooth or GGX rough, index `ior`, reflection `tint`, transmission `transmittance`,
                // absorption `absorption` per unit length inside (Beer), or a thin sheet
  kPlastic,     // a smooth or GGX coat of index `ior` and reflectance `tint` over a diffuse base `albedo`
};

struct Material {
  std::string name;
  MaterialType type = MaterialType::kDiffuse;
  Vec3 albedo{0.8f};        // diffuse reflectance (multiplied by the texture when there is one)
  int texture = -1;         // index into Scene::textures, or -1
  Vec3 tint{1.0f};          // mirror / coat reflectance
  float ior = 1.5f;         // coat index of refraction (kCoated)
  Vec3 emission{0.0f};      // emitted radiance (front face unless two_sided)
  bool two_sided = false;   // emission on both faces
  // Hard materials (kConductor, kDielectric, kPlastic); `roughness` is GGX's alpha (0: smooth),
  // anisotropic when alpha_x != alpha_y (x along the shading frame's tangent, built from the normal).
  float alpha_x = 0, alpha_y = 0;
  Vec3 eta_c{0.2f}, k_c{3.9f};  // conductor's complex index
  bool schlick = false;          // conductor: F = Schlick with F0 = tint instead of eta_c, k_c
  Vec3 transmittance{1.0f};      // dielectric: colour of the transmitted lobe
  Vec3 absorption{0.0f};         // dielectric: Beer absorption coefficient inside (per world unit)
  bool thin = false;             // dielectric: a thin sheet (window pane), smooth only
  float base_inner_reflectance = 0;  // plastic: fresnel_diffuse_reflectance(1 / ior), set by the loader
  // Alpha cut-out: index into Scene::textures of the opacity (Texture::opacity), or -1. The
  // surface is there where the opacity is at least 0.5 and a hole elsewhere, for every ray
  // (camera, shadow, light and AOV rays alike: an Embree filter function, Scene::commit).
  int opacity = -1;
  // A tangent-space normal map (Scene::textures, linear RGB in [0, 1] -> [-1, 1], z along the
  // surface normal, x along increasing u, y along increasing v), or -1.
  int normal_map = -1;
  // Hard materials: GGX alpha (both axes) times this texture's first channel, or -1.
  int roughness_map = -1;
  bool is_hard() const { return type >= MaterialType::kConductor; }
  bool is_specular() const { return type != MaterialType::kDiffuse; }
  bool is_emitter() const { return !is_black(emission); }
};

// Schlick's approximation of the dielectric Fresnel reflectance for the coat.
inline float fresnel_schlick(float cos_theta, float ior) {
  float r0 = (ior - 1) / (ior + 1);
  r0 *= r0;
  float m = 1.0f - std::clamp(cos_theta, 0.0f, 1.0f);
  float m2 = m * m;
  return r0 + (1 - r0) * m2 * m2 * m;
}

// One triangle mesh = one Embree geometry (geomID = index in Scene::meshes). Corners are not
// shared: corner 3*i+k belongs to triangle i, so normals and uvs need no separate index lists.
struct Mesh {
  std::string name;
  std::vector<Vec3> positions;        // 3 per triangle
  std::vector<Vec3> normals;          // 3 per triangle, or empty (flat shading)
  std::vector<float> uvs;             // 6 per triangle, or empty (uv = barycentrics)
  std::vector<std::uint32_t> material;  // 1 per triangle (index into Scene::materials)
  // Motion blur: the corners at the later time steps k = 1 .. n - 1 of the frame interval
  // (time k / (n - 1)); `positions` and `normals` are step 0. Embree interpolates linearly
  // between steps; a rotating object has enough steps for that to follow its arc. Empty: static.
  std::vector<std::vector<Vec3>> later_positions, later_normals;
  std::size_t triangles() const { return positions.size() / 3; }
  bool moving() const { return !later_positions.empty(); }
  std::size_t time_steps() const { return 1 + later_positions.size(); }
  // Texture coordinates of triangle prim at barycentrics (b1, b2) (the barycentrics themselves
  // where the mesh has none).
  void uv_at(unsigned prim, float b1, float b2, float& u, float& v) const {
    if (uvs.empty()) {
      u = b1;
      v = b2;
      return;
    }
    const float* uv = &uvs[6 * prim];
    const float b0 = 1.0f - b1 - b2;
    u = uv[0] * b0 + uv[2] * b1 + uv[4] * b2;
    v = uv[1] * b0 + uv[3] * b1 + uv[5] * b2;
  }
  // The interpolated (unnormalised) shading normal of a moving mesh at `time`.
  Vec3 normal_at(unsigned prim, float b1, float b2, float time) const;
};

// How far off a surface rays leave it, at a point whose largest coordinate magnitude is `mag`
// (SurfaceHit::offset): it grows with the magnitude, as the spacing of floats does.
inline float ray_offset(float mag) { return 1e-4f * std::max(1.0f, mag); }

// Everything a renderer needs at a ray's closest hit.
struct SurfaceHit {
  float t = 0;                // distance along the (unit) ray
  Vec3 p;                     // position
  Vec3 ng;                    // unit geometric normal, flipped to face the incoming ray
  Vec3 ns;                    // unit shading normal, flipped to the same side as ng
  float u = 0, v = 0;         // texture coordinates
  float time = 0;             // the ray's time (Ray::time): rays leaving this hit carry it
  float roughness_scale = 1;  // the material's roughness map at (u, v) (Material::roughness_map)
  bool front = true;          // the ray hit the triangle's front (winding) side
  unsigned geom = 0, prim = 0;
  const Material* material = nullptr;
  Vec3 albedo;                // diffuse albedo at the hit: material albedo x texture (0 for mirrors)
  // Radiance emitted towards the ray's origin (0 unless an emitter seen from its emitting side).
  Vec3 emitted() const {
    return (front || material->two_sided) ? material->emission : Vec3(0.0f);
  }
  // A ray origin just off the surface on the side of `dir`, so that the new ray does not hit
  // this triangle again (nor a coplanar duplicate of it, as in CornellBox-Original.obj).
  Vec3 spawn_origin(Vec3 dir) const;
  // A ray from spawn_origin(dir) along dir, at this hit's time.
  Ray spawn_ray(Vec3 dir, float tmax = 1e30f) const { return Ray{spawn_origin(dir), dir, tmax, time}; }
  float offset = 1e-4f;       // size of that offset (scales with the position's magnitude)
};

struct Camera {
  Vec3 eye{0, 0, 0};
  Vec3 look_at{0, 0, -1};
  Vec3 up{0, 1, 0};
  float vfov_degrees = 45.0f;
  // A pinhole camera ray through film position (fx, fy) in pixels, (0, 0) being the top-left
  // corner of the image and (width, height) the bottom-right one. Call prepare() after
  // changing eye, look_at, up or vfov (Scene::commit does).
  Ray generate_ray(float fx, float fy, int width, int height) const {
    float sx = (2.0f * fx / width - 1.0f) * tan_half_ * (float(width) / float(height));
    float sy = (1.0f - 2.0f * fy / height) * tan_half_;
    return Ray{eye, normalize(forward_ + right_ * sx + up_ * sy), 1e30f};
  }
  // Thin lens (depth of field): with aperture_radius > 0 the ray leaves a point of the lens disc
  // (eye + radius (lu, lv) in the camera's right/up plane, (lu, lv) from (u1, u2) by the concentric
  // map) towards the point of the pinhole ray at distance focus_distance along the view axis, so
  // that the plane at focus_distance is sharp. With aperture_radius = 0 it is the pinhole ray.
  Ray generate_ray(float fx, float fy, int width, int height, float u1, float u2) const {
    Ray r = generate_ray(fx, fy, width, height);
    if (!(aperture_radius > 0)) return r;
    float lu, lv;
    concentric_disk(u1, u2, lu, lv);
    const Vec3 focus = eye + r.dir * (focus_distance / dot(r.dir, forward_));
    r.origin = eye + right_ * (lu * aperture_radius) + up_ * (lv * aperture_radius);
    r.dir = normalize(focus - r.origin);
    return r;
  }
  float aperture_radius = 0;   // lens radius in scene units (0: pinhole)
  float focus_distance = 1;    // distance of the sharp plane along the view axis
  bool has_lens() const { return aperture_radius > 0; }

  // Motion blur. The shutter is open over [shutter_open, shutter_close] of the frame interval
  // [0, 1]; a sample's time is uniform in it (time_at). Moving geometry is where its transform
  // puts it at that time; the camera moves from (eye, look_at) at time 0 to (eye_end,
  // look_at_end) at time 1, linearly. A closed shutter (open == close) renders the one instant.
  float shutter_open = 0, shutter_close = 0;
  Vec3 eye_end, look_at_end;  // prepare() sets them to eye, look_at unless moving
  bool moving = false;        // the camera moves (eye_end or look_at_end differ)
  bool has_shutter() const { return shutter_close > shutter_open; }
  // Whether rays need a time other than 0: a shutter interval, a moving camera, or one instant
  // after time 0.
  bool timed() const { return has_shutter() || moving || shutter_open > 0; }
  float time_at(float u) const { return shutter_open + (shutter_close - shutter_open) * u; }
  // The ray of generate_ray(fx, fy, width, height, u1, u2) with the camera where it is at
  // `time`, carrying the time.
  Ray generate_ray_at(float fx, float fy, int width, int height, float u1, float u2, float time) const {
    if (moving) return generate_moving_ray(fx, fy, width, height, u1, u2, time);
    Ray r = has_lens() ? generate_ray(fx, fy, width, height, u1, u2) : generate_ray(fx, fy, width, height);
    r.time = time;
    return r;
  }
  void prepare();
  // Film position (fx, fy) in pixels of world point p seen by this camera at time 0 (the
  // inverse of the pinhole generate_ray); false when p is not in front of the camera.
  bool project(Vec3 p, int width, int height, float& fx, float& fy) const {
    return project_direction(p - eye, width, height, fx, fy);
  }
  // The same for a point at infinity in direction d (the sky): only the camera's rotation moves it.
  bool project_direction(Vec3 d, int width, int height, float& fx, float& fy) const {
    const float z = dot(d, forward_);
    if (!(z > 0)) return false;
    const float sx = dot(d, right_) / z, sy = dot(d, up_) / z;
    fx = (sx / (tan_half_ * (float(width) / float(height))) + 1.0f) * 0.5f * float(width);
    fy = (1.0f - sy / tan_half_) * 0.5f * float(height);
    return true;
  }

 private:
  Ray generate_moving_ray(float fx, float fy, int width, int height, float u1, float u2, float time) const;
  Vec3 forward_{0, 0, -1}, right_{1, 0, 0}, up_{0, 1, 0};
  float tan_half_ = 0.41421356f;
};

// The sky: radiance arriving from directions no surface blocks.
struct Sky {
  bool enabled = false;
  bool gradient = false;
  Vec3 color{0.0f};                       // constant sky
  Vec3 zenith{0.0f}, horizon{0.0f}, ground{0.0f};  // gradient sky: blended by dot(dir, up)
  Vec3 up{0, 1, 0};
  Vec3 radiance(Vec3 dir) const;
  Vec3 average = Vec3(0.0f);              // mean radiance over the sphere (for light selection)
  // Sets `average` of a gradient sky (by quadrature in the cosine, on which alone it depends).
  void average_gradient();
};

// A directional sun of angular radius `angular_radius`: a disc of constant radiance
// `radiance` around `direction` (pointing towards the sun).
struct Sun {
  bool enabled = false;
  Vec3 direction{0, 1, 0};
  Vec3 radiance{0.0f};
  float cos_max = 1.0f;  // cos(angular radius)
  float solid_angle() const { return 2 * kPi * (1 - cos_max); }
};

// One light sample for next-event estimation.
struct LightSample {
  Vec3 wi;            // unit direction from the shading point to the light
  float dist = 0;     // distance to the light point (1e30 for sun and sky)
  Vec3 radiance;      // emitted radiance arriving along -wi (before visibility)
  float pdf = 0;      // solid-angle density of choosing wi, light selection included
  // A sphere light's sample is a direction in the cone of its bounding sphere: the emitter is
  // whatever the ray hits first, which must be a front face of mesh `sphere_mesh` (then its
  // emission is `radiance`); dist is 1e30 and visibility is a closest-hit query.
  int sphere_mesh = -1;
};

// A spherical area light ([[lights]] type = "sphere"): its tessellated mesh, and the sphere
// through the mesh's vertices (which contains the mesh). Sampled by the cone of directions the
// sphere subtends, which is far better than sampling its triangles by area (half of which face
// away from any shading point).
struct SphereLight {
  unsigned mesh = 0;
  Vec3 center;
  float radius = 0;
};

}  // namespace rt

class Scene {
 public:
  // The configuration of every Scene's Embree device: the kernels capped at AVX2, so that AVX2
  // and AVX-512 machines compute the same hits (scene.cpp, Scene::Scene; part of tracer 7).
  static constexpr const char* kEmbreeConfig = "max_isa=avx2";
  Scene();
  ~Scene();
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  // ---- content (filled by the loader, then commit()) ----
  std::string name;                 // built-in name or file stem
  std::string source_file;          // the scene TOML
  std::vector<std::string> files;   // every file read (TOML, meshes, textures) for the content hash
  std::string content_hash;         // scene_content_hash, computed by load_scene
  // Animated scenes ([animation], docs/sequences.md): the sequence's length and the frame this
  // scene is (its keys evaluated there). A still: frames = 0, frame = 0.
  int frames = 0;
  int frame = 0;
  bool animated() const { return frames > 0; }
  rt::Camera camera;
  std::vector<rt::Material> materials;
  std::vector<std::unique_ptr<rt::Texture>> textures;
  std::vector<rt::Mesh> meshes;
  rt::Sky sky;
  rt::Sun sun;
  std::vector<rt::SphereLight> sphere_lights;

  // Builds the Embree scene and the emitter distribution. Called once by the loader.
  void commit();

  // ---- queries (thread-safe after commit) ----
  // Closest hit along the ray in (0, ray.tmax); false on a miss.
  bool intersect(const rt::Ray& ray, rt::SurfaceHit& hit) const;
  // intersect() for n rays at once (Embree packets of 16): found[i] = 1 and hits[i] filled when
  // rays[i] hits something, found[i] = 0 (hits[i] untouched) on a miss; the same hits as
  // intersect() one by one, bit for bit (Embree's packet and single-ray kernels run the same
  // triangle test; tested). Not used by the integrator: BM_BounceRays measures what packets gain
  // (little under the AVX2 cap), and a wavefront integrator built on them was slower than
  // tracing one path at a time (docs/speed.md).
  void intersect(const rt::Ray* rays, int n, rt::SurfaceHit* hits, std::uint8_t* found) const;
  // True when something blocks the segment origin + t dir, t in (0, tmax).
  bool occluded(const rt::Ray& ray) const;
  // occluded() for n rays at once (Embree packets of 16): hidden[i] = 1 when rays[i] is
  // blocked, else 0. Shadow rays from one point towards the lights are coherent, and a packet
  // traverses them together. The same answers as occluded() one by one except for a ray whose
  // blocker is exactly at tmax, which Embree's single-ray kernel counts and its packet kernel
  // may not (seen once in a 96x72, 16-spp cornell-box render; docs/speed.md).
  void occluded(const rt::Ray* rays, int n, std::uint8_t* hidden) const;
  // Whether `dir` is inside the sun's disc. Every use of the disc asks this once per direction
  // and passes the answer on, so that a direction's radiance and its density never disagree at
  // the rim: a cone sample turned into world space may round to just outside the disc, and two
  // inlined copies of the test may round differently (-O1 against -O3 contraction).
  bool in_sun(rt::Vec3 dir) const;
  // Radiance arriving along a ray that escapes the scene (sky plus the sun's disc).
  rt::Vec3 escaped_radiance(rt::Vec3 dir) const { return escaped_radiance(dir, in_sun(dir)); }
  rt::Vec3 escaped_radiance(rt::Vec3 dir, bool in_sun) const;

  // Chooses an emitter (emissive triangle, sun or sky; see Scene::commit for the probabilities)
  // and a point or direction on it, for a shading point `p` with shading normal `n` (the sky is
  // sampled by a cosine-weighted hemisphere about n). Returns false when the scene has no
  // emitter or the sample is unusable. u0 selects the emitter, (u1, u2) the point.
  bool sample_light(rt::Vec3 p, rt::Vec3 n, float u0, float u1, float u2, rt::LightSample& out) const;
  // The solid-angle density with which sample_light() from `from` would have produced the
  // emitter point `hit`, and the same for an escaped direction from a point of normal n.
  float light_pdf(rt::Vec3 from, const rt::SurfaceHit& hit) const;
  float escaped_light_pdf(rt::Vec3 dir, rt::Vec3 n) const { return escaped_light_pdf(dir, n, in_sun(dir)); }
  float escaped_light_pdf(rt::Vec3 dir, rt::Vec3 n, bool in_sun) const;
  bool has_lights() const { return total_light_weight_ > 0; }

  rt::Vec3 bounds_min() const { return bmin_; }
  rt::Vec3 bounds_max() const { return bmax_; }
  std::size_t triangle_count() const;

 private:
  void fill_hit(const rt::Ray& ray, const RTCRayHit& rh, rt::SurfaceHit& hit) const;
  // Alpha cut-outs (Material::opacity): the filter function and what it reads per mesh.
  struct Cutout {
    const Scene* scene;
    const rt::Mesh* mesh;
  };
  static void cutout_filter(const RTCFilterFunctionNArguments* args);
  // Material::normal_map applied to hit.ns.
  static void apply_normal_map(const rt::Mesh& m, unsigned prim, const rt::Texture& map, rt::SurfaceHit& hit);
  std::vector<std::unique_ptr<Cutout>> cutout_;  // per mesh; null where no material cuts out

  RTCDevice device_ = nullptr;
  RTCScene rtc_ = nullptr;
  rt::Vec3 bmin_, bmax_;
  // Emitter distribution: emissive triangles (in order), then the sun, then the sky.
  struct EmissiveTriangle {
    unsigned mesh, prim;
    float area;
    rt::Vec3 p0, e1, e2, normal;  // corner, edges, unit normal (winding side)
    const rt::Material* material;
  };
  std::vector<EmissiveTriangle> emitters_;
  std::vector<float> emitter_cdf_;   // over emitters_, then sun, then sky (sums to 1)
  std::vector<float> tri_select_;    // per emissive triangle: selection probability
  // Selection probability of emissive triangle (mesh, prim), looked up on BSDF hits.
  std::vector<std::vector<float>> select_prob_;
  float sun_select_ = 0, sky_select_ = 0;
  std::vector<float> sphere_select_;   // per sphere light: selection probability
  std::vector<int> sphere_of_mesh_;    // per mesh: index into sphere_lights, or -1
  float sphere_pdf(const rt::SphereLight& l, rt::Vec3 from) const;  // cone density, no selection
  float total_light_weight_ = 0;
};

}  // namespace dnb
