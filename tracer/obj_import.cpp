// OBJ/MTL import (tracer/obj_import.h): tinyobjloader reads and triangulates the file; the
// MTL materials are mapped onto the tracer's materials, then the faces become one mesh.
#include "tracer/obj_import.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <vector>

#include <fmt/format.h>
#include <tiny_obj_loader.h>

#include "core/bounds.h"
#include "core/errors.h"
#include "tracer/scene.h"
#include "tracer/texture.h"

namespace fs = std::filesystem;

namespace dnb::rt {

namespace {

// The material files named by the OBJ's mtllib lines, for the content hash (tinyobjloader
// reads them but does not say which).
void append_mtllib_files(const fs::path& path, std::vector<std::string>& files) {
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("mtllib", 0) != 0) continue;
    std::string n = line.substr(6);
    n.erase(0, n.find_first_not_of(" \t"));
    while (!n.empty() && (n.back() == '\r' || n.back() == ' ' || n.back() == '\t')) n.pop_back();
    fs::path mp = find_file_ignoring_case(path.parent_path(), n);
    if (!mp.empty()) files.push_back(mp.string());
  }
}

// Kd, Ks and Ke of the OBJ's MTL files are finite and non-negative, and Ke at most
// bounds::kRadiance. Checked on the text, with its line: tinyobjloader reads "nan" or "inf" as 0
// without a word, and keeps no line numbers.
void check_mtl_colours(const fs::path& obj) {
  std::vector<std::string> libs;
  append_mtllib_files(obj, libs);
  for (const auto& lib : libs) {
    std::ifstream in(lib);
    std::string line, material;
    for (int n = 1; std::getline(in, line); ++n) {
      std::istringstream words(line);
      std::string key;
      words >> key;
      if (key == "newmtl") {
        std::getline(words >> std::ws, material);
        while (!material.empty() && (material.back() == '\r' || material.back() == ' ')) material.pop_back();
        continue;
      }
      if (key != "Kd" && key != "Ks" && key != "Ke") continue;
      const double max = key == "Ke" ? bounds::kRadiance.max : std::numeric_limits<float>::max();
      std::string w;
      while (words >> w) {
        if (w == "spectral" || w == "xyz") break;  // other colour forms of the MTL format: not read as RGB
        char* end = nullptr;
        const double v = std::strtod(w.c_str(), &end);
        // Compared in float: "Ke 1e30" reads as a float slightly above the double 1e30.
        if (end == w.c_str() || *end != '\0' || !std::isfinite(v) || v < 0 || float(v) > float(max))
          throw InputError(fmt::format(
              "{}:{}: material '{}': key '{}': expected finite non-negative numbers{}, got '{}'", lib, n, material, key,
              key == "Ke" ? fmt::format(" at most {:g} ({})", max, bounds::kRadiance.why) : "", w));
      }
    }
  }
}

// The first face line of the OBJ with an index out of range (position, texture coordinate or
// normal: "f v/vt/vn"), as "FILE:LINE: face index N ..."; "" when none is found. Run only after
// an index error, to name its line (tinyobjloader reports none, or the last line of the file).
std::string bad_face_index(const fs::path& path) {
  // Vertex lines of each kind: v, vt, vn (a negative index counts back from the line).
  auto kind_of = [](const std::string& line) -> int {
    if (line.size() > 2 && line[0] == 'v' && (line[1] == ' ' || line[1] == '\t')) return 0;
    if (line.size() > 3 && line[0] == 'v' && line[1] == 't' && (line[2] == ' ' || line[2] == '\t')) return 1;
    if (line.size() > 3 && line[0] == 'v' && line[1] == 'n' && (line[2] == ' ' || line[2] == '\t')) return 2;
    return -1;
  };
  static const char* const kWhat[3] = {"vertices", "texture coordinates", "normals"};
  static const char* const kPart[3] = {"position", "texture coordinate", "normal"};
  std::int64_t total[3] = {0, 0, 0};
  {
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line))
      if (const int k = kind_of(line); k >= 0) ++total[k];
  }
  std::ifstream in(path);
  std::string line;
  std::int64_t so_far[3] = {0, 0, 0};
  for (int n = 1; std::getline(in, line); ++n) {
    if (const int k = kind_of(line); k >= 0) ++so_far[k];
    if (line.size() < 2 || line[0] != 'f' || (line[1] != ' ' && line[1] != '\t')) continue;
    std::istringstream words(line.substr(1));
    std::string w;
    while (words >> w) {
      std::istringstream parts(w);
      std::string part;
      for (int k = 0; k < 3 && std::getline(parts, part, '/'); ++k) {
        if (part.empty()) continue;  // "1//3": no texture coordinate
        const long long idx = std::atoll(part.c_str());
        if (idx == 0 || idx > total[k] || (idx < 0 && -idx > so_far[k]))
          return fmt::format("{}:{}: face index {} ({} {}) is out of range (the file has {} {}{})", path.string(), n, w,
                             kPart[k], part, total[k], kWhat[k],
                             idx < 0 ? fmt::format(", {} before this line", so_far[k]) : "");
      }
    }
  }
  return "";
}

// Positions and normals are finite: "v 1e39 0 0" reads as an infinite float. The line of the
// first one that is not, as "FILE:LINE: ..." (found only after the values showed one).
void check_finite_vertices(const fs::path& path, const tinyobj::attrib_t& attrib) {
  const auto finite = [](const std::vector<tinyobj::real_t>& v) {
    return std::all_of(v.begin(), v.end(), [](tinyobj::real_t x) { return std::isfinite(x); });
  };
  if (finite(attrib.vertices) && finite(attrib.normals)) return;
  std::ifstream in(path);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n) {
    std::istringstream words(line);
    std::string key, w;
    words >> key;
    if (key != "v" && key != "vn") continue;
    for (int k = 0; k < 3 && words >> w; ++k)
      if (!std::isfinite(float(std::strtod(w.c_str(), nullptr))))
        throw InputError(fmt::format("{}:{}: '{}' value '{}' is not a finite float", path.string(), n, key, w));
  }
  throw InputError(fmt::format("'{}': a vertex position or normal is not finite", path.string()));
}

[[noreturn]] void throw_index_error(const fs::path& path, const std::string& fallback) {
  const std::string at = bad_face_index(path);
  throw InputError(at.empty() ? fallback : at);
}

// An MTL material's colours and type (see the top of obj_import.h); the texture is added by
// the caller.
Material mtl_material(const tinyobj::material_t& om, const std::string& stem) {
  Material m;
  m.name = stem + "/" + om.name;
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
  return m;
}

// Scene material indices of an OBJ's materials.
struct MaterialMap {
  std::vector<unsigned> of_obj;  // per OBJ material
  unsigned fallback = 0;         // for faces without one
};

// The OBJ's materials appended to the scene, then the fallback.
MaterialMap import_materials(Scene& scene, const fs::path& path, const std::vector<tinyobj::material_t>& mats) {
  MaterialMap map;
  map.of_obj.resize(mats.size());
  std::map<std::string, int> tex_cache;  // map_Kd / map_d name -> scene texture: each file read once
  // The scene texture of an MTL texture statement (`what`: map_Kd or map_d).
  auto texture = [&](const tinyobj::material_t& om, const std::string& name, const char* what, bool linear = false) {
    if (auto it = tex_cache.find(name); it != tex_cache.end()) return it->second;
    fs::path tp = find_file_ignoring_case(path.parent_path(), name);
    if (tp.empty())
      throw InputError(fmt::format("'{}': material '{}': texture file '{}' ({}) not found in '{}'", path.string(),
                                   om.name, name, what, path.parent_path().string()));
    scene.files.push_back(tp.string());
    const int index = int(scene.textures.size());
    scene.textures.push_back(load_image_texture(tp.string(), linear));
    return tex_cache[name] = index;
  };
  for (std::size_t i = 0; i < mats.size(); ++i) {
    const auto& om = mats[i];
    Material m = mtl_material(om, path.stem().string());
    if (!om.diffuse_texname.empty()) {
      m.texture = texture(om, om.diffuse_texname, "map_Kd");
      // map_Kd replaces Kd in most exporters' intent when Kd is black.
      if (max_component(m.albedo) <= 0) m.albedo = Vec3(1.0f);
    }
    // norm: a tangent-space normal map, data (never sRGB-decoded). Bump (height) maps are not read.
    if (!om.normal_texname.empty()) {
      m.normal_map = texture(om, om.normal_texname, "norm", true);
      if (const std::string why = scene.textures[std::size_t(m.normal_map)]->data_problem(3); !why.empty())
        throw InputError(fmt::format("'{}': material '{}': norm: {}", path.string(), om.name, why));
    }
    // map_d: the cut-out mask (foliage); its grey value or alpha is the coverage.
    if (!om.alpha_texname.empty()) {
      m.opacity = texture(om, om.alpha_texname, "map_d");
      if (const std::string why = scene.textures[std::size_t(m.opacity)]->opacity_problem(); !why.empty())
        throw InputError(fmt::format("'{}': material '{}': map_d: {}", path.string(), om.name, why));
    }
    map.of_obj[i] = unsigned(scene.materials.size());
    scene.materials.push_back(m);
  }
  map.fallback = unsigned(scene.materials.size());
  Material fallback;
  fallback.name = path.stem().string() + "/(no material)";
  scene.materials.push_back(fallback);
  return map;
}

// Every triangle of the file, transformed, with its scene material.
Mesh obj_triangles(const tinyobj::ObjReader& reader, const fs::path& path, const Transform& x,
                   const MaterialMap& mat_map, std::optional<unsigned> material) {
  const auto& attrib = reader.GetAttrib();
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
          throw_index_error(path,
                            fmt::format("'{}': face index out of range in shape '{}'", path.string(), shape.name));
        p[k] = x.point(Vec3(attrib.vertices[3 * ix.vertex_index], attrib.vertices[3 * ix.vertex_index + 1],
                            attrib.vertices[3 * ix.vertex_index + 2]));
        // A normal or texture coordinate index that is given must exist (tinyobjloader passes it on).
        if ((ix.normal_index >= 0 && std::size_t(3 * ix.normal_index + 2) >= attrib.normals.size()) ||
            (ix.texcoord_index >= 0 && std::size_t(2 * ix.texcoord_index + 1) >= attrib.texcoords.size()))
          throw_index_error(path, fmt::format("'{}': a normal or texture coordinate index is out of range in shape '{}'",
                                              path.string(), shape.name));
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
      unsigned mat = material                                                  ? *material
                     : (mid >= 0 && std::size_t(mid) < mat_map.of_obj.size()) ? mat_map.of_obj[mid]
                                                                               : mat_map.fallback;
      mesh.material.push_back(mat);
    }
  }
  return mesh;
}

}  // namespace

fs::path find_file_ignoring_case(const fs::path& dir, std::string name) {
  std::replace(name.begin(), name.end(), '\\', '/');
  fs::path exact = dir / name;
  // The error_code forms throughout: a name the system refuses (too long) is a file not found,
  // not a std::filesystem_error escaping the loader (found by fuzz/scene_fuzz.cpp).
  std::error_code ec;
  if (fs::exists(exact, ec)) return exact;
  fs::path folder = exact.parent_path();
  std::string want = exact.filename().string();
  auto lower = [](std::string s) {
    for (auto& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
  };
  want = lower(want);
  if (fs::is_directory(folder, ec))
    for (const auto& e : fs::directory_iterator(folder, ec))
      if (lower(e.path().filename().string()) == want) return e.path();
  return {};
}

void import_obj(Scene& scene, const fs::path& path, const Transform& x, std::optional<unsigned> material) {
  tinyobj::ObjReaderConfig cfg;
  cfg.triangulate = true;
  cfg.vertex_color = false;
  cfg.mtl_search_path = path.parent_path().string();
  require_regular_file(path.string(), "OBJ import", "OBJ file");
  tinyobj::ObjReader reader;
  if (!reader.ParseFromFile(path.string(), cfg))
    throw InputError(fmt::format("'{}': cannot read OBJ: {}", path.string(), reader.Error()));
  // tinyobjloader drops a quad with an out-of-range index with only a warning.
  if (reader.Warning().find("Face with invalid vertex index") != std::string::npos ||
      reader.Warning().find("Vertex indices out of bounds") != std::string::npos)
    throw_index_error(path, fmt::format("'{}': face index out of range: {}", path.string(), reader.Warning()));
  check_mtl_colours(path);
  scene.files.push_back(path.string());
  append_mtllib_files(path, scene.files);
  check_finite_vertices(path, reader.GetAttrib());
  const MaterialMap mat_map = import_materials(scene, path, reader.GetMaterials());
  Mesh mesh = obj_triangles(reader, path, x, mat_map, material);
  if (mesh.positions.empty()) throw InputError(fmt::format("'{}': the OBJ file has no triangles", path.string()));
  scene.meshes.push_back(std::move(mesh));
}

}  // namespace dnb::rt
