// Scene -> Mitsuba 3 XML and PLY files (tracer/mitsuba_export.h has the mapping and what is refused).
#include "tracer/mitsuba_export.h"

#include <bit>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <unistd.h>
#include <vector>

#include <fmt/format.h>

#include "core/errors.h"
#include "tracer/integrator.h"
#include "tracer/scene.h"

namespace fs = std::filesystem;

namespace dnb {
using namespace rt;

namespace {

bool is_rough(const Material& m) { return !(m.alpha_x < 1e-3f && m.alpha_y < 1e-3f); }
bool is_anisotropic(const Material& m) { return is_rough(m) && m.alpha_x != m.alpha_y; }

[[noreturn]] void refuse(const Scene& s, const std::string& what) {
  throw InputError(fmt::format("scene '{}' ({}): cannot export to Mitsuba 3: {}", s.name, s.source_file, what));
}

// Which materials some triangle uses, and per mesh whether it uses each.
std::vector<bool> used_materials(const Scene& s) {
  std::vector<bool> used(s.materials.size(), false);
  for (const Mesh& m : s.meshes)
    for (std::uint32_t id : m.material) used[id] = true;
  return used;
}

// The tracer's GGX lobes are oriented by Frame(ns).t (tracer/math.h), the frame of the shading
// normal facing the ray; Mitsuba's by the surface's dp_du. Exact only when every triangle of the
// material is flat (ns is the face normal) and its front and back frames share their axes, so
// that one exported tangent serves both sides.
void check_anisotropic_faces(const Scene& s, const Mesh& mesh, std::uint32_t mat) {
  const Material& m = s.materials[mat];
  for (std::size_t t = 0; t < mesh.triangles(); ++t) {
    if (mesh.material[t] != mat) continue;
    if (!mesh.normals.empty())
      refuse(s, fmt::format("material '{}' has anisotropic roughness on mesh '{}', which has interpolated normals: "
                            "the tracer's tangent follows the shading normal per hit, Mitsuba's the uv "
                            "parametrisation",
                            m.name, mesh.name));
    const Vec3 n = normalize(cross(mesh.positions[3 * t + 1] - mesh.positions[3 * t], mesh.positions[3 * t + 2] - mesh.positions[3 * t]));
    if (std::fabs(dot(Frame(n).t, Frame(-n).t)) < 1 - 1e-5f)
      refuse(s, fmt::format("material '{}' has anisotropic roughness on mesh '{}' triangle {}, whose front and back "
                            "tangent frames differ (the tracer builds the frame from the normal facing the ray; "
                            "Mitsuba keeps one tangent for both sides)",
                            m.name, mesh.name, t));
  }
}

// ---- XML ----------------------------------------------------------------------------------------
std::string rgb(const char* name, Vec3 v) {
  return fmt::format("<rgb name=\"{}\" value=\"{}, {}, {}\"/>", name, v.x, v.y, v.z);
}
std::string flt(const char* name, float v) { return fmt::format("<float name=\"{}\" value=\"{}\"/>", name, v); }
std::string vec(Vec3 v) { return fmt::format("{}, {}, {}", v.x, v.y, v.z); }

std::string inner_bsdf(const Material& m) {
  switch (m.type) {
    case MaterialType::kDiffuse:
      return fmt::format("<bsdf type=\"diffuse\">{}</bsdf>", rgb("reflectance", m.albedo));
    case MaterialType::kMirror:
      return fmt::format("<bsdf type=\"conductor\"><string name=\"material\" value=\"none\"/>{}</bsdf>",
                         rgb("specular_reflectance", m.tint));
    case MaterialType::kConductor: {
      const std::string common = rgb("eta", m.eta_c) + rgb("k", m.k_c) + rgb("specular_reflectance", m.tint);
      if (!is_rough(m)) return "<bsdf type=\"conductor\">" + common + "</bsdf>";
      return "<bsdf type=\"roughconductor\"><string name=\"distribution\" value=\"ggx\"/>" + flt("alpha_u", m.alpha_x) +
             flt("alpha_v", m.alpha_y) + common + "</bsdf>";
    }
    case MaterialType::kDielectric: {
      const std::string common = flt("int_ior", m.ior) + flt("ext_ior", 1.0f) + rgb("specular_reflectance", m.tint) +
                                 rgb("specular_transmittance", m.transmittance);
      if (m.thin) return "<bsdf type=\"thindielectric\">" + common + "</bsdf>";
      if (!is_rough(m)) return "<bsdf type=\"dielectric\">" + common + "</bsdf>";
      return "<bsdf type=\"roughdielectric\"><string name=\"distribution\" value=\"ggx\"/>" + flt("alpha_u", m.alpha_x) +
             flt("alpha_v", m.alpha_y) + common + "</bsdf>";
    }
    case MaterialType::kPlastic: {
      const std::string common = rgb("diffuse_reflectance", m.albedo) + rgb("specular_reflectance", m.tint) +
                                 flt("int_ior", m.ior) + flt("ext_ior", 1.0f) +
                                 "<boolean name=\"nonlinear\" value=\"true\"/>";
      if (!is_rough(m)) return "<bsdf type=\"plastic\">" + common + "</bsdf>";
      return "<bsdf type=\"roughplastic\"><string name=\"distribution\" value=\"ggx\"/>" + flt("alpha", m.alpha_x) +
             common + "</bsdf>";
    }
    case MaterialType::kCoated:
      break;  // refused by check_mitsuba_exportable
  }
  throw InputError("material '" + m.name + "': no Mitsuba 3 BSDF");
}

std::string bsdf_xml(const Material& m, const std::string& id) {
  // Dielectrics are two-sided by nature (the side picks eta); everything else reflects on both
  // sides in the tracer and on the front only in Mitsuba without the wrapper.
  if (m.type == MaterialType::kDielectric) {
    std::string b = inner_bsdf(m);
    return b.insert(b.find('>'), fmt::format(" id=\"{}\"", id));
  }
  return fmt::format("<bsdf type=\"twosided\" id=\"{}\">{}</bsdf>", id, inner_bsdf(m));
}

std::string sensor_xml(const Scene& s, const MitsubaExportSettings& e) {
  const Camera& c = s.camera;
  std::string x = fmt::format("  <sensor type=\"{}\">\n", c.has_lens() ? "thinlens" : "perspective");
  x += fmt::format("    {}\n    <string name=\"fov_axis\" value=\"y\"/>\n", flt("fov", c.vfov_degrees));
  if (c.has_lens())
    x += fmt::format("    {}\n    {}\n", flt("aperture_radius", c.aperture_radius), flt("focus_distance", c.focus_distance));
  // The tracer's camera rays start at the eye with no near plane; Mitsuba's default near_clip
  // (0.01) and far_clip (1e4) would cut surfaces the tracer sees. Scene coordinates are within
  // 1e6 (core/bounds.h), so 1e7 is beyond everything; 1e-4 keeps the projection well conditioned.
  x += fmt::format("    {}\n    {}\n", flt("near_clip", 1e-4f), flt("far_clip", 1e7f));
  // lookat: Mitsuba's image x runs along cross(dir, up) and y down the up vector, as the tracer's
  // generate_ray (the agreement test's scenes are asymmetric, so a mirrored image fails it).
  x += fmt::format("    <transform name=\"to_world\"><lookat origin=\"{}\" target=\"{}\" up=\"{}\"/></transform>\n",
                   vec(c.eye), vec(c.look_at), vec(c.up));
  x += fmt::format("    <sampler type=\"independent\"><integer name=\"sample_count\" value=\"{}\"/>"
                   "<integer name=\"seed\" value=\"{}\"/></sampler>\n",
                   e.spp, e.seed);
  x += fmt::format("    <film type=\"hdrfilm\"><integer name=\"width\" value=\"{}\"/><integer name=\"height\" "
                   "value=\"{}\"/><string name=\"pixel_format\" value=\"rgb\"/><rfilter type=\"box\"/></film>\n",
                   e.width, e.height);
  return x + "  </sensor>\n";
}

// ---- PLY ----------------------------------------------------------------------------------------
static_assert(std::endian::native == std::endian::little, "the PLY files are written as little-endian bytes");

template <class T>
void put(std::string& out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.append(b, sizeof(T));
}

// The triangles of `mesh` with material `mat` as a binary PLY. `tangent_uvs`: texture coordinates
// u = p . t, v = p . b in each face's tracer frame, so that Mitsuba's dp_du is the tracer's
// tangent (anisotropic lobes; check_anisotropic_faces has made sure that is exact).
std::string ply_bytes(const Mesh& mesh, std::uint32_t mat, bool tangent_uvs) {
  std::vector<std::size_t> tris;
  for (std::size_t t = 0; t < mesh.triangles(); ++t)
    if (mesh.material[t] == mat) tris.push_back(t);
  const bool normals = !mesh.normals.empty();
  const bool uvs = tangent_uvs || !mesh.uvs.empty();
  std::string out = "ply\nformat binary_little_endian 1.0\n";
  out += fmt::format("element vertex {}\nproperty float x\nproperty float y\nproperty float z\n", 3 * tris.size());
  if (normals) out += "property float nx\nproperty float ny\nproperty float nz\n";
  if (uvs) out += "property float u\nproperty float v\n";
  out += fmt::format("element face {}\nproperty list uchar int vertex_indices\nend_header\n", tris.size());
  for (std::size_t t : tris) {
    const Vec3* p = &mesh.positions[3 * t];
    const Frame f(normalize(cross(p[1] - p[0], p[2] - p[0])));
    for (int k = 0; k < 3; ++k) {
      for (int a = 0; a < 3; ++a) put(out, p[k][a]);
      if (normals)
        for (int a = 0; a < 3; ++a) put(out, mesh.normals[3 * t + k][a]);
      if (tangent_uvs) {
        put(out, dot(p[k], f.t));
        put(out, dot(p[k], f.b));
      } else if (uvs) {
        put(out, mesh.uvs[6 * t + 2 * k]);
        put(out, mesh.uvs[6 * t + 2 * k + 1]);
      }
    }
  }
  for (std::size_t i = 0; i < tris.size(); ++i) {
    put(out, std::uint8_t(3));
    for (int k = 0; k < 3; ++k) put(out, std::int32_t(3 * i + std::size_t(k)));
  }
  return out;
}

void write_file(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary);
  out.write(bytes.data(), std::streamsize(bytes.size()));
  out.close();
  if (!out) throw WorkError(fmt::format("{}: could not write the file ({})", p.string(), std::strerror(errno)));
}

}  // namespace

void check_mitsuba_exportable(const Scene& s) {
  if (s.sun.enabled)
    refuse(s, "the sun: a disc of constant radiance and finite angular radius; Mitsuba 3's `directional` emitter is a "
              "delta direction and it has no sun-disc emitter");
  if (s.sky.enabled && s.sky.gradient)
    refuse(s, "the gradient sky (zenith/horizon/ground blended by the cosine): Mitsuba 3's `constant` emitter is "
              "uniform, and an `envmap` would be a tabulated approximation");
  // Mitsuba 3 has no animated transforms (its shapes and sensors are static): no motion blur.
  if (s.camera.has_shutter() || s.camera.moving || s.camera.shutter_open > 0)
    refuse(s, "the camera's shutter interval or motion (motion blur): Mitsuba 3 has no animated transforms");
  for (const Mesh& mesh : s.meshes)
    if (mesh.moving()) refuse(s, fmt::format("mesh '{}' moves (motion blur): Mitsuba 3 has no animated transforms", mesh.name));
  const std::vector<bool> used = used_materials(s);
  for (std::size_t i = 0; i < s.materials.size(); ++i) {
    if (!used[i]) continue;
    const Material& m = s.materials[i];
    const std::string name = fmt::format("material '{}'", m.name);
    if (m.type == MaterialType::kCoated)
      refuse(s, name + ": the `coated` material (a Schlick-weighted mirror coat over a Lambertian base, not energy "
                       "conserving) has no Mitsuba 3 counterpart; use `plastic`");
    if (m.type == MaterialType::kConductor && m.schlick)
      refuse(s, name + ": a Schlick conductor (F0 = tint): Mitsuba 3's conductors take a complex index (eta, k); give "
                       "`metal` or `eta` and `k`");
    if (m.type == MaterialType::kDielectric && !is_black(m.absorption))
      refuse(s, name + ": absorption inside glass (Beer) would need the volpath integrator and a homogeneous medium");
    if (m.type == MaterialType::kPlastic && is_anisotropic(m))
      refuse(s, name + ": anisotropic roughness on plastic: Mitsuba 3's roughplastic is isotropic");
    if (m.texture >= 0)
      refuse(s, name + ": textures are not exported (an image's v orientation and texel centres are not checked "
                       "against Mitsuba's bitmap; procedural textures would have to be baked)");
    if (m.normal_map >= 0 || m.roughness_map >= 0)
      refuse(s, name + ": a normal or roughness map: textures are not exported");
    if (m.opacity >= 0)
      refuse(s, name + ": an opacity (alpha cut-out) texture: textures are not exported, and Mitsuba's `mask` BSDF "
                       "is not checked against the tracer's threshold at 0.5");
    if (m.is_emitter() && m.two_sided)
      refuse(s, name + ": a two-sided emitter: Mitsuba 3's area emitter emits from the front only, and a reversed "
                       "coincident copy would occlude it at random");
  }
  for (const Mesh& mesh : s.meshes)
    for (std::size_t i = 0; i < s.materials.size(); ++i)
      if (used[i] && is_anisotropic(s.materials[i])) check_anisotropic_faces(s, mesh, std::uint32_t(i));
}

std::string export_mitsuba(const Scene& s, const MitsubaExportSettings& e, const std::string& dir) {
  check_mitsuba_exportable(s);
  if (e.width < 1 || e.height < 1 || e.spp < 1 || e.max_depth < 1)
    throw InputError(fmt::format("export to Mitsuba: expected a positive size, spp and max_depth, got {}x{}, {}, {}",
                                 e.width, e.height, e.spp, e.max_depth));
  if (e.seed > 0xffffffffu)
    throw InputError(fmt::format("export to Mitsuba: seed {} is above 2^32 - 1 (Mitsuba's samplers take 32-bit seeds)",
                                 e.seed));
  const fs::path dest = fs::absolute(dir).lexically_normal();
  std::error_code ec;
  if (fs::exists(dest, ec) && !(fs::is_directory(dest, ec) && fs::is_empty(dest, ec)))
    throw InputError(fmt::format("{}: exists and is not an empty folder (an export never mixes with other files; "
                                 "remove it or choose another)",
                                 dest.string()));

  // The XML, with one BSDF per used material and one shape per (mesh, material) pair.
  std::string xml = "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n";
  xml += "<!-- written by denoisebench export-mitsuba (tracer/mitsuba_export.h) -->\n";
  xml += "<scene version=\"3.0.0\">\n";
  // Russian roulette from the same vertex as the tracer's (mitsuba_export.h, "integrator"):
  // Mitsuba's default (5) would make it trace more of each path than the tracer does.
  xml += fmt::format(
      "  <integrator type=\"path\"><integer name=\"max_depth\" value=\"{}\"/>"
      "<integer name=\"rr_depth\" value=\"{}\"/></integrator>\n",
      e.max_depth, rt::PathTracer::Options{}.rr_depth);
  xml += sensor_xml(s, e);
  if (s.sky.enabled && !is_black(s.sky.color))
    xml += fmt::format("  <emitter type=\"constant\">{}</emitter>\n", rgb("radiance", s.sky.color));
  const std::vector<bool> used = used_materials(s);
  for (std::size_t i = 0; i < s.materials.size(); ++i)
    if (used[i]) xml += "  " + bsdf_xml(s.materials[i], fmt::format("mat{}", i)) + "\n";
  std::map<std::string, std::string> plys;  // file name -> bytes
  for (std::size_t mi = 0; mi < s.meshes.size(); ++mi) {
    const Mesh& mesh = s.meshes[mi];
    std::vector<bool> here(s.materials.size(), false);
    for (std::uint32_t id : mesh.material) here[id] = true;
    for (std::uint32_t id = 0; id < here.size(); ++id) {
      if (!here[id]) continue;
      const Material& m = s.materials[id];
      const std::string file = fmt::format("meshes/mesh{}_mat{}.ply", mi, id);
      plys[file] = ply_bytes(mesh, id, is_anisotropic(m));
      xml += fmt::format("  <shape type=\"ply\"><string name=\"filename\" value=\"{}\"/>", file);
      if (mesh.normals.empty()) xml += "<boolean name=\"face_normals\" value=\"true\"/>";
      xml += fmt::format("<ref id=\"mat{}\"/>", id);
      if (m.is_emitter()) xml += fmt::format("<emitter type=\"area\">{}</emitter>", rgb("radiance", m.emission));
      xml += "</shape>\n";
    }
  }
  xml += "</scene>\n";

  // Everything into a temporary folder beside DIR, then one rename.
  const fs::path tmp = dest.parent_path() / fmt::format(".{}.tmp-{}", dest.filename().string(), ::getpid());
  fs::remove_all(tmp, ec);
  try {
    fs::create_directories(tmp / "meshes");
    for (const auto& [file, bytes] : plys) write_file(tmp / file, bytes);
    write_file(tmp / "scene.xml", xml);
    if (fs::exists(dest, ec)) fs::remove(dest);  // the empty folder checked above
    fs::rename(tmp, dest);
  } catch (const fs::filesystem_error& err) {
    fs::remove_all(tmp, ec);
    throw WorkError(fmt::format("{}: could not write the export: {}", dest.string(), err.what()));
  } catch (...) {
    fs::remove_all(tmp, ec);
    throw;
  }
  return (dest / "scene.xml").string();
}

}  // namespace dnb
