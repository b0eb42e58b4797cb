// Scene files (TOML) -> Scene (tracer/scene_loader.h): where scene and mesh files are found
// (built-in scenes, the McGuire scenes folder, paths relative to the scene file), the schema of
// the scene file, and the content hash. The format is documented in configs/scenes/README.md;
// every table's keys are read where their defaults are written and finish() rejects any other
// key (core/config.h). Shapes are tessellated by tracer/shapes.h, OBJ files imported by
// tracer/obj_import.h, glTF files by tracer/gltf_import.h.
#include "core/env.h"
#include "tracer/scene_loader.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <tuple>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "core/bounds.h"
#include "core/config.h"
#include "core/errors.h"
#include "tracer/animation.h"
#include "tracer/bsdf.h"
#include "tracer/gltf_import.h"
#include "tracer/obj_import.h"
#include "tracer/scene.h"
#include "tracer/scene_check.h"
#include "tracer/shapes.h"
#include "tracer/texture.h"

namespace fs = std::filesystem;

namespace dnb {
using namespace rt;

namespace {

using Arr3 = std::array<double, 3>;

// A sequence's length is bounded ([animation] frames); glTF animations run on a clock of kGltfFps
// frames per second unless a scene's [animation] fps says otherwise (docs/sequences.md).
constexpr int kMaxFrames = 100000;
constexpr double kGltfFps = 24;
Vec3 vec3(const Arr3& a) { return {float(a[0]), float(a[1]), float(a[2])}; }

// Where the built-in scene files live: $DENOISEBENCH_SOURCE_DIR/configs/scenes when set (tests), else
// the source tree this program was built from.
fs::path builtin_dir() {
  if (const char* s = env::get("SOURCE_DIR"); s && *s) {
    fs::path p = fs::path(s) / "configs" / "scenes";
    if (fs::is_directory(p)) return p;
  }
  return fs::path(DNB_SOURCE_SCENES_DIR);
}

// The McGuire scenes folder: --scenes-dir, else $DENOISEBENCH_SCENES, else ../shared/scenes
// beside the repository. Empty when none exists.
fs::path mcguire_dir(const SceneLoadOptions& o) {
  if (!o.scenes_dir.empty()) return o.scenes_dir;
  if (const char* s = env::get("SCENES"); s && *s) return s;
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

// Every number of a scene file is finite and bounded where it is read (core/bounds.h): a NaN
// emission rendered black with exit 0, and a huge `segments` hung the loader.
constexpr RealBound kAngle{-1e6, 1e6, "degrees"};
constexpr RealBound kUvScale{-1e6, 1e6, "texture repeats"};

Transform read_transform(ConfigTable& t) {
  Transform x;
  x.scale = float(t.get("scale", 1.0, bounds::kLength));
  x.rot_deg = vec3(t.get("rotate", Arr3{0, 0, 0}, kAngle));
  x.translate = vec3(t.get("translate", Arr3{0, 0, 0}, bounds::kCoordinate));
  return x;
}

std::vector<Vec3> read_points(ConfigTable& t, const std::string& key, std::size_t count) {
  // An array of `count` [x, y, z] arrays, read as a flat list of numbers for simplicity of the
  // strict reader: `vertices = [x0,y0,z0, x1,y1,z1, ...]`.
  std::vector<double> v = t.get(key, std::vector<double>{});
  if (v.empty()) return {};
  if (v.size() != 3 * count)
    throw InputError(fmt::format("{}: expected {} numbers ({} points x, y, z)", t.where(key), 3 * count, count));
  for (double c : v) check_bound(c, bounds::kCoordinate, t.where(key));
  std::vector<Vec3> out;
  for (std::size_t i = 0; i < count; ++i) out.emplace_back(float(v[3 * i]), float(v[3 * i + 1]), float(v[3 * i + 2]));
  return out;
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
    read_animation(root);
    const bool own_camera = root.contains("camera");
    if (own_camera) read_camera(root);
    read_environment(root);
    read_textures(root);
    read_materials(root);
    for (auto& t : root.tables("objects")) read_object(t, false);
    for (auto& t : root.tables("lights")) read_object(t, true);
    root.finish();
    if (scene_.meshes.empty()) throw InputError(fmt::format("{}: the scene has no geometry", path));
    if (!scene_.animated() && opt_.frame > 0)
      throw InputError(fmt::format("{}: frame {} asked of a still scene (no [animation] table)", path, opt_.frame));
    if (!own_camera) {
      if (!gltf_camera_)
        throw InputError(fmt::format("{}: missing [camera] table (eye, look_at, up, vfov), and no glTF object has a "
                                     "perspective camera",
                                     path));
      scene_.camera = *gltf_camera_;
    }
  }

  // A glTF file alone: its default scene, lit by its lights, seen through its first perspective
  // camera (which it must have). With node animations it is an animated scene of
  // floor(duration x 24) + 1 frames at kGltfFps (docs/sequences.md, "glTF animations"), frame t
  // its animations at t / 24 s; without, a still.
  void load_gltf(const std::string& path) {
    scene_.source_file = path;
    dir_ = fs::path(path).parent_path().string();
    require_regular_file(path, "scene", "glTF file");
    const int frame = std::max(opt_.frame, 0);
    const GltfImport g = import_gltf(scene_, path, Transform{}, std::nullopt, frame / kGltfFps);
    warnings_.insert(warnings_.end(), g.warnings.begin(), g.warnings.end());
    if (!g.animated && frame > 0)
      throw InputError(fmt::format("{}: frame {} asked of a still glTF file (no animation moves its nodes)", path, frame));
    if (g.animated) {
      // Key times are 32-bit floats: a duration within 1e-4 of a frame's time reaches that frame.
      const double last = std::floor(g.duration * kGltfFps + 1e-4);
      if (last >= kMaxFrames) {
        warnings_.push_back(fmt::format("{}: /animations: they last {:g} s, more than {} frames at {:g} fps: the sequence "
                                        "is cut at {} frames",
                                        path, g.duration, kMaxFrames, kGltfFps, kMaxFrames));
      }
      scene_.frames = int(std::min<double>(last, kMaxFrames - 1)) + 1;
      if (frame >= scene_.frames)
        throw InputError(fmt::format("{}: frame {} is past the sequence's {} frames (0 .. {}: its animations last {:g} s, at "
                                     "{:g} frames per second)",
                                     path, frame, scene_.frames, scene_.frames - 1, g.duration, kGltfFps));
      scene_.frame = frame;
    }
    if (!g.camera)
      throw InputError(fmt::format("{}: no perspective camera in the default scene (render it from a scene TOML with a "
                                   "[camera] and an object of type \"gltf\")",
                                   path));
    scene_.camera = *g.camera;
  }

  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  void read_camera(ConfigTable& root) {
    auto c = root.table("camera");
    if (!c) throw InputError(fmt::format("{}: missing [camera] table (eye, look_at, up, vfov)", root.file()));
    scene_.camera.eye = vec3(c->require_vec3("eye", bounds::kCoordinate));
    scene_.camera.look_at = vec3(c->require_vec3("look_at", bounds::kCoordinate));
    scene_.camera.up = vec3(c->get("up", Arr3{0, 1, 0}, bounds::kCoordinate));
    scene_.camera.vfov_degrees = float(c->get("vfov", 45.0, kAngle));
    static constexpr RealBound kAperture{0, 1e6, "the lens radius is a length in [0, 1e6] (0: a pinhole)"};
    static constexpr RealBound kFocus{0, 1e6, "the focus distance is a positive length, below 1e6", true};
    scene_.camera.aperture_radius = float(c->get("aperture_radius", 0.0, kAperture));
    if (scene_.camera.aperture_radius > 0)
      scene_.camera.focus_distance = float(c->require_double("focus_distance", kFocus));
    else
      scene_.camera.focus_distance = float(c->get("focus_distance", 1.0, kFocus));
    if (!(scene_.camera.vfov_degrees > 0 && scene_.camera.vfov_degrees < 179))
      throw InputError(fmt::format("{}: expected a field of view in (0, 179) degrees", c->where("vfov")));
    if (length(scene_.camera.look_at - scene_.camera.eye) <= 0)
      throw InputError(fmt::format("{}: eye and look_at coincide", c->where("look_at")));
    if (length(cross(normalize(scene_.camera.look_at - scene_.camera.eye), normalize(scene_.camera.up))) < 1e-4f)
      throw InputError(fmt::format("{}: up is parallel to the viewing direction", c->where("up")));
    read_shutter(*c);
    read_camera_keys(*c);
    c->finish();
  }

  // [animation] frames = N, interpolation: the scene is frame `frame_` of an N-frame sequence.
  void read_animation(ConfigTable& root) {
    auto a = root.table("animation");
    if (!a) return;
    static constexpr Bound kFrames{1, kMaxFrames, "a sequence of 1 to 100000 frames"};
    if (!a->contains("frames"))
      throw InputError(fmt::format("{}: missing key (the sequence's length in frames)", a->where("frames")));
    scene_.frames = a->get("frames", 1, kFrames);
    const std::string how = a->get("interpolation", std::string("catmull-rom"));
    if (how == "linear") interpolation_ = Interpolation::kLinear;
    else if (how == "catmull-rom") interpolation_ = Interpolation::kCatmullRom;
    else throw InputError(fmt::format("{}: expected \"linear\" or \"catmull-rom\"", a->where("interpolation")));
    static constexpr RealBound kFps{0, 1000, "frames per second (of the glTF animations' clock), in (0, 1000]", true};
    fps_ = a->get("fps", kGltfFps, kFps);
    a->finish();
    frame_ = std::max(opt_.frame, 0);
    if (frame_ >= scene_.frames)
      throw InputError(fmt::format("{}: frame {} is past the sequence's {} frames (0 .. {})", a->where("frames"), frame_,
                                   scene_.frames, scene_.frames - 1));
    scene_.frame = frame_;
  }

  // The keys of `t` ([[camera.keys]], [[objects.keys]]): each a table with `frame` and some of
  // `names` (sizes in `sizes`), a missing one taking its value from `defaults`. Empty without keys.
  KeyTrack read_keys(ConfigTable& t, const std::vector<std::pair<const char*, int>>& names, const std::vector<double>& defaults,
                     const std::vector<RealBound>& value_bounds) {
    KeyTrack track;
    auto keys = t.tables("keys");
    if (keys.empty()) return track;
    if (!scene_.animated())
      throw InputError(fmt::format("{}: keys need an [animation] table (frames = N) in the scene file", t.where("keys")));
    for (auto& k : keys) {
      static constexpr Bound kFrame{0, 100000, "a frame index of the sequence"};
      if (!k.contains("frame")) throw InputError(fmt::format("{}: missing key (the key's frame index)", k.where("frame")));
      const int f = k.get("frame", 0, kFrame);
      if (f >= scene_.frames)
        throw InputError(fmt::format("{}: frame {} is past the sequence's {} frames", k.where("frame"), f, scene_.frames));
      if (!track.frames.empty() && f <= track.frames.back())
        throw InputError(fmt::format("{}: keys' frames must rise strictly ({} after {})", k.where("frame"), f,
                                     track.frames.back()));
      std::vector<double> v;
      std::size_t at = 0;
      for (std::size_t i = 0; i < names.size(); ++i) {
        const auto [name, size] = names[i];
        std::vector<double> d(defaults.begin() + long(at), defaults.begin() + long(at) + size);
        std::vector<double> got = !k.contains(name) ? d : size == 1 ? std::vector<double>{k.get(name, d[0])} : k.get(name, d);
        if (got.size() != d.size())
          throw InputError(fmt::format("{}: expected {} numbers", k.where(name), d.size()));
        for (double x : got) check_bound(x, value_bounds[i], k.where(name));
        v.insert(v.end(), got.begin(), got.end());
        at += std::size_t(size);
      }
      k.finish();
      track.frames.push_back(f);
      track.values.push_back(std::move(v));
    }
    return track;
  }

  // [[camera.keys]]: eye, look_at, vfov at frames; the camera at this frame (and, with a shutter,
  // moving towards the next frame's).
  void read_camera_keys(ConfigTable& c) {
    Camera& cam = scene_.camera;
    const std::vector<double> base{cam.eye.x, cam.eye.y, cam.eye.z, cam.look_at.x, cam.look_at.y, cam.look_at.z, cam.vfov_degrees};
    const KeyTrack track = read_keys(c, {{"eye", 3}, {"look_at", 3}, {"vfov", 1}}, base,
                                     {bounds::kCoordinate, bounds::kCoordinate, kAngle});
    if (track.empty()) return;
    if (cam.moving)
      throw InputError(fmt::format("{}: an animated camera moves by its keys; eye_end and look_at_end are for a still's "
                                   "motion blur",
                                   c.where("keys")));
    auto place = [&](double frame, Vec3& eye, Vec3& at, float* vfov) {
      const std::vector<double> v = track.at(frame, interpolation_);
      eye = {float(v[0]), float(v[1]), float(v[2])};
      at = {float(v[3]), float(v[4]), float(v[5])};
      if (vfov) *vfov = float(v[6]);
      if (!(length(at - eye) > 0))
        throw InputError(fmt::format("{}: eye and look_at coincide at frame {}", c.where("keys"), frame));
      if (length(cross(normalize(at - eye), normalize(cam.up))) < 1e-4f)
        throw InputError(fmt::format("{}: up is parallel to the viewing direction at frame {}", c.where("keys"), frame));
      if (vfov && !(*vfov > 0 && *vfov < 179))
        throw InputError(fmt::format("{}: the field of view at frame {} is not in (0, 179) degrees", c.where("keys"), frame));
    };
    for (int f : track.frames) {  // every key is a valid camera, whichever frame this is
      Vec3 e, a;
      float v;
      place(f, e, a, &v);
    }
    place(frame_, cam.eye, cam.look_at, &cam.vfov_degrees);
    cam.eye_end = cam.eye;
    cam.look_at_end = cam.look_at;
    if (cam.has_shutter()) {
      place(frame_ + 1.0, cam.eye_end, cam.look_at_end, nullptr);
      cam.moving = length(cam.eye_end - cam.eye) > 0 || length(cam.look_at_end - cam.look_at) > 0;
    }
  }

  // [[objects.keys]]: translate, rotate, scale at frames. The object's transform at this frame,
  // and with the camera's shutter open over an interval, at the next frame (its motion blur).
  std::optional<std::pair<Transform, Transform>> read_object_keys(ConfigTable& t, const Transform& x, bool light) {
    if (light && t.contains("keys"))
      throw InputError(fmt::format("{}: lights do not move (light sampling assumes emitters that stay where they are)",
                                   t.where("keys")));
    const std::vector<double> base{x.translate.x, x.translate.y, x.translate.z, x.rot_deg.x, x.rot_deg.y, x.rot_deg.z, x.scale};
    const KeyTrack track = read_keys(t, {{"translate", 3}, {"rotate", 3}, {"scale", 1}}, base,
                                     {bounds::kCoordinate, kAngle, bounds::kLength});
    if (track.empty()) return std::nullopt;
    if (t.contains("translate_end") || t.contains("rotate_end") || t.contains("scale_end"))
      throw InputError(fmt::format("{}: an animated object moves by its keys; translate_end, rotate_end and scale_end are "
                                   "for a still's motion blur",
                                   t.where("keys")));
    auto at = [&](double frame) {
      const std::vector<double> v = track.at(frame, interpolation_);
      Transform r;
      r.translate = {float(v[0]), float(v[1]), float(v[2])};
      r.rot_deg = {float(v[3]), float(v[4]), float(v[5])};
      r.scale = float(v[6]);
      if (!(r.scale > 0))
        throw InputError(fmt::format("{}: the scale at frame {} is not positive", t.where("keys"), frame));
      return r;
    };
    for (int f : track.frames) at(f);  // every key is a valid transform, whichever frame this is
    const Transform now = at(frame_);
    return std::pair(now, scene_.camera.has_shutter() ? at(frame_ + 1.0) : now);
  }

  // Motion blur's camera keys: the shutter interval within the frame interval [0, 1], and where
  // the camera is at the interval's end (it moves linearly from eye, look_at).
  void read_shutter(ConfigTable& c) {
    Camera& cam = scene_.camera;
    static constexpr RealBound kTime{0, 1, "a time in the frame interval [0, 1]"};
    const auto shutter = c.get("shutter", std::vector<double>{0, 0});
    if (shutter.size() != 2)
      throw InputError(fmt::format("{}: expected [open, close], times in the frame interval [0, 1]", c.where("shutter")));
    for (double v : shutter) check_bound(v, kTime, c.where("shutter"));
    if (shutter[0] > shutter[1])
      throw InputError(fmt::format("{}: the shutter opens at {} after it closes at {}", c.where("shutter"), shutter[0],
                                   shutter[1]));
    cam.shutter_open = float(shutter[0]);
    cam.shutter_close = float(shutter[1]);
    const Arr3 eye{cam.eye.x, cam.eye.y, cam.eye.z}, at{cam.look_at.x, cam.look_at.y, cam.look_at.z};
    const bool moves = c.contains("eye_end") || c.contains("look_at_end");
    cam.eye_end = vec3(c.get("eye_end", eye, bounds::kCoordinate));
    cam.look_at_end = vec3(c.get("look_at_end", at, bounds::kCoordinate));
    cam.moving = moves && (length(cam.eye_end - cam.eye) > 0 || length(cam.look_at_end - cam.look_at) > 0);
    if (!cam.moving) return;
    if (!(length(cam.look_at_end - cam.eye_end) > 0))
      throw InputError(fmt::format("{}: eye_end and look_at_end coincide", c.where("look_at_end")));
    if (length(cross(normalize(cam.look_at_end - cam.eye_end), normalize(cam.up))) < 1e-4f)
      throw InputError(fmt::format("{}: up is parallel to the viewing direction at the end of the motion",
                                   c.where("look_at_end")));
  }

  void read_environment(ConfigTable& root) {
    if (auto s = root.table("sky")) {
      Sky& sky = scene_.sky;
      sky.enabled = true;
      std::string type = s->get("type", std::string("constant"));
      if (type == "constant") {
        sky.color = vec3(s->require_vec3("color", bounds::kRadiance));
        sky.average = sky.color;
      } else if (type == "gradient") {
        sky.gradient = true;
        sky.zenith = vec3(s->require_vec3("zenith", bounds::kRadiance));
        sky.horizon = vec3(s->require_vec3("horizon", bounds::kRadiance));
        sky.ground = vec3(s->get("ground", Arr3{0, 0, 0}, bounds::kRadiance));
        const Vec3 up = vec3(s->get("up", Arr3{0, 1, 0}, bounds::kCoordinate));
        if (!(length(up) > 0)) throw InputError(fmt::format("{}: expected a non-zero direction", s->where("up")));
        sky.up = normalize(up);
        sky.average_gradient();
      } else {
        throw InputError(fmt::format("{}: expected \"constant\" or \"gradient\"", s->where("type")));
      }
      s->finish();
    }
    if (auto s = root.table("sun")) {
      Sun& sun = scene_.sun;
      sun.enabled = true;
      const Vec3 dir = vec3(s->require_vec3("direction", bounds::kCoordinate));
      if (!(length(dir) > 0))
        throw InputError(fmt::format("{}: expected a non-zero direction", s->where("direction")));
      sun.direction = normalize(dir);
      float radius_deg = float(s->get("angular_radius", 0.27, kAngle));
      if (!(radius_deg > 0 && radius_deg < 30))
        throw InputError(fmt::format("{}: expected degrees in (0, 30)", s->where("angular_radius")));
      sun.cos_max = std::cos(radius_deg * kPi / 180);
      // Irradiance on a surface facing the sun; the disc's radiance follows from its solid angle.
      Vec3 e = vec3(s->require_vec3("irradiance", bounds::kRadiance));
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
    else if (type == "conductor") m.type = MaterialType::kConductor;
    else if (type == "dielectric") m.type = MaterialType::kDielectric;
    else if (type == "plastic") m.type = MaterialType::kPlastic;
    else
      throw InputError(fmt::format(
          "{}: expected \"diffuse\", \"mirror\", \"coated\", \"conductor\", \"dielectric\" or \"plastic\"",
          t.where("type")));
    m.albedo = vec3(t.get("albedo", Arr3{0.8, 0.8, 0.8}, bounds::kReflectance));
    m.texture = texture_key(t, "texture");
    m.tint = vec3(t.get("tint", Arr3{1, 1, 1}, bounds::kReflectance));
    m.ior = float(t.get("ior", 1.5, RealBound{1, 10, "an index of refraction above 1", true}));
    m.emission = vec3(t.get("emission", Arr3{0, 0, 0}, bounds::kRadiance));
    m.two_sided = t.get("two_sided", false);
    m.opacity = texture_key(t, "opacity", [](const Texture& x) { return x.opacity_problem(); });
    m.normal_map = texture_key(t, "normal_map", [](const Texture& x) { return x.data_problem(3); });
    if (m.is_hard()) read_hard_material(t, m);
  }

  // The hard materials' keys (tracer/bsdf.h), read only for their types, so that a key of
  // another type's (roughness on a diffuse material) is refused as unknown by finish().
  // The index of the texture a material key names (-1 without the key): one of [textures], and,
  // with `problem`, fit for the use (a colour, an opacity, a map of data: tracer/texture.h says
  // why a texture is not), else InputError naming the key.
  int texture_key(ConfigTable& t, const char* key, std::string (*problem)(const Texture&) = nullptr) {
    const std::string name = t.get(key, std::string());
    if (name.empty()) return -1;
    auto it = texture_index_.find(name);
    if (it == texture_index_.end()) throw InputError(fmt::format("{}: no texture '{}' in [textures]", t.where(key), name));
    if (problem)
      if (const std::string why = problem(*scene_.textures[std::size_t(it->second)]); !why.empty())
        throw InputError(fmt::format("{}: texture '{}': {}", t.where(key), name, why));
    return it->second;
  }

  void read_hard_material(ConfigTable& t, Material& m) {
    static constexpr RealBound kRoughness{0, 1, "roughness is GGX's alpha, 0 (smooth) to 1 (very rough)"};
    const float r = float(t.get("roughness", 0.0, kRoughness));
    m.alpha_x = float(t.get("roughness_x", double(r), kRoughness));
    m.alpha_y = float(t.get("roughness_y", double(r), kRoughness));
    if ((m.alpha_x < 1e-3f) != (m.alpha_y < 1e-3f))
      throw InputError(fmt::format("{}: roughness_x and roughness_y must both be below 0.001 (smooth) or both above",
                                   t.where("roughness_x")));
    m.roughness_map = texture_key(t, "roughness_texture", [](const Texture& x) { return x.data_problem(1); });
    if (m.roughness_map >= 0 && m.alpha_x < 1e-3f)
      throw InputError(fmt::format("{}: a roughness texture scales the roughness, which is 0 (smooth) here",
                                   t.where("roughness_texture")));
    if (m.type == MaterialType::kConductor) {
      static constexpr RealBound kEta{0, 100, "a conductor's refractive index is positive, below 100", true};
      static constexpr RealBound kK{0, 100, "a conductor's extinction coefficient is in [0, 100]"};
      const std::string metal = t.get("metal", std::string());
      const bool has_eta = t.contains("eta") || t.contains("k");
      m.schlick = t.get("schlick", false);
      if (int(!metal.empty()) + int(has_eta) + int(m.schlick) > 1)
        throw InputError(fmt::format("{}: give one of metal, eta and k, or schlick = true (a Schlick tint)",
                                     t.where(metal.empty() ? "eta" : "metal")));
      if (!metal.empty()) {
        if (!conductor_preset(metal.c_str(), m.eta_c, m.k_c))
          throw InputError(fmt::format("{}: unknown metal '{}': expected \"Au\", \"Ag\", \"Cu\" or \"Al\"",
                                       t.where("metal"), metal));
      } else if (has_eta) {
        m.eta_c = vec3(t.require_vec3("eta", kEta));
        m.k_c = vec3(t.require_vec3("k", kK));
      } else if (!m.schlick) {
        conductor_preset("Al", m.eta_c, m.k_c);  // default: aluminium
      }
    }
    if (m.type == MaterialType::kDielectric) {
      m.transmittance = vec3(t.get("transmittance", Arr3{1, 1, 1}, bounds::kReflectance));
      static constexpr RealBound kAbsorption{0, 1e6, "absorption is a non-negative coefficient per scene unit"};
      m.absorption = vec3(t.get("absorption", Arr3{0, 0, 0}, kAbsorption));
      m.thin = t.get("thin", false);
      if (m.thin && m.alpha_x >= 1e-3f)
        throw InputError(fmt::format("{}: a thin sheet is smooth only (roughness 0); model rough glass as a solid",
                                     t.where("thin")));
      if (m.thin && !is_black(m.absorption))
        throw InputError(fmt::format("{}: a thin sheet has no inside to absorb in; use transmittance", t.where("absorption")));
    }
    if (m.type == MaterialType::kPlastic) m.base_inner_reflectance = fresnel_diffuse_reflectance(1.0f / m.ior);
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
      m.albedo = vec3(t.get("albedo", Arr3{0, 0, 0}, bounds::kReflectance));
      m.emission = vec3(t.require_vec3("emission", bounds::kRadiance));
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

  // An object's motion over the frame interval: its transform at time 1 (translate_end,
  // rotate_end, scale_end; each defaults to its time-0 value). Lights do not move (their
  // sampling assumes fixed emitters), so they have no such keys.
  std::optional<Transform> read_motion(ConfigTable& t, const Transform& x) {
    if (!t.contains("translate_end") && !t.contains("rotate_end") && !t.contains("scale_end")) return std::nullopt;
    Transform end;
    end.scale = float(t.get("scale_end", double(x.scale), bounds::kLength));
    end.rot_deg = vec3(t.get("rotate_end", Arr3{x.rot_deg.x, x.rot_deg.y, x.rot_deg.z}, kAngle));
    end.translate = vec3(t.get("translate_end", Arr3{x.translate.x, x.translate.y, x.translate.z}, bounds::kCoordinate));
    return end;
  }

  static bool same(const Transform& a, const Transform& b) {
    return a.scale == b.scale && a.rot_deg.x == b.rot_deg.x && a.rot_deg.y == b.rot_deg.y && a.rot_deg.z == b.rot_deg.z &&
           a.translate.x == b.translate.x && a.translate.y == b.translate.y && a.translate.z == b.translate.z;
  }

  // The meshes from `first` on belong to one moving object, which must not emit.
  void refuse_emitters(ConfigTable& t, std::size_t first, const char* key) {
    for (std::size_t i = first; i < scene_.meshes.size(); ++i)
      for (std::uint32_t mi : scene_.meshes[i].material)
        if (scene_.materials[mi].is_emitter())
          throw InputError(fmt::format("{}: a moving object cannot emit (material '{}'): light sampling assumes "
                                       "emitters that stay where they are",
                                       t.where(key), scene_.materials[mi].name));
  }

  // The meshes from `first` on belong to one moving object.
  void apply_motion(ConfigTable& t, std::size_t first, const Transform& start, const Transform& end) {
    const char* key = t.contains("keys")            ? "keys"
                      : t.contains("translate_end") ? "translate_end"
                      : t.contains("rotate_end")    ? "rotate_end"
                                                    : "scale_end";
    const int steps = motion_steps(start, end);
    refuse_emitters(t, first, key);
    for (std::size_t i = first; i < scene_.meshes.size(); ++i) {
      Mesh& m = scene_.meshes[i];
      // Each step is a copy of the mesh's corners: bounded like the triangles of one mesh.
      if (std::int64_t(steps) * std::int64_t(m.triangles()) > bounds::kMaxTriangles)
        throw InputError(fmt::format("{}: {} time steps of {} triangles are more than {} triangles' corners (fewer "
                                     "degrees of rotation, or a smaller mesh)",
                                     t.where(key), steps, m.triangles(), bounds::kMaxTriangles));
      add_motion(m, start, end);
    }
  }

  void read_object(ConfigTable& t, bool light) {
    std::string type = t.require_string("type");
    std::string name = t.get("name", fmt::format("{}{}", type, scene_.meshes.size()));
    Transform x = read_transform(t);
    const auto keyed = read_object_keys(t, x, light);
    std::optional<Transform> motion = light ? std::nullopt : read_motion(t, x);
    if (keyed) {
      x = keyed->first;
      if (!same(keyed->first, keyed->second)) motion = keyed->second;
    }
    const std::size_t first_mesh = scene_.meshes.size();
    // The object's meshes are built: its motion over the frame, if any, and an animated object's
    // emitters refused even when it rests at this frame.
    auto moved = [&] {
      if (motion) apply_motion(t, first_mesh, x, *motion);
      else if (keyed) refuse_emitters(t, first_mesh, "keys");
    };
    if (type == "obj" || type == "gltf") {
      if (light) throw InputError(fmt::format("{}: lights are quads or spheres", t.where("type")));
      std::string file = t.require_string("file");
      std::string override_mat = t.get("material", std::string());
      t.finish();
      if (type == "obj") load_obj(t, file, override_mat, x);
      else load_gltf_object(t, file, override_mat, x);
      moved();
      return;
    }
    auto uvs = t.get("uv_scale", std::vector<double>{1, 1});
    if (uvs.size() != 2) throw InputError(fmt::format("{}: expected [su, sv]", t.where("uv_scale")));
    for (double u : uvs) check_bound(u, kUvScale, t.where("uv_scale"));
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
        for (double a : sz) check_bound(a, bounds::kLength, t.where("size"));
        float hx = float(sz[0]) / 2, hz = float(sz[1]) / 2;
        v = {Vec3(-hx, 0, hz), Vec3(hx, 0, hz), Vec3(hx, 0, -hz), Vec3(-hx, 0, -hz)};
      }
      for (auto& p : v) p = x.point(p);
      b.quad(v[0], v[1], v[2], v[3], su, sv, mat);
    } else if (type == "box") {
      build_box(b, vec3(t.get("size", Arr3{1, 1, 1}, bounds::kLength)), x, su, sv, mat);
    } else if (type == "sphere") {
      float r = float(t.require_double("radius", bounds::kLength));
      int seg = t.get("segments", 48, bounds::kSegments);
      bool inward = t.get("inward", false);
      Vec3 center = vec3(t.get("center", Arr3{0, 0, 0}, bounds::kCoordinate));
      build_sphere(b, center, r, seg, x, su, sv, mat, inward, t.get("smooth", true));
      if (light && !inward) sphere_light_ = SphereLight{unsigned(scene_.meshes.size()), x.point(center), r * x.scale};
    } else if (type == "arch") {
      float r = float(t.require_double("radius", bounds::kLength));
      float h = float(t.require_double("height", bounds::kLength));
      float d = float(t.require_double("depth", bounds::kLength));
      if (!(h >= r)) throw InputError(fmt::format("{}: expected height >= radius", t.where("height")));
      int seg = t.get("segments", 16, bounds::kArchSegments);
      build_arch(b, r, h, d, seg, x, su, sv, mat);
    } else if (type == "cylinder") {
      float r = float(t.require_double("radius", bounds::kLength));
      float h = float(t.require_double("height", bounds::kLength));
      int seg = t.get("segments", 32, bounds::kSegments);
      build_cylinder(b, vec3(t.get("center", Arr3{0, 0, 0}, bounds::kCoordinate)), r, h, seg, t.get("capped", true), x, su, sv, mat);
    } else {
      throw InputError(fmt::format("{}: unknown {} type '{}' (expected {})", t.where("type"),
                                   light ? "light" : "object", type,
                                   light ? "quad or sphere" : "quad, box, sphere, cylinder, arch, obj or gltf"));
    }
    if (light && type != "quad" && type != "sphere")
      throw InputError(fmt::format("{}: lights are quads or spheres", t.where("type")));
    // `repeat = N` copies: copy k is moved by k * repeat_offset (rows of chairs, columns).
    int repeat = t.get("repeat", 1, bounds::kObjectCopies);
    Vec3 step = vec3(t.get("repeat_offset", Arr3{0, 0, 0}, bounds::kCoordinate));
    if (std::int64_t(b.mesh.material.size()) * repeat > bounds::kMaxTriangles)
      throw InputError(fmt::format("{}: {} copies of {} triangles are more than {} triangles in one mesh (32-bit "
                                   "vertex indices)",
                                   t.where("repeat"), repeat, b.mesh.material.size(), bounds::kMaxTriangles));
    if (motion && repeat > 1)
      throw InputError(fmt::format("{}: a moving object is one copy (repeat = 1): give each copy its own object",
                                   t.where("repeat")));
    repeat_mesh(b.mesh, repeat, step);
    t.finish();
    // A repeated sphere light is several spheres: those stay triangle emitters.
    if (sphere_light_ && repeat == 1) scene_.sphere_lights.push_back(*sphere_light_);
    sphere_light_.reset();
    scene_.meshes.push_back(std::move(b.mesh));
    moved();
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

  // The scene material an OBJ or glTF object's `material` key forces on all its faces, if any.
  std::optional<unsigned> override_material(ConfigTable& t, const std::string& name) {
    if (name.empty()) return std::nullopt;
    auto it = material_index_.find(name);
    if (it == material_index_.end())
      throw InputError(fmt::format("{}: no material '{}' in [materials]", t.where("material"), name));
    return it->second;
  }

  void load_obj(ConfigTable& t, const std::string& file, const std::string& override_mat, const Transform& x) {
    fs::path path = resolve_mesh_path(t, file);
    require_regular_file(path.string(), t.where("file"), "OBJ file");
    import_obj(scene_, path, x, override_material(t, override_mat));
  }

  void load_gltf_object(ConfigTable& t, const std::string& file, const std::string& override_mat, const Transform& x) {
    fs::path path = resolve_mesh_path(t, file);
    require_regular_file(path.string(), t.where("file"), "glTF file");
    if (!is_gltf_path(path))
      throw InputError(fmt::format("{}: '{}': expected a .gltf or .glb file", t.where("file"), path.string()));
    // Frame t of a sequence is at t / fps seconds of the file's animations; a still at 0 s.
    GltfImport g = import_gltf(scene_, path, x, override_material(t, override_mat), scene_.animated() ? frame_ / fps_ : 0.0);
    warnings_.insert(warnings_.end(), g.warnings.begin(), g.warnings.end());
    if (g.animated && !scene_.animated())
      warnings_.push_back(fmt::format("{}: {}: the scene is a still: the file's animations are at 0 s (an [animation] "
                                      "table renders them as a sequence)",
                                      t.where("file"), path.string()));
    else if (g.animated && scene_.camera.has_shutter())
      warnings_.push_back(fmt::format("{}: {}: the shutter blurs the object's scene keys, not the file's animations (each "
                                      "frame shows them at its instant)",
                                      t.where("file"), path.string()));
    if (!gltf_camera_ && g.camera) gltf_camera_ = g.camera;
  }

  Scene& scene_;
  const SceneLoadOptions& opt_;
  std::string dir_;
  std::map<std::string, int> texture_index_;
  std::map<std::string, unsigned> material_index_;
  std::optional<SphereLight> sphere_light_;  // of the object being read
  std::optional<Camera> gltf_camera_;         // the first glTF object's camera
  std::vector<std::string> warnings_;         // what glTF files hold that the tracer leaves out
  Interpolation interpolation_ = Interpolation::kCatmullRom;
  int frame_ = 0;                             // the frame of an animated scene
  double fps_ = kGltfFps;                     // [animation] fps: frame t is at t / fps s of glTF animations
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

namespace {

// Faces whose image is the ray tracer's tie-break (tracer/scene_check.h): warned, not refused,
// since imported collections have them (a decal on a wall) and render all the same. Checked once
// per scene content and frame in a process (a run loads a scene several times: checking the
// config, planning, rendering), at both ends of the shutter where meshes move, and every frame of
// a sequence (its keys move the geometry); a pair of (mesh, material) is named once per scene
// content, not again in each frame that has it.
void warn_coplanar_overlaps(const Scene& scene) {
  static std::mutex mutex;
  static std::set<std::pair<std::string, int>> checked;
  static std::set<std::pair<std::string, std::tuple<unsigned, unsigned, unsigned, unsigned>>> named;
  {
    std::lock_guard lock(mutex);
    if (!checked.insert({scene.content_hash, scene.frame}).second) return;
  }
  bool complete = true;
  std::vector<CoplanarOverlap> overlaps = find_coplanar_overlaps_over_shutter(scene, &complete);
  {
    std::lock_guard lock(mutex);
    std::erase_if(overlaps, [&](const CoplanarOverlap& o) {
      return !named.insert({scene.content_hash, o.pair()}).second;
    });
  }
  constexpr std::size_t kShown = 5;
  for (std::size_t i = 0; i < std::min(overlaps.size(), kShown); ++i)
    spdlog::warn("{}{}", describe(scene, overlaps[i]), scene.animated() ? fmt::format(" (frame {})", scene.frame) : "");
  if (overlaps.size() > kShown)
    spdlog::warn("scene '{}': {} more pairs of meshes with overlapping coplanar faces", scene.name,
                 overlaps.size() - kShown);
  if (!complete)
    spdlog::warn("scene '{}': many faces are stacked in one place; the check for coplanar faces stopped at its work "
                 "limit, and there may be more than it named",
                 scene.name);
}

}  // namespace

std::shared_ptr<const Scene> load_scene(const std::string& name_or_path, const SceneLoadOptions& options) {
  fs::path path;
  std::string name;
  std::error_code ec;  // a name the system refuses (too long) is no such scene, not an exception
  if (fs::is_regular_file(name_or_path, ec)) {
    path = name_or_path;
    name = path.stem().string();
  } else {
    fs::path p = builtin_dir() / (name_or_path + ".toml");
    const bool builtin =
        name_or_path.find('/') == std::string::npos && !name_or_path.ends_with(".toml") && fs::is_regular_file(p, ec);
    if (!builtin && fs::exists(name_or_path, ec))  // a folder, a device or a pipe: not a file to read a scene from
      throw InputError(fmt::format("scene '{}': exists but is not a regular file (expected a scene TOML file or the name "
                                   "of a built-in scene)",
                                   name_or_path));
    if (!builtin)
      throw InputError(fmt::format("scene '{}': no such scene file or built-in scene (built-in: {})", name_or_path,
                                   fmt::join(builtin_scene_names(), ", ")));
    path = p;
    name = name_or_path;
  }
  auto scene = std::make_shared<Scene>();
  scene->name = name;
  Loader loader(*scene, options);
  if (is_gltf_path(path)) loader.load_gltf(path.string());
  else loader.load(path.string());
  // Every reader of scenes (render, reference, run, export) lists what was left out.
  for (const auto& w : loader.warnings()) spdlog::warn("{}", w);
  scene->commit();
  scene->content_hash = scene_content_hash(*scene);  // once: the OBJ files can be large
  warn_coplanar_overlaps(*scene);
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
  // A frame of an animated scene is its own content (docs/sequences.md); a still's hash is the
  // files' alone, as before sequences existed.
  if (scene.animated()) {
    const std::string f = fmt::format("frame={}/{}", scene.frame, scene.frames);
    feed(f.data(), f.size());
  }
  return fmt::format("{:016x}", h);
}

const std::string& scene_name(const Scene& scene) { return scene.name; }

}  // namespace dnb
