// Scene files (TOML) and OBJ/MTL meshes -> Scene. The format is documented in
// configs/scenes/README.md; every table's keys are read where their defaults are written and
// finish() rejects any other key (core/config.h).
#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>

#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include "core/config.h"
#include "core/errors.h"
#include "tracer/render.h"
#include "tracer/scene.h"

namespace fs = std::filesystem;

namespace dnb {
using namespace rt;

namespace {

using Arr3 = std::array<double, 3>;
Vec3 vec3(const Arr3& a) { return {float(a[0]), float(a[1]), float(a[2])}; }

// Where the built-in scene files live: $DNB_SOURCE_DIR/configs/scenes when set (tests), else
// the source tree this program was built from.
fs::path builtin_dir() {
  if (const char* s = std::getenv("DNB_SOURCE_DIR"); s && *s) {
    fs::path p = fs::path(s) / "configs" / "scenes";
    if (fs::is_directory(p)) return p;
  }
  return fs::path(DNB_SOURCE_SCENES_DIR);
}

// The McGuire scenes folder: --scenes-dir, else $DENOISEBENCH_SCENES, else ../shared/scenes
// beside the repository. Empty when none exists.
fs::path mcguire_dir(const SceneLoadOptions& o) {
  if (!o.scenes_dir.empty()) return o.scenes_dir;
  if (const char* s = std::getenv("DENOISEBENCH_SCENES"); s && *s) return s;
  // ../shared/scenes beside the repository; a git worktree one or two folders further down
  // (worktrees/NAME) also finds it, by looking up to two more levels up.
  fs::path dir = builtin_dir().parent_path().parent_path().parent_path();
  for (int up = 0; up < 3 && !dir.empty(); ++up, dir = dir.parent_path()) {
    fs::path p = dir / "shared" / "scenes";
    if (fs::is_directory(p)) return p;
    if (dir == dir.parent_path()) break;
  }
  return {};
}

// An affine transform: scale (uniform), then rotations about x, y, z (degrees), then translate.
struct Transform {
  float scale = 1;
  Vec3 rot_deg;
  Vec3 translate;
  Vec3 rotate(Vec3 v) const {
    auto rx = rot_deg.x * kPi / 180, ry = rot_deg.y * kPi / 180, rz = rot_deg.z * kPi / 180;
    v = {v.x, v.y * std::cos(rx) - v.z * std::sin(rx), v.y * std::sin(rx) + v.z * std::cos(rx)};
    v = {v.x * std::cos(ry) + v.z * std::sin(ry), v.y, -v.x * std::sin(ry) + v.z * std::cos(ry)};
    v = {v.x * std::cos(rz) - v.y * std::sin(rz), v.x * std::sin(rz) + v.y * std::cos(rz), v.z};
    return v;
  }
  Vec3 point(Vec3 p) const { return rotate(p * scale) + translate; }
  Vec3 normal(Vec3 n) const { return normalize(rotate(n)); }
};

Transform read_transform(ConfigTable& t) {
  Transform x;
  x.scale = float(t.get("scale", 1.0));
  if (!(x.scale > 0)) throw InputError(fmt::format("{}: expected a positive number", t.where("scale")));
  x.rot_deg = vec3(t.get("rotate", Arr3{0, 0, 0}));
  x.translate = vec3(t.get("translate", Arr3{0, 0, 0}));
  return x;
}

// Builds meshes of primitives. uv of every face spans [0, uv_scale].
struct MeshBuilder {
  Mesh mesh;
  bool smooth = false;
  void tri(Vec3 a, Vec3 b, Vec3 c, float ua, float va, float ub, float vb, float uc, float vc, unsigned mat,
           Vec3 na = {}, Vec3 nb = {}, Vec3 nc = {}) {
    if (!(length(cross(b - a, c - a)) > 0)) return;  // degenerate (sphere poles)
    mesh.positions.insert(mesh.positions.end(), {a, b, c});
    mesh.uvs.insert(mesh.uvs.end(), {ua, va, ub, vb, uc, vc});
    mesh.material.push_back(mat);
    if (smooth) mesh.normals.insert(mesh.normals.end(), {na, nb, nc});
  }
  // Quad p0 p1 p2 p3 (counter-clockwise seen from the front), uv (0,0) (1,0) (1,1) (0,1).
  void quad(Vec3 p0, Vec3 p1, Vec3 p2, Vec3 p3, float su, float sv, unsigned mat) {
    tri(p0, p1, p2, 0, 0, su, 0, su, sv, mat);
    tri(p0, p2, p3, 0, 0, su, sv, 0, sv, mat);
  }
  // Quad with explicit texture coordinates per corner.
  void quad_uv(const Vec3 (&p)[4], const float (&uv)[8], unsigned mat) {
    tri(p[0], p[1], p[2], uv[0], uv[1], uv[2], uv[3], uv[4], uv[5], mat);
    tri(p[0], p[2], p[3], uv[0], uv[1], uv[4], uv[5], uv[6], uv[7], mat);
  }
};

std::vector<Vec3> read_points(ConfigTable& t, const std::string& key, std::size_t count) {
  // An array of `count` [x, y, z] arrays, read as a flat list of numbers for simplicity of the
  // strict reader: `vertices = [x0,y0,z0, x1,y1,z1, ...]`.
  std::vector<double> v = t.get(key, std::vector<double>{});
  if (v.empty()) return {};
  if (v.size() != 3 * count)
    throw InputError(fmt::format("{}: expected {} numbers ({} points x, y, z)", t.where(key), 3 * count, count));
  std::vector<Vec3> out;
  for (std::size_t i = 0; i < count; ++i) out.emplace_back(float(v[3 * i]), float(v[3 * i + 1]), float(v[3 * i + 2]));
  return out;
}

void build_box(MeshBuilder& b, Vec3 size, const Transform& x, float su, float sv, unsigned mat) {
  Vec3 h = size * 0.5f;
  auto P = [&](float sx, float sy, float sz) { return x.point(Vec3(sx * h.x, sy * h.y, sz * h.z)); };
  // Outward faces, counter-clockwise seen from outside.
  b.quad(P(-1, -1, 1), P(1, -1, 1), P(1, 1, 1), P(-1, 1, 1), su, sv, mat);      // +z
  b.quad(P(1, -1, -1), P(-1, -1, -1), P(-1, 1, -1), P(1, 1, -1), su, sv, mat);  // -z
  b.quad(P(1, -1, 1), P(1, -1, -1), P(1, 1, -1), P(1, 1, 1), su, sv, mat);      // +x
  b.quad(P(-1, -1, -1), P(-1, -1, 1), P(-1, 1, 1), P(-1, 1, -1), su, sv, mat);  // -x
  b.quad(P(-1, 1, 1), P(1, 1, 1), P(1, 1, -1), P(-1, 1, -1), su, sv, mat);      // +y
  b.quad(P(-1, -1, -1), P(1, -1, -1), P(1, -1, 1), P(-1, -1, 1), su, sv, mat);  // -y
}

void build_sphere(MeshBuilder& b, Vec3 c, float r, int seg, const Transform& x, float su, float sv, unsigned mat,
                  bool inward, bool smooth) {
  b.smooth = smooth;
  int rings = std::max(4, seg / 2);
  auto pt = [&](int i, int j, Vec3& p, Vec3& n, float& u, float& v) {
    float th = kPi * i / rings, ph = 2 * kPi * j / seg;
    Vec3 d(std::sin(th) * std::cos(ph), std::cos(th), -std::sin(th) * std::sin(ph));
    p = x.point(c + d * r);
    n = x.normal(inward ? -d : d);
    u = su * float(j) / seg;
    v = sv * (1 - float(i) / rings);
  };
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < seg; ++j) {
      Vec3 p[4], n[4];
      float u[4], v[4];
      pt(i, j, p[0], n[0], u[0], v[0]);
      pt(i + 1, j, p[1], n[1], u[1], v[1]);
      pt(i + 1, j + 1, p[2], n[2], u[2], v[2]);
      pt(i, j + 1, p[3], n[3], u[3], v[3]);
      // Counter-clockwise from outside (or inside when inward).
      int a = 0, bb = 1, cc = 2, d = 3;
      if (inward) std::swap(bb, d);
      b.tri(p[a], p[bb], p[cc], u[a], v[a], u[bb], v[bb], u[cc], v[cc], mat, n[a], n[bb], n[cc]);
      b.tri(p[a], p[cc], p[d], u[a], v[a], u[cc], v[cc], u[d], v[d], mat, n[a], n[cc], n[d]);
    }
}

void build_cylinder(MeshBuilder& b, Vec3 base, float r, float height, int seg, bool capped, const Transform& x,
                    float su, float sv, unsigned mat) {
  // Side with smooth normals, caps flat: a separate builder would be cleaner, but the normals
  // of a cap are simply its face normal, so they are written explicitly here.
  b.smooth = true;
  for (int j = 0; j < seg; ++j) {
    float a0 = 2 * kPi * j / seg, a1 = 2 * kPi * (j + 1) / seg;
    Vec3 d0(std::cos(a0), 0, -std::sin(a0)), d1(std::cos(a1), 0, -std::sin(a1));
    Vec3 p0 = x.point(base + d0 * r), p1 = x.point(base + d1 * r);
    Vec3 q0 = x.point(base + d0 * r + Vec3(0, height, 0)), q1 = x.point(base + d1 * r + Vec3(0, height, 0));
    Vec3 n0 = x.normal(d0), n1 = x.normal(d1);
    float u0 = su * float(j) / seg, u1 = su * float(j + 1) / seg;
    b.tri(p0, p1, q1, u0, 0, u1, 0, u1, sv, mat, n0, n1, n1);
    b.tri(p0, q1, q0, u0, 0, u1, sv, u0, sv, mat, n0, n1, n0);
    if (capped) {
      Vec3 top = x.point(base + Vec3(0, height, 0)), bot = x.point(base);
      Vec3 nt = x.normal(Vec3(0, 1, 0)), nb = x.normal(Vec3(0, -1, 0));
      b.tri(top, q0, q1, 0.5f, 0.5f, 0.5f + 0.5f * d0.x, 0.5f + 0.5f * d0.z, 0.5f + 0.5f * d1.x,
            0.5f + 0.5f * d1.z, mat, nt, nt, nt);
      b.tri(bot, p1, p0, 0.5f, 0.5f, 0.5f + 0.5f * d1.x, 0.5f + 0.5f * d1.z, 0.5f + 0.5f * d0.x,
            0.5f + 0.5f * d0.z, mat, nb, nb, nb);
    }
  }
}

// An arch: the wall piece between a rectangle [-r, r] x [0, height] and the semicircle of
// radius r about the origin (the opening), extruded over z in [-depth/2, depth/2]. Front, back,
// intrados (the curved underside) and top faces; the sides meet the columns.
void build_arch(MeshBuilder& b, float r, float height, float depth, int seg, const Transform& x, float su, float sv,
                unsigned mat) {
  std::vector<float> angles;
  for (int i = 0; i <= seg; ++i) angles.push_back(kPi * i / seg);
  const float corner = std::atan2(height, r);
  angles.push_back(corner);
  angles.push_back(kPi - corner);
  std::sort(angles.begin(), angles.end());
  const float hz = depth / 2, w = 2 * r;
  auto outer = [&](float a) {
    float c = std::cos(a), s = std::sin(a);
    float t = 1e30f;
    if (std::fabs(c) > 1e-6f) t = std::min(t, r / std::fabs(c));
    if (s > 1e-6f) t = std::min(t, height / s);
    return Vec3(t * c, t * s, 0);
  };
  auto P = [&](Vec3 p, float z) { return x.point(Vec3(p.x, p.y, z)); };
  auto U = [&](Vec3 p) { return su * (p.x / w + 0.5f); };
  auto V = [&](Vec3 p) { return sv * (p.y / height); };
  for (std::size_t i = 0; i + 1 < angles.size(); ++i) {
    float a0 = angles[i], a1 = angles[i + 1];
    if (a1 - a0 < 1e-6f) continue;
    Vec3 c0(r * std::cos(a0), r * std::sin(a0), 0), c1(r * std::cos(a1), r * std::sin(a1), 0);
    Vec3 o0 = outer(a0), o1 = outer(a1);
    // Front and back faces, texture coordinates following the wall's x, y.
    const Vec3 f[4] = {c0, o0, o1, c1}, k[4] = {c1, o1, o0, c0};
    const Vec3 pf[4] = {P(f[0], hz), P(f[1], hz), P(f[2], hz), P(f[3], hz)};
    const Vec3 pk[4] = {P(k[0], -hz), P(k[1], -hz), P(k[2], -hz), P(k[3], -hz)};
    const float uf[8] = {U(f[0]), V(f[0]), U(f[1]), V(f[1]), U(f[2]), V(f[2]), U(f[3]), V(f[3])};
    const float uk[8] = {U(k[0]), V(k[0]), U(k[1]), V(k[1]), U(k[2]), V(k[2]), U(k[3]), V(k[3])};
    b.quad_uv(pf, uf, mat);
    b.quad_uv(pk, uk, mat);
    float l = r * (a1 - a0);
    b.quad(P(c1, hz), P(c1, -hz), P(c0, -hz), P(c0, hz), su * depth / w, sv * l / height, mat);
  }
  Vec3 tl(-r, height, 0), tr(r, height, 0);
  b.quad(P(tr, hz), P(tr, -hz), P(tl, -hz), P(tl, hz), su, sv * depth / height, mat);
}

// A file name as written in an MTL file, found on disk: the exact name first, else the one file
// of that folder whose name matches ignoring letter case (sponza.mtl says SP_LUK.JPG for
// sp_luk.JPG). Backslashes are taken as folder separators.
fs::path find_file_ignoring_case(const fs::path& dir, std::string name) {
  std::replace(name.begin(), name.end(), '\\', '/');
  fs::path exact = dir / name;
  if (fs::exists(exact)) return exact;
  fs::path folder = exact.parent_path();
  std::string want = exact.filename().string();
  auto lower = [](std::string s) {
    for (auto& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
  };
  want = lower(want);
  std::error_code ec;
  if (fs::is_directory(folder, ec))
    for (const auto& e : fs::directory_iterator(folder, ec))
      if (lower(e.path().filename().string()) == want) return e.path();
  return {};
}

class Loader {
 public:
  Loader(Scene& s, const SceneLoadOptions& o) : scene_(s), opt_(o) {}

  void load(const std::string& path) {
    ConfigFile file = ConfigFile::load(path);
    scene_.source_file = path;
    scene_.files.push_back(path);
    dir_ = fs::path(path).parent_path().string();
    ConfigTable root = file.root();
    root.get("description", std::string());
    read_camera(root);
    read_environment(root);
    read_textures(root);
    read_materials(root);
    for (auto& t : root.tables("objects")) read_object(t, false);
    for (auto& t : root.tables("lights")) read_object(t, true);
    root.finish();
    if (scene_.meshes.empty()) throw InputError(fmt::format("{}: the scene has no geometry", path));
  }

 private:
  void read_camera(ConfigTable& root) {
    auto c = root.table("camera");
    if (!c) throw InputError(fmt::format("{}: missing [camera] table (eye, look_at, up, vfov)", root.file()));
    scene_.camera.eye = vec3(c->require_vec3("eye"));
    scene_.camera.look_at = vec3(c->require_vec3("look_at"));
    scene_.camera.up = vec3(c->get("up", Arr3{0, 1, 0}));
    scene_.camera.vfov_degrees = float(c->get("vfov", 45.0));
    if (!(scene_.camera.vfov_degrees > 0 && scene_.camera.vfov_degrees < 179))
      throw InputError(fmt::format("{}: expected a field of view in (0, 179) degrees", c->where("vfov")));
    if (length(scene_.camera.look_at - scene_.camera.eye) <= 0)
      throw InputError(fmt::format("{}: eye and look_at coincide", c->where("look_at")));
    if (length(cross(normalize(scene_.camera.look_at - scene_.camera.eye), normalize(scene_.camera.up))) < 1e-4f)
      throw InputError(fmt::format("{}: up is parallel to the viewing direction", c->where("up")));
    c->finish();
  }

  void read_environment(ConfigTable& root) {
    if (auto s = root.table("sky")) {
      Sky& sky = scene_.sky;
      sky.enabled = true;
      std::string type = s->get("type", std::string("constant"));
      if (type == "constant") {
        sky.color = vec3(s->require_vec3("color"));
        sky.average = sky.color;
      } else if (type == "gradient") {
        sky.gradient = true;
        sky.zenith = vec3(s->require_vec3("zenith"));
        sky.horizon = vec3(s->require_vec3("horizon"));
        sky.ground = vec3(s->get("ground", Arr3{0, 0, 0}));
        sky.up = normalize(vec3(s->get("up", Arr3{0, 1, 0})));
        // Mean over the sphere by quadrature in the cosine (the sky depends on it only).
        Vec3 sum(0.0f);
        const int n = 512;
        for (int i = 0; i < n; ++i) {
          float c = -1 + 2 * (i + 0.5f) / n;
          Vec3 d = sky.up * c;  // only dot(d, up) matters
          d = d + Frame(sky.up).t * std::sqrt(std::max(0.0f, 1 - c * c));
          sum += sky.radiance(normalize(d));
        }
        sky.average = sum / float(n);
      } else {
        throw InputError(fmt::format("{}: expected \"constant\" or \"gradient\"", s->where("type")));
      }
      s->finish();
    }
    if (auto s = root.table("sun")) {
      Sun& sun = scene_.sun;
      sun.enabled = true;
      sun.direction = normalize(vec3(s->require_vec3("direction")));
      float radius_deg = float(s->get("angular_radius", 0.27));
      if (!(radius_deg > 0 && radius_deg < 30))
        throw InputError(fmt::format("{}: expected degrees in (0, 30)", s->where("angular_radius")));
      sun.cos_max = std::cos(radius_deg * kPi / 180);
      // Irradiance on a surface facing the sun; the disc's radiance follows from its solid angle.
      Vec3 e = vec3(s->require_vec3("irradiance"));
      sun.radiance = e / sun.solid_angle();
      s->finish();
    }
  }

  void read_textures(ConfigTable& root) {
    auto t = root.table("textures");
    if (!t) return;
    for (const auto& name : t->keys()) {
      auto tt = t->table(name);
      texture_index_[name] = int(scene_.textures.size());
      scene_.textures.push_back(make_texture(*tt, dir_, scene_.files));
    }
    t->finish();
  }

  void read_material(ConfigTable& t, Material& m) {
    std::string type = t.get("type", std::string("diffuse"));
    if (type == "diffuse") m.type = MaterialType::kDiffuse;
    else if (type == "mirror") m.type = MaterialType::kMirror;
    else if (type == "coated") m.type = MaterialType::kCoated;
    else throw InputError(fmt::format("{}: expected \"diffuse\", \"mirror\" or \"coated\"", t.where("type")));
    m.albedo = vec3(t.get("albedo", Arr3{0.8, 0.8, 0.8}));
    std::string tex = t.get("texture", std::string());
    if (!tex.empty()) {
      auto it = texture_index_.find(tex);
      if (it == texture_index_.end())
        throw InputError(fmt::format("{}: no texture '{}' in [textures]", t.where("texture"), tex));
      m.texture = it->second;
    }
    m.tint = vec3(t.get("tint", Arr3{1, 1, 1}));
    m.ior = float(t.get("ior", 1.5));
    if (!(m.ior > 1)) throw InputError(fmt::format("{}: expected an index of refraction > 1", t.where("ior")));
    m.emission = vec3(t.get("emission", Arr3{0, 0, 0}));
    m.two_sided = t.get("two_sided", false);
    if (max_component(m.albedo) > 1 || max_component(m.tint) > 1)
      throw InputError(fmt::format("{}: albedo and tint must be at most 1", t.where("albedo")));
  }

  void read_materials(ConfigTable& root) {
    auto t = root.table("materials");
    if (!t) return;
    for (const auto& name : t->keys()) {
      auto mt = t->table(name);
      Material m;
      m.name = name;
      read_material(*mt, m);
      mt->finish();
      material_index_[name] = unsigned(scene_.materials.size());
      scene_.materials.push_back(m);
    }
    t->finish();
  }

  unsigned material_of(ConfigTable& t, bool light) {
    if (light) {
      // A light: emission (and optionally albedo) written on the light itself.
      Material m;
      m.name = fmt::format("light{}", scene_.materials.size());
      m.albedo = vec3(t.get("albedo", Arr3{0, 0, 0}));
      m.emission = vec3(t.require_vec3("emission"));
      m.two_sided = t.get("two_sided", false);
      scene_.materials.push_back(m);
      return unsigned(scene_.materials.size() - 1);
    }
    std::string name = t.require_string("material");
    auto it = material_index_.find(name);
    if (it == material_index_.end())
      throw InputError(fmt::format("{}: no material '{}' in [materials]", t.where("material"), name));
    return it->second;
  }

  void read_object(ConfigTable& t, bool light) {
    std::string type = t.require_string("type");
    std::string name = t.get("name", fmt::format("{}{}", type, scene_.meshes.size()));
    Transform x = read_transform(t);
    if (type == "obj") {
      if (light) throw InputError(fmt::format("{}: lights are quads or spheres", t.where("type")));
      std::string file = t.require_string("file");
      std::string override_mat = t.get("material", std::string());
      t.finish();
      load_obj(t, file, override_mat, x);
      return;
    }
    auto uvs = t.get("uv_scale", std::vector<double>{1, 1});
    if (uvs.size() != 2) throw InputError(fmt::format("{}: expected [su, sv]", t.where("uv_scale")));
    float su = float(uvs[0]), sv = float(uvs[1]);
    unsigned mat = material_of(t, light);
    MeshBuilder b;
    b.mesh.name = name;
    if (type == "quad") {
      auto v = read_points(t, "vertices", 4);
      if (v.empty()) {
        // A unit square in the xz-plane facing +y, sized by `size` = [sx, sz], then transformed.
        auto sz = t.get("size", std::vector<double>{1, 1});
        if (sz.size() != 2) throw InputError(fmt::format("{}: expected [sx, sz]", t.where("size")));
        float hx = float(sz[0]) / 2, hz = float(sz[1]) / 2;
        v = {Vec3(-hx, 0, hz), Vec3(hx, 0, hz), Vec3(hx, 0, -hz), Vec3(-hx, 0, -hz)};
      }
      for (auto& p : v) p = x.point(p);
      b.quad(v[0], v[1], v[2], v[3], su, sv, mat);
    } else if (type == "box") {
      build_box(b, vec3(t.get("size", Arr3{1, 1, 1})), x, su, sv, mat);
    } else if (type == "sphere") {
      float r = float(t.require_double("radius"));
      if (!(r > 0)) throw InputError(fmt::format("{}: expected a positive radius", t.where("radius")));
      int seg = t.get("segments", 48);
      if (seg < 3) throw InputError(fmt::format("{}: expected at least 3 segments", t.where("segments")));
      bool inward = t.get("inward", false);
      Vec3 center = vec3(t.get("center", Arr3{0, 0, 0}));
      build_sphere(b, center, r, seg, x, su, sv, mat, inward, t.get("smooth", true));
      if (light && !inward) sphere_light_ = SphereLight{unsigned(scene_.meshes.size()), x.point(center), r * x.scale};
    } else if (type == "arch") {
      float r = float(t.require_double("radius"));
      float h = float(t.require_double("height"));
      float d = float(t.require_double("depth"));
      if (!(r > 0 && h >= r && d > 0))
        throw InputError(fmt::format("{}: expected radius > 0, height >= radius, depth > 0", t.where("radius")));
      int seg = t.get("segments", 16);
      if (seg < 2) throw InputError(fmt::format("{}: expected at least 2 segments", t.where("segments")));
      build_arch(b, r, h, d, seg, x, su, sv, mat);
    } else if (type == "cylinder") {
      float r = float(t.require_double("radius"));
      float h = float(t.require_double("height"));
      if (!(r > 0 && h > 0)) throw InputError(fmt::format("{}: expected positive radius and height", t.where("radius")));
      int seg = t.get("segments", 32);
      if (seg < 3) throw InputError(fmt::format("{}: expected at least 3 segments", t.where("segments")));
      build_cylinder(b, vec3(t.get("center", Arr3{0, 0, 0})), r, h, seg, t.get("capped", true), x, su, sv, mat);
    } else {
      throw InputError(fmt::format("{}: unknown {} type '{}' (expected {})", t.where("type"),
                                   light ? "light" : "object", type,
                                   light ? "quad or sphere" : "quad, box, sphere, cylinder, arch or obj"));
    }
    if (light && type != "quad" && type != "sphere")
      throw InputError(fmt::format("{}: lights are quads or spheres", t.where("type")));
    // `repeat = N` copies: copy k is moved by k * repeat_offset (rows of chairs, columns).
    int repeat = t.get("repeat", 1);
    Vec3 step = vec3(t.get("repeat_offset", Arr3{0, 0, 0}));
    if (repeat < 1 || repeat > 10000) throw InputError(fmt::format("{}: expected 1..10000", t.where("repeat")));
    if (repeat > 1) {
      Mesh one = b.mesh;
      for (int k = 1; k < repeat; ++k) {
        for (const Vec3& p : one.positions) b.mesh.positions.push_back(p + step * float(k));
        b.mesh.normals.insert(b.mesh.normals.end(), one.normals.begin(), one.normals.end());
        b.mesh.uvs.insert(b.mesh.uvs.end(), one.uvs.begin(), one.uvs.end());
        b.mesh.material.insert(b.mesh.material.end(), one.material.begin(), one.material.end());
      }
    }
    t.finish();
    // A repeated sphere light is several spheres: those stay triangle emitters.
    if (sphere_light_ && repeat == 1) scene_.sphere_lights.push_back(*sphere_light_);
    sphere_light_.reset();
    scene_.meshes.push_back(std::move(b.mesh));
  }

  fs::path resolve_mesh_path(ConfigTable& t, const std::string& file) {
    const std::string prefix = "@scenes/";
    if (file.rfind(prefix, 0) == 0) {
      fs::path dir = mcguire_dir(opt_);
      if (dir.empty())
        throw InputError(fmt::format("{}: '{}' needs the McGuire scenes folder: pass --scenes-dir or set "
                                     "DENOISEBENCH_SCENES (../shared/scenes was not found)",
                                     t.where("file"), file));
      return dir / file.substr(prefix.size());
    }
    fs::path p(file);
    return p.is_relative() ? fs::path(dir_) / p : p;
  }

  void load_obj(ConfigTable& t, const std::string& file, const std::string& override_mat, const Transform& x) {
    fs::path path = resolve_mesh_path(t, file);
    if (!fs::exists(path)) throw InputError(fmt::format("{}: OBJ file '{}' not found", t.where("file"), path.string()));
    unsigned forced = 0;
    if (!override_mat.empty()) {
      auto it = material_index_.find(override_mat);
      if (it == material_index_.end())
        throw InputError(fmt::format("{}: no material '{}' in [materials]", t.where("material"), override_mat));
      forced = it->second;
    }
    tinyobj::ObjReaderConfig cfg;
    cfg.triangulate = true;
    cfg.vertex_color = false;
    cfg.mtl_search_path = path.parent_path().string();
    tinyobj::ObjReader reader;
    if (!reader.ParseFromFile(path.string(), cfg))
      throw InputError(fmt::format("'{}': cannot read OBJ: {}", path.string(), reader.Error()));
    scene_.files.push_back(path.string());
    const auto& attrib = reader.GetAttrib();
    const auto& mats = reader.GetMaterials();
    // Material files named by mtllib, for the content hash.
    {
      std::ifstream in(path);
      std::string line;
      while (std::getline(in, line)) {
        if (line.rfind("mtllib", 0) != 0) continue;
        std::string n = line.substr(6);
        n.erase(0, n.find_first_not_of(" \t"));
        while (!n.empty() && (n.back() == '\r' || n.back() == ' ' || n.back() == '\t')) n.pop_back();
        fs::path mp = find_file_ignoring_case(path.parent_path(), n);
        if (!mp.empty()) scene_.files.push_back(mp.string());
      }
    }
    // OBJ materials -> scene materials.
    std::vector<unsigned> mat_map(mats.size());
    std::map<std::string, int> tex_cache;
    for (std::size_t i = 0; i < mats.size(); ++i) {
      const auto& om = mats[i];
      Material m;
      m.name = path.stem().string() + "/" + om.name;
      Vec3 kd(float(om.diffuse[0]), float(om.diffuse[1]), float(om.diffuse[2]));
      Vec3 ks(float(om.specular[0]), float(om.specular[1]), float(om.specular[2]));
      m.albedo = vmin(kd, Vec3(1.0f));
      m.emission = Vec3(float(om.emission[0]), float(om.emission[1]), float(om.emission[2]));
      const bool mirror_illum = om.illum == 3 || om.illum == 5 || om.illum == 7;
      if (mirror_illum || (max_component(ks) > 0 && om.shininess >= 200)) {
        // Specular: a mirror when there is no diffuse part, else a coated diffuse.
        if (max_component(kd) < 0.01f) {
          m.type = MaterialType::kMirror;
          m.tint = max_component(ks) > 0 ? vmin(ks, Vec3(1.0f)) : Vec3(1.0f);
        } else {
          m.type = MaterialType::kCoated;
          m.ior = om.ior > 1.0 ? float(om.ior) : 1.5f;
        }
      }
      if (!om.diffuse_texname.empty()) {
        auto it = tex_cache.find(om.diffuse_texname);
        if (it != tex_cache.end()) {
          m.texture = it->second;
        } else {
          fs::path tp = find_file_ignoring_case(path.parent_path(), om.diffuse_texname);
          if (tp.empty())
            throw InputError(fmt::format("'{}': material '{}': texture file '{}' (map_Kd) not found in '{}'",
                                         path.string(), om.name, om.diffuse_texname, path.parent_path().string()));
          scene_.files.push_back(tp.string());
          m.texture = int(scene_.textures.size());
          scene_.textures.push_back(load_image_texture(tp.string()));
          tex_cache[om.diffuse_texname] = m.texture;
        }
        // map_Kd replaces Kd in most exporters' intent when Kd is black.
        if (max_component(m.albedo) <= 0) m.albedo = Vec3(1.0f);
      }
      mat_map[i] = unsigned(scene_.materials.size());
      scene_.materials.push_back(m);
    }
    unsigned fallback = unsigned(scene_.materials.size());
    {
      Material m;
      m.name = path.stem().string() + "/(no material)";
      scene_.materials.push_back(m);
    }
    Mesh mesh;
    mesh.name = path.stem().string();
    bool any_normals = !attrib.normals.empty(), any_uvs = !attrib.texcoords.empty();
    for (const auto& shape : reader.GetShapes()) {
      const auto& idx = shape.mesh.indices;
      for (std::size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
        if (shape.mesh.num_face_vertices[f] != 3) continue;  // triangulated by the reader
        Vec3 p[3], n[3];
        float uv[6] = {0, 0, 0, 0, 0, 0};
        bool have_n = true;
        for (int k = 0; k < 3; ++k) {
          const auto& ix = idx[3 * f + k];
          if (ix.vertex_index < 0 || std::size_t(3 * ix.vertex_index + 2) >= attrib.vertices.size())
            throw InputError(fmt::format("'{}': face index out of range in shape '{}'", path.string(), shape.name));
          p[k] = x.point(Vec3(attrib.vertices[3 * ix.vertex_index], attrib.vertices[3 * ix.vertex_index + 1],
                              attrib.vertices[3 * ix.vertex_index + 2]));
          if (ix.normal_index >= 0 && std::size_t(3 * ix.normal_index + 2) < attrib.normals.size())
            n[k] = x.normal(Vec3(attrib.normals[3 * ix.normal_index], attrib.normals[3 * ix.normal_index + 1],
                                 attrib.normals[3 * ix.normal_index + 2]));
          else
            have_n = false;
          if (ix.texcoord_index >= 0 && std::size_t(2 * ix.texcoord_index + 1) < attrib.texcoords.size()) {
            uv[2 * k] = attrib.texcoords[2 * ix.texcoord_index];
            uv[2 * k + 1] = attrib.texcoords[2 * ix.texcoord_index + 1];
          }
        }
        Vec3 ng = cross(p[1] - p[0], p[2] - p[0]);
        if (!(length(ng) > 0)) continue;  // degenerate
        if (!have_n) n[0] = n[1] = n[2] = normalize(ng);
        mesh.positions.insert(mesh.positions.end(), {p[0], p[1], p[2]});
        if (any_normals) mesh.normals.insert(mesh.normals.end(), {n[0], n[1], n[2]});
        if (any_uvs) mesh.uvs.insert(mesh.uvs.end(), uv, uv + 6);
        int mid = f < shape.mesh.material_ids.size() ? shape.mesh.material_ids[f] : -1;
        unsigned mat = !override_mat.empty() ? forced
                       : (mid >= 0 && std::size_t(mid) < mat_map.size()) ? mat_map[mid] : fallback;
        mesh.material.push_back(mat);
      }
    }
    if (mesh.positions.empty()) throw InputError(fmt::format("'{}': the OBJ file has no triangles", path.string()));
    scene_.meshes.push_back(std::move(mesh));
  }

  Scene& scene_;
  const SceneLoadOptions& opt_;
  std::string dir_;
  std::map<std::string, int> texture_index_;
  std::map<std::string, unsigned> material_index_;
  std::optional<SphereLight> sphere_light_;  // of the object being read
};

}  // namespace

std::vector<std::string> builtin_scene_names() {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(builtin_dir(), ec))
    if (e.path().extension() == ".toml") names.push_back(e.path().stem().string());
  std::sort(names.begin(), names.end());
  return names;
}

std::shared_ptr<const Scene> load_scene(const std::string& name_or_path, const SceneLoadOptions& options) {
  fs::path path;
  std::string name;
  if (fs::is_regular_file(name_or_path)) {
    path = name_or_path;
    name = path.stem().string();
  } else {
    fs::path p = builtin_dir() / (name_or_path + ".toml");
    if (name_or_path.find('/') != std::string::npos || name_or_path.ends_with(".toml") || !fs::is_regular_file(p))
      throw InputError(fmt::format("scene '{}': no such scene file or built-in scene (built-in: {})", name_or_path,
                                   fmt::join(builtin_scene_names(), ", ")));
    path = p;
    name = name_or_path;
  }
  auto scene = std::make_shared<Scene>();
  scene->name = name;
  Loader(*scene, options).load(path.string());
  scene->commit();
  scene->content_hash = scene_content_hash(*scene);  // once: the OBJ files can be large
  return scene;
}

std::string scene_content_hash(const Scene& scene) {
  if (!scene.content_hash.empty()) return scene.content_hash;
  // FNV-1a over the bytes of every file the scene read, in the order read, each preceded by its
  // file name (not its folder: moving a scene collection keeps its caches valid).
  std::uint64_t h = 0xcbf29ce484222325ULL;
  auto feed = [&h](const char* p, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) {
      h ^= static_cast<unsigned char>(p[i]);
      h *= 0x100000001b3ULL;
    }
  };
  std::vector<char> buf(1 << 16);
  for (const auto& f : scene.files) {
    std::string base = fs::path(f).filename().string();
    feed(base.data(), base.size() + 1);
    std::ifstream in(f, std::ios::binary);
    while (in) {
      in.read(buf.data(), std::streamsize(buf.size()));
      feed(buf.data(), std::size_t(in.gcount()));
    }
  }
  return fmt::format("{:016x}", h);
}

const std::string& scene_name(const Scene& scene) { return scene.name; }

}  // namespace dnb
