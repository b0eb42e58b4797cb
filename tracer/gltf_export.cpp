// glTF export (tracer/gltf_export.h). The document is built with nlohmann::json rather than
// tinygltf's writer: the exporter needs extras and extensions written exactly as they are, and
// tinygltf's Value tree would only be a detour to the same JSON.
#include "tracer/gltf_export.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "tracer/bsdf.h"
#include "tracer/scene.h"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace dnb {
namespace {

using rt::Material;
using rt::MaterialType;
using rt::Vec3;

json rgb(Vec3 v) { return json::array({v.x, v.y, v.z}); }

// A colour texture as a 16-bit sRGB PNG (glTF's base colour is sRGB): evaluated at the texel
// centres of a 1024 x 1024 image, row 0 at the top (v = 1: the tracer's v runs up). An image
// texture of up to that size is reproduced to 16-bit rounding where its texels align, a
// procedural one is sampled (its sharp edges move by at most half a texel).
std::string bake_png(const rt::Texture& t, const std::string& scratch) {
  constexpr int n = 1024;
  std::vector<std::uint16_t> px(std::size_t(n) * n * 3);
  auto encode = [](float c) {
    c = std::clamp(c, 0.0f, 1.0f);
    const float s = c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1 / 2.4f) - 0.055f;
    return std::uint16_t(std::lround(s * 65535));
  };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const Vec3 c = t.eval((i + 0.5f) / n, 1.0f - (j + 0.5f) / n);
      for (int k = 0; k < 3; ++k) px[(std::size_t(j) * n + std::size_t(i)) * 3 + std::size_t(k)] = encode(c[k]);
    }
  auto out = OIIO::ImageOutput::create(scratch);
  if (!out || !out->open(scratch, OIIO::ImageSpec(n, n, 3, OIIO::TypeDesc::UINT16)) ||
      !out->write_image(OIIO::TypeDesc::UINT16, px.data()) || !out->close())
    throw WorkError(fmt::format("export-gltf: cannot write '{}': {}", scratch, OIIO::geterror()));
  std::ifstream in(scratch, std::ios::binary);
  std::string bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  fs::remove(scratch);
  return bytes;
}

[[noreturn]] void refuse(const Scene& s, const std::string& what) {
  throw InputError(fmt::format("scene '{}': {} (glTF export)", s.name, what));
}

const char* type_name(MaterialType t) {
  switch (t) {
    case MaterialType::kDiffuse: return "diffuse";
    case MaterialType::kMirror: return "mirror";
    case MaterialType::kCoated: return "coated";
    case MaterialType::kConductor: return "conductor";
    case MaterialType::kDielectric: return "dielectric";
    case MaterialType::kPlastic: return "plastic";
  }
  return "diffuse";
}

void check_exportable(const Scene& s) {
  if (s.camera.has_lens()) refuse(s, "a thin lens (depth of field) is not exported");
  if (s.camera.timed()) refuse(s, "motion blur (a shutter or a moving camera) is not exported");
  for (const auto& m : s.meshes)
    if (m.moving()) refuse(s, fmt::format("mesh '{}' moves: motion blur is not exported", m.name));
  for (const Material& m : s.materials) {
    if (m.opacity >= 0 || m.normal_map >= 0 || m.roughness_map >= 0)
      refuse(s, fmt::format("material '{}': opacity, normal and roughness maps are not exported yet", m.name));
    if (m.texture >= 0 && m.type != MaterialType::kDiffuse && m.type != MaterialType::kPlastic && m.type != MaterialType::kCoated)
      refuse(s, fmt::format("material '{}': a texture on a {} is not read by the tracer", m.name, type_name(m.type)));
    if (m.alpha_x != m.alpha_y) refuse(s, fmt::format("material '{}': anisotropic roughness has no glTF form", m.name));
  }
}

// The nearest glTF material, and the tracer's own in extras.
json material_json(const Material& m, int texture) {
  json pbr, ext = json::object();
  const float roughness = std::sqrt(m.alpha_x);  // GGX alpha = glTF roughness^2
  json exact = {{"type", type_name(m.type)}};
  switch (m.type) {
    case MaterialType::kDiffuse:
      pbr = {{"baseColorFactor", {m.albedo.x, m.albedo.y, m.albedo.z, 1}}, {"metallicFactor", 0}, {"roughnessFactor", 1}};
      ext["KHR_materials_specular"] = {{"specularFactor", 0}};
      exact["albedo"] = rgb(m.albedo);
      break;
    case MaterialType::kMirror:
      pbr = {{"baseColorFactor", {m.tint.x, m.tint.y, m.tint.z, 1}}, {"metallicFactor", 1}, {"roughnessFactor", 0}};
      exact["tint"] = rgb(m.tint);
      break;
    case MaterialType::kConductor: {
      // glTF's metal is Schlick's curve from its base colour: F at normal incidence.
      const Vec3 f0 = rt::conductor_fresnel(1.0f, m.eta_c, m.k_c, m.schlick, m.tint);
      pbr = {{"baseColorFactor", {std::min(1.0f, f0.x), std::min(1.0f, f0.y), std::min(1.0f, f0.z), 1}},
             {"metallicFactor", 1}, {"roughnessFactor", roughness}};
      exact.update({{"tint", rgb(m.tint)}, {"eta", rgb(m.eta_c)}, {"k", rgb(m.k_c)}, {"schlick", m.schlick}, {"alpha", m.alpha_x}});
      break;
    }
    case MaterialType::kDielectric:
      pbr = {{"baseColorFactor", {m.transmittance.x, m.transmittance.y, m.transmittance.z, 1}}, {"metallicFactor", 0},
             {"roughnessFactor", roughness}};
      ext["KHR_materials_transmission"] = {{"transmissionFactor", 1}};
      ext["KHR_materials_ior"] = {{"ior", m.ior}};
      if (!rt::is_black(m.absorption)) {
        // Beer: what is left after one unit is exp(-absorption).
        ext["KHR_materials_volume"] = {{"thicknessFactor", 1}, {"attenuationDistance", 1},
                                       {"attenuationColor", {std::exp(-m.absorption.x), std::exp(-m.absorption.y), std::exp(-m.absorption.z)}}};
      }
      exact.update({{"tint", rgb(m.tint)}, {"transmittance", rgb(m.transmittance)}, {"ior", m.ior}, {"alpha", m.alpha_x},
                    {"absorption", rgb(m.absorption)}, {"thin", m.thin}});
      break;
    case MaterialType::kPlastic:
    case MaterialType::kCoated:
      pbr = {{"baseColorFactor", {m.albedo.x, m.albedo.y, m.albedo.z, 1}}, {"metallicFactor", 0},
             {"roughnessFactor", m.type == MaterialType::kCoated ? 0.0f : roughness}};
      ext["KHR_materials_ior"] = {{"ior", m.ior}};
      exact.update({{"albedo", rgb(m.albedo)}, {"tint", rgb(m.tint)}, {"ior", m.ior}, {"alpha", m.alpha_x}});
      break;
  }
  json j = {{"name", m.name}, {"pbrMetallicRoughness", pbr}, {"doubleSided", !m.is_emitter() || m.two_sided}};
  if (m.is_emitter()) {
    const float peak = std::max({m.emission.x, m.emission.y, m.emission.z});
    j["emissiveFactor"] = rgb(m.emission / peak);
    if (peak != 1) ext["KHR_materials_emissive_strength"] = {{"emissiveStrength", peak}};
    exact["emission"] = rgb(m.emission);
    exact["two_sided"] = m.two_sided;
  }
  if (texture >= 0) {
    j["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", texture}};
    exact["texture"] = texture;  // the albedo is multiplied by it, as glTF's base colour is
  }
  if (!ext.empty()) j["extensions"] = ext;
  j["extras"] = {{"denoisebench", exact}};
  return j;
}

}  // namespace

std::string export_gltf(const Scene& scene, const GltfExportSettings& settings, const std::string& path) {
  check_exportable(scene);
  std::error_code ec;
  if (fs::exists(path, ec)) throw InputError(fmt::format("export-gltf: '{}' exists (an export never overwrites)", path));
  json doc = {{"asset", {{"version", "2.0"}, {"generator", "denoisebench export-gltf"}}}, {"scene", 0}};
  std::string bin;
  std::set<std::string> used;
  auto add_view = [&](const void* data, std::size_t bytes) {
    while (bin.size() % 4) bin += '\0';
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes}});
    bin.append(static_cast<const char*>(data), bytes);
    return doc["bufferViews"].size() - 1;
  };
  auto add_accessor = [&](const std::vector<float>& v, int n, bool bounds) {
    json a = {{"bufferView", add_view(v.data(), v.size() * 4)}, {"componentType", 5126}, {"count", v.size() / std::size_t(n)},
              {"type", n == 3 ? "VEC3" : "VEC2"}};
    if (bounds) {  // glTF requires POSITION's min and max
      std::vector<float> lo(3, 1e30f), hi(3, -1e30f);
      for (std::size_t i = 0; i < v.size(); ++i) {
        lo[i % 3] = std::min(lo[i % 3], v[i]);
        hi[i % 3] = std::max(hi[i % 3], v[i]);
      }
      a["min"] = lo;
      a["max"] = hi;
    }
    doc["accessors"].push_back(a);
    return doc["accessors"].size() - 1;
  };
  std::map<unsigned, std::size_t> material_index;
  std::map<int, int> texture_index;  // scene texture -> glTF texture
  json roots = json::array();
  for (const auto& mesh : scene.meshes) {
    std::map<unsigned, std::vector<std::size_t>> by_material;
    for (std::size_t t = 0; t < mesh.triangles(); ++t) by_material[mesh.material[t]].push_back(t);
    for (const auto& [mi, tris] : by_material) {
      if (!material_index.count(mi)) {
        const Material& m = scene.materials[mi];
        int texture = -1;
        if (m.texture >= 0) {
          if (!texture_index.count(m.texture)) {
            const std::string png = bake_png(*scene.textures[std::size_t(m.texture)], path + ".bake.png");
            doc["images"].push_back({{"uri", "data:image/png;base64," + OIIO::Strutil::base64_encode(png)}});
            doc["textures"].push_back({{"source", doc["images"].size() - 1}});
            texture_index[m.texture] = int(doc["textures"].size() - 1);
          }
          texture = texture_index[m.texture];
        }
        doc["materials"].push_back(material_json(m, texture));
        material_index[mi] = doc["materials"].size() - 1;
      }
      std::vector<float> pos, nor, uv;
      for (std::size_t t : tris)
        for (int k = 0; k < 3; ++k) {
          const Vec3 p = mesh.positions[3 * t + std::size_t(k)];
          pos.insert(pos.end(), {p.x, p.y, p.z});
          if (!mesh.normals.empty()) {
            const Vec3 n = mesh.normals[3 * t + std::size_t(k)];
            nor.insert(nor.end(), {n.x, n.y, n.z});
          }
          if (!mesh.uvs.empty()) uv.insert(uv.end(), {mesh.uvs[6 * t + 2 * std::size_t(k)], 1.0f - mesh.uvs[6 * t + 2 * std::size_t(k) + 1]});
        }
      json prim = {{"attributes", {{"POSITION", add_accessor(pos, 3, true)}}}, {"material", material_index[mi]}};
      if (!nor.empty()) prim["attributes"]["NORMAL"] = add_accessor(nor, 3, false);
      if (!uv.empty()) prim["attributes"]["TEXCOORD_0"] = add_accessor(uv, 2, false);
      doc["meshes"].push_back({{"name", mesh.name}, {"primitives", {prim}}});
      doc["nodes"].push_back({{"name", mesh.name}, {"mesh", doc["meshes"].size() - 1}});
      roots.push_back(doc["nodes"].size() - 1);
    }
  }
  // The camera node: columns right, up, -forward, and the eye.
  const rt::Camera& c = scene.camera;
  const Vec3 f = rt::normalize(c.look_at - c.eye), r = rt::normalize(rt::cross(f, c.up)), u = rt::cross(r, f);
  doc["cameras"] = {{{"type", "perspective"},
                     {"perspective", {{"yfov", c.vfov_degrees * rt::kPi / 180}, {"znear", 1e-3},
                                      {"aspectRatio", double(settings.width) / settings.height}}}}};
  doc["nodes"].push_back({{"name", "camera"}, {"camera", 0},
                          {"matrix", {r.x, r.y, r.z, 0, u.x, u.y, u.z, 0, -f.x, -f.y, -f.z, 0, c.eye.x, c.eye.y, c.eye.z, 1}}});
  roots.push_back(doc["nodes"].size() - 1);
  json scene_extras = json::object();
  if (scene.sky.enabled && !scene.sky.gradient) scene_extras["sky"] = rgb(scene.sky.color);
  if (scene.sky.enabled && scene.sky.gradient)
    scene_extras["sky_gradient"] = {{"zenith", rgb(scene.sky.zenith)}, {"horizon", rgb(scene.sky.horizon)},
                                    {"ground", rgb(scene.sky.ground)}, {"up", rgb(scene.sky.up)}};
  if (scene.sun.enabled) {
    const Vec3 e = scene.sun.radiance * scene.sun.solid_angle();  // irradiance
    const float peak = std::max({e.x, e.y, e.z});
    doc["extensions"]["KHR_lights_punctual"]["lights"] = {
        {{"type", "directional"}, {"color", rgb(e / peak)}, {"intensity", peak},
         {"extras", {{"denoisebench", {{"angular_radius_degrees", std::acos(scene.sun.cos_max) * 180 / rt::kPi}}}}}}};
    // The light shines along its node's -z: +z towards the sun.
    const Vec3 z = scene.sun.direction, x = rt::normalize(rt::cross(std::fabs(z.y) < 0.9f ? Vec3(0, 1, 0) : Vec3(1, 0, 0), z)),
               y = rt::cross(z, x);
    doc["nodes"].push_back({{"name", "sun"}, {"matrix", {x.x, x.y, x.z, 0, y.x, y.y, y.z, 0, z.x, z.y, z.z, 0, 0, 0, 0, 1}},
                            {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
    roots.push_back(doc["nodes"].size() - 1);
  }
  doc["scenes"] = {{{"nodes", roots}, {"extras", {{"denoisebench", scene_extras}}}}};
  for (const auto& m : doc["materials"])
    if (m.contains("extensions"))
      for (auto it = m["extensions"].begin(); it != m["extensions"].end(); ++it) used.insert(it.key());
  if (doc.contains("extensions")) used.insert("KHR_lights_punctual");
  if (!used.empty()) doc["extensionsUsed"] = used;
  doc["buffers"] = {{{"byteLength", bin.size()},
                     {"uri", "data:application/octet-stream;base64," + OIIO::Strutil::base64_encode(bin)}}};
  write_text_atomic(path, doc.dump(1) + "\n");
  return path;
}

}  // namespace dnb
