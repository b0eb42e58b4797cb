// glTF 2.0 import (tracer/gltf_import.h). Three steps: the JSON is parsed and checked here with
// nlohmann::json, so that every error can name its JSON pointer (tinygltf's messages name none,
// and it does not check that indices point at something); tinygltf then decodes buffers (data
// URIs, external .bin files, the GLB chunk) and reads image bytes; the scene graph is then walked
// and mapped onto the tracer's scene.
//
// tinygltf's implementation is compiled into this file rather than linked from Debian's
// libtinygltf.so: the fuzzing and sanitizer builds then instrument it too, and images are decoded
// by OpenImageIO (bounded before allocation, tracer/texture.h) instead of its stb copy.
#define TINYGLTF_IMPLEMENTATION
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_USE_CPP14
#include <tiny_gltf.h>

#include "tracer/gltf_import.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "core/bounds.h"
#include "core/errors.h"
#include "tracer/bsdf.h"
#include "tracer/gltf_animation.h"
#include "tracer/texture.h"

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace dnb::rt {
namespace {

// The extensions whose content is read (others in extensionsUsed give a warning; in
// extensionsRequired, an error).
const std::set<std::string> kSupportedExtensions = {
    "KHR_lights_punctual",  "KHR_materials_emissive_strength", "KHR_materials_ior",
    "KHR_materials_transmission", "KHR_materials_volume",      "KHR_mesh_quantization", "KHR_materials_specular"};

constexpr double kBig = 1e30;  // the bound of factors and intensities (bounds::kRadiance)

std::string escape_pointer(const std::string& key) {
  std::string out;
  for (char c : key) {
    if (c == '~') out += "~0";
    else if (c == '/') out += "~1";
    else out += c;
  }
  return out;
}

// Percent-decoding of a relative URI (the glTF names external files by URI).
std::string uri_decode(const std::string& uri) {
  std::string out;
  for (std::size_t i = 0; i < uri.size(); ++i) {
    if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(uri[i + 1]) && std::isxdigit(uri[i + 2])) {
      out += char(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
      i += 2;
    } else {
      out += uri[i];
    }
  }
  return out;
}

bool is_data_uri(const std::string& uri) { return uri.rfind("data:", 0) == 0; }

// ---------------------------------------------------------------------------------------------
// The document check: types, required properties, ranges and indices of everything the import
// reads, each failure "FILE: POINTER: what is wrong (what was expected)".
class DocCheck {
 public:
  DocCheck(const std::string& file, const json& doc, bool binary, const fs::path& dir, std::size_t bin_size,
           std::vector<std::string>& warnings)
      : file_(file), doc_(doc), binary_(binary), dir_(dir), bin_size_(bin_size), warnings_(warnings) {}

  void run() {
    if (!doc_.is_object()) fail("", "expected a JSON object (a glTF 2.0 document)");
    const json& asset = object(doc_, "", "asset", true);
    const std::string version = string(asset, "/asset", "version", true);
    if (version.rfind("2.", 0) != 0) fail("/asset/version", fmt::format("'{}': expected a glTF 2.x file", version));
    extensions();
    buffers();
    buffer_views();
    accessors();
    images_and_textures();
    materials();
    meshes();
    cameras();
    lights();
    nodes();
    scenes();
    animations();
  }

 private:
  [[noreturn]] void fail(const std::string& ptr, const std::string& what) const {
    throw InputError(fmt::format("{}: {}: {}", file_, ptr.empty() ? "/" : ptr, what));
  }
  static std::string at(const std::string& ptr, const std::string& key) { return ptr + "/" + escape_pointer(key); }
  static std::string at(const std::string& ptr, std::size_t i) { return fmt::format("{}/{}", ptr, i); }

  const json* member(const json& o, const char* key) const {
    auto it = o.find(key);
    return it == o.end() ? nullptr : &*it;
  }
  const json& object(const json& o, const std::string& ptr, const char* key, bool required) const {
    static const json empty = json::object();
    const json* v = member(o, key);
    if (!v) {
      if (required) fail(at(ptr, key), "missing (expected an object)");
      return empty;
    }
    if (!v->is_object()) fail(at(ptr, key), fmt::format("expected an object, got {}", v->type_name()));
    return *v;
  }
  std::string string(const json& o, const std::string& ptr, const char* key, bool required) const {
    const json* v = member(o, key);
    if (!v) {
      if (required) fail(at(ptr, key), "missing (expected a string)");
      return {};
    }
    if (!v->is_string()) fail(at(ptr, key), fmt::format("expected a string, got {}", v->type_name()));
    return v->get<std::string>();
  }
  // A top-level array of objects (absent: empty).
  const json& array(const json& o, const std::string& ptr, const char* key, bool of_objects = true) const {
    static const json empty = json::array();
    const json* v = member(o, key);
    if (!v) return empty;
    if (!v->is_array()) fail(at(ptr, key), fmt::format("expected an array, got {}", v->type_name()));
    if (of_objects)
      for (std::size_t i = 0; i < v->size(); ++i)
        if (!(*v)[i].is_object())
          fail(at(at(ptr, key), i), fmt::format("expected an object, got {}", (*v)[i].type_name()));
    return *v;
  }
  std::size_t count(const char* top) const {
    const json* v = member(doc_, top);
    return v && v->is_array() ? v->size() : 0;
  }
  double number(const json& o, const std::string& ptr, const char* key, double lo, double hi, bool required,
                const char* why) const {
    const json* v = member(o, key);
    if (!v) {
      if (required) fail(at(ptr, key), fmt::format("missing (expected a number in [{:g}, {:g}]: {})", lo, hi, why));
      return 0;
    }
    if (!v->is_number()) fail(at(ptr, key), fmt::format("expected a number, got {}", v->type_name()));
    const double d = v->get<double>();
    if (!std::isfinite(d) || d < lo || d > hi)
      fail(at(ptr, key), fmt::format("{:g} is out of range (expected [{:g}, {:g}]: {})", d, lo, hi, why));
    return d;
  }
  std::int64_t integer(const json& o, const std::string& ptr, const char* key, std::int64_t lo, std::int64_t hi,
                       bool required, const char* what) const {
    const json* v = member(o, key);
    if (!v) {
      if (required) fail(at(ptr, key), fmt::format("missing (expected {})", what));
      return -1;
    }
    if (!v->is_number_integer()) fail(at(ptr, key), fmt::format("expected an integer ({}), got {}", what, v->dump()));
    const std::int64_t i = v->get<std::int64_t>();
    if (i < lo || i > hi) fail(at(ptr, key), fmt::format("{} is out of range (expected {})", i, what));
    return i;
  }
  void numbers(const json& o, const std::string& ptr, const char* key, std::size_t n, double lo, double hi,
               const char* why) const {
    const json* v = member(o, key);
    if (!v) return;
    if (!v->is_array() || v->size() != n) fail(at(ptr, key), fmt::format("expected an array of {} numbers", n));
    for (std::size_t i = 0; i < n; ++i) {
      const json& e = (*v)[i];
      const std::string p = at(at(ptr, key), i);
      if (!e.is_number()) fail(p, fmt::format("expected a number, got {}", e.type_name()));
      const double d = e.get<double>();
      if (!std::isfinite(d) || d < lo || d > hi) fail(p, fmt::format("{:g} is out of range (expected [{:g}, {:g}]: {})", d, lo, hi, why));
    }
  }
  // An index into the top-level array `target` (or into `n` items called `what`).
  std::int64_t index(const json& o, const std::string& ptr, const char* key, const char* target, bool required,
                     std::int64_t n = -1) const {
    const json* v = member(o, key);
    if (!v) {
      if (required) fail(at(ptr, key), fmt::format("missing (expected an index into /{})", target));
      return -1;
    }
    if (n < 0) n = std::int64_t(count(target));
    if (!v->is_number_integer())
      fail(at(ptr, key), fmt::format("expected an index into /{}, got {}", target, v->dump()));
    const std::int64_t i = v->get<std::int64_t>();
    if (i < 0 || i >= n)
      fail(at(ptr, key), fmt::format("{} {} does not exist (the file has {})", target, i, n));
    return i;
  }

  void extensions() {
    for (const char* key : {"extensionsUsed", "extensionsRequired"}) {
      const json& list = array(doc_, "", key, false);
      for (std::size_t i = 0; i < list.size(); ++i) {
        if (!list[i].is_string()) fail(at(at("", key), i), "expected an extension name (a string)");
        const std::string name = list[i].get<std::string>();
        if (kSupportedExtensions.count(name)) continue;
        if (std::string(key) == "extensionsRequired")
          fail(at(at("", key), i), fmt::format("the file requires extension {}, which the tracer does not read "
                                               "(supported: {})",
                                               name, fmt::join(kSupportedExtensions, ", ")));
        warnings_.push_back(fmt::format("{}: {}: extension {} is not read: what it adds is left out", file_,
                                        at(at("", key), i), name));
      }
    }
  }

  void buffers() {
    const json& list = array(doc_, "", "buffers");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = at("/buffers", i);
      const std::int64_t length = integer(list[i], p, "byteLength", 1, std::int64_t(1) << 40, true, "a length in bytes, at least 1");
      const std::string uri = string(list[i], p, "uri", false);
      if (uri.empty()) {
        if (!binary_ || i != 0) fail(at(p, "uri"), "missing (only a .glb file's first buffer may have no uri)");
        if (std::uint64_t(length) > bin_size_)
          fail(at(p, "byteLength"), fmt::format("{} bytes, but the GLB's binary chunk has {}", length, bin_size_));
      } else if (!is_data_uri(uri)) {
        external_file(at(p, "uri"), uri, "buffer");
        const auto size = fs::file_size(dir_ / uri_decode(uri));
        if (size < std::uint64_t(length))
          fail(at(p, "byteLength"), fmt::format("{} bytes, but '{}' has {}", length, (dir_ / uri_decode(uri)).string(), size));
      }
    }
  }
  void external_file(const std::string& ptr, const std::string& uri, const char* what) const {
    const fs::path path = dir_ / uri_decode(uri);
    std::error_code ec;
    if (!fs::is_regular_file(path, ec))
      fail(ptr, fmt::format("the {} file '{}' {}", what, path.string(),
                            fs::exists(path, ec) ? "is not a regular file" : "does not exist"));
  }

  void buffer_views() {
    const json& list = array(doc_, "", "bufferViews");
    const json& bufs = array(doc_, "", "buffers");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = at("/bufferViews", i);
      const std::int64_t b = index(list[i], p, "buffer", "buffers", true);
      const std::int64_t length = integer(list[i], p, "byteLength", 1, std::int64_t(1) << 40, true, "a length in bytes, at least 1");
      std::int64_t offset = integer(list[i], p, "byteOffset", 0, std::int64_t(1) << 40, false, "a byte offset");
      offset = std::max<std::int64_t>(offset, 0);
      integer(list[i], p, "byteStride", 4, 252, false, "a stride of 4 to 252 bytes");
      const std::int64_t buffer_length = bufs[std::size_t(b)]["byteLength"].get<std::int64_t>();
      if (offset + length > buffer_length)
        fail(p, fmt::format("bytes {} to {} are past the end of /buffers/{} ({} bytes)", offset, offset + length, b,
                            buffer_length));
    }
  }

  static int components(const std::string& type) {
    static const std::map<std::string, int> n = {{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4},
                                                 {"MAT2", 4},   {"MAT3", 9}, {"MAT4", 16}};
    auto it = n.find(type);
    return it == n.end() ? 0 : it->second;
  }
  static int component_size(std::int64_t t) {
    switch (t) {
      case 5120: case 5121: return 1;
      case 5122: case 5123: return 2;
      case 5125: case 5126: return 4;
      default: return 0;
    }
  }

  void accessors() {
    const json& list = array(doc_, "", "accessors");
    const json& views = array(doc_, "", "bufferViews");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = at("/accessors", i);
      const std::int64_t ct = integer(list[i], p, "componentType", 5120, 5126, true,
                                      "5120, 5121, 5122, 5123, 5125 or 5126 (byte to float)");
      if (component_size(ct) == 0) fail(at(p, "componentType"), fmt::format("{} is not a glTF component type", ct));
      const std::int64_t n = integer(list[i], p, "count", 1, bounds::kMaxTriangles * 3, true, "an element count, at least 1");
      const std::string type = string(list[i], p, "type", true);
      if (components(type) == 0)
        fail(at(p, "type"), fmt::format("'{}': expected SCALAR, VEC2, VEC3, VEC4, MAT2, MAT3 or MAT4", type));
      std::int64_t offset = std::max<std::int64_t>(0, integer(list[i], p, "byteOffset", 0, std::int64_t(1) << 40, false, "a byte offset"));
      const std::int64_t v = index(list[i], p, "bufferView", "bufferViews", false);
      if (v < 0) continue;  // all zeros (or sparse)
      const json& view = views[std::size_t(v)];
      const std::int64_t elem = component_size(ct) * components(type);
      const std::int64_t stride = view.contains("byteStride") ? view["byteStride"].get<std::int64_t>() : elem;
      const std::int64_t need = offset + stride * (n - 1) + elem;
      const std::int64_t have = view["byteLength"].get<std::int64_t>();
      if (need > have)
        fail(p, fmt::format("{} elements of {} bytes (stride {}) from byte {} need {} bytes of /bufferViews/{}, which "
                            "has {}",
                            n, elem, stride, offset, need, v, have));
    }
  }

  void texture_info(const json& o, const std::string& ptr, const char* key) const {
    const json& t = object(o, ptr, key, false);
    if (t.empty()) return;
    index(t, at(ptr, key), "index", "textures", true);
    integer(t, at(ptr, key), "texCoord", 0, 64, false, "a texture coordinate set");
    number(t, at(ptr, key), "scale", -kBig, kBig, false, "a normal map's scale");
  }

  void images_and_textures() {
    const json& images = array(doc_, "", "images");
    for (std::size_t i = 0; i < images.size(); ++i) {
      const std::string p = at("/images", i);
      const std::string uri = string(images[i], p, "uri", false);
      const bool view = images[i].contains("bufferView");
      if (uri.empty() == !view) fail(p, "expected exactly one of uri and bufferView");
      if (view) {
        index(images[i], p, "bufferView", "bufferViews", true);
        string(images[i], p, "mimeType", true);
      } else if (!is_data_uri(uri)) {
        external_file(at(p, "uri"), uri, "image");
      }
    }
    const json& textures = array(doc_, "", "textures");
    for (std::size_t i = 0; i < textures.size(); ++i) {
      index(textures[i], at("/textures", i), "source", "images", false);
      index(textures[i], at("/textures", i), "sampler", "samplers", false);
    }
    array(doc_, "", "samplers");
  }

  void materials() {
    const json& list = array(doc_, "", "materials");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = at("/materials", i);
      const json& m = list[i];
      const json& pbr = object(m, p, "pbrMetallicRoughness", false);
      const std::string pp = at(p, "pbrMetallicRoughness");
      numbers(pbr, pp, "baseColorFactor", 4, 0, 1, "a linear colour and alpha");
      number(pbr, pp, "metallicFactor", 0, 1, false, "glTF's metalness");
      number(pbr, pp, "roughnessFactor", 0, 1, false, "glTF's perceptual roughness");
      texture_info(pbr, pp, "baseColorTexture");
      texture_info(pbr, pp, "metallicRoughnessTexture");
      texture_info(m, p, "normalTexture");
      texture_info(m, p, "occlusionTexture");
      texture_info(m, p, "emissiveTexture");
      numbers(m, p, "emissiveFactor", 3, 0, 1, "glTF's emissive colour; KHR_materials_emissive_strength scales it");
      const std::string mode = string(m, p, "alphaMode", false);
      if (!mode.empty() && mode != "OPAQUE" && mode != "MASK" && mode != "BLEND")
        fail(at(p, "alphaMode"), fmt::format("'{}': expected OPAQUE, MASK or BLEND", mode));
      number(m, p, "alphaCutoff", 0, kBig, false, "an alpha threshold");
      if (m.contains("doubleSided") && !m["doubleSided"].is_boolean()) fail(at(p, "doubleSided"), "expected true or false");
      const json& ext = object(m, p, "extensions", false);
      const std::string pe = at(p, "extensions");
      const json& ior = object(ext, pe, "KHR_materials_ior", false);
      if (!ior.empty()) {
        const double v = number(ior, at(pe, "KHR_materials_ior"), "ior", 0, 10, false, "an index of refraction, 1 to 10");
        if (v != 0 && v < 1) fail(at(at(pe, "KHR_materials_ior"), "ior"), fmt::format("{:g}: an index of refraction is at least 1", v));
      }
      const json& tr = object(ext, pe, "KHR_materials_transmission", false);
      number(tr, at(pe, "KHR_materials_transmission"), "transmissionFactor", 0, 1, false, "a fraction of light transmitted");
      texture_info(tr, at(pe, "KHR_materials_transmission"), "transmissionTexture");
      const json& es = object(ext, pe, "KHR_materials_emissive_strength", false);
      number(es, at(pe, "KHR_materials_emissive_strength"), "emissiveStrength", 0, kBig, false, "a non-negative scale");
      exact_material(m, p);
      const json& spec = object(ext, pe, "KHR_materials_specular", false);
      number(spec, at(pe, "KHR_materials_specular"), "specularFactor", 0, 1, false, "the strength of the specular layer");
      const json& vol = object(ext, pe, "KHR_materials_volume", false);
      const std::string pv = at(pe, "KHR_materials_volume");
      number(vol, pv, "thicknessFactor", 0, kBig, false, "a thickness in the mesh's units");
      number(vol, pv, "attenuationDistance", 1e-30, kBig, false, "a positive distance");
      numbers(vol, pv, "attenuationColor", 3, 0, 1, "a colour left after attenuationDistance");
    }
  }

  // extras.denoisebench: the tracer's own material as export-gltf writes it (tracer/gltf_export.h).
  void exact_material(const json& m, const std::string& p) const {
    const json& extras = object(m, p, "extras", false);
    const json& e = object(extras, at(p, "extras"), "denoisebench", false);
    if (e.empty()) return;
    const std::string pe = at(at(p, "extras"), "denoisebench");
    const std::string type = string(e, pe, "type", true);
    static const std::set<std::string> types = {"diffuse", "mirror", "coated", "conductor", "dielectric", "plastic"};
    if (!types.count(type)) fail(at(pe, "type"), fmt::format("'{}': expected one of {}", type, fmt::join(types, ", ")));
    for (const char* key : {"albedo", "tint", "transmittance"}) numbers(e, pe, key, 3, 0, 1, "a reflectance");
    for (const char* key : {"eta", "k"}) numbers(e, pe, key, 3, 0, 100, "a conductor's complex index");
    numbers(e, pe, "absorption", 3, 0, 1e6, "a Beer coefficient");
    numbers(e, pe, "emission", 3, 0, kBig, "a radiance");
    number(e, pe, "ior", 1, 10, false, "an index of refraction");
    number(e, pe, "alpha", 0, 1, false, "GGX's alpha");
    for (const char* key : {"schlick", "thin", "two_sided"})
      if (e.contains(key) && !e[key].is_boolean()) fail(at(pe, key), "expected true or false");
  }

  void meshes() {
    const json& list = array(doc_, "", "meshes");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = at("/meshes", i);
      const json& prims = array(list[i], p, "primitives");
      if (prims.empty()) fail(at(p, "primitives"), "missing or empty (expected at least one primitive)");
      for (std::size_t k = 0; k < prims.size(); ++k) {
        const std::string pk = at(at(p, "primitives"), k);
        const json& attrs = object(prims[k], pk, "attributes", true);
        for (auto it = attrs.begin(); it != attrs.end(); ++it)
          index(attrs, at(pk, "attributes"), it.key().c_str(), "accessors", true);
        index(prims[k], pk, "indices", "accessors", false);
        index(prims[k], pk, "material", "materials", false);
        integer(prims[k], pk, "mode", 0, 6, false, "a primitive mode, 0 (points) to 6 (triangle fan)");
        const json& targets = array(prims[k], pk, "targets");
        for (std::size_t t = 0; t < targets.size(); ++t)
          for (auto it = targets[t].begin(); it != targets[t].end(); ++it)
            index(targets[t], at(at(pk, "targets"), t), it.key().c_str(), "accessors", true);
      }
    }
  }

  void cameras() {
    const json& list = array(doc_, "", "cameras");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = at("/cameras", i);
      const std::string type = string(list[i], p, "type", true);
      if (type == "perspective") {
        const json& per = object(list[i], p, "perspective", true);
        number(per, at(p, "perspective"), "yfov", 1e-6, 3.12, true, "a vertical field of view in radians, below pi");
        number(per, at(p, "perspective"), "znear", 0, kBig, true, "the near plane's distance");
      } else if (type == "orthographic") {
        object(list[i], p, "orthographic", true);
      } else {
        fail(at(p, "type"), fmt::format("'{}': expected perspective or orthographic", type));
      }
    }
  }

  void lights() {
    const json& ext = object(doc_, "", "extensions", false);
    const json& punctual = object(ext, "/extensions", "KHR_lights_punctual", false);
    const std::string pp = "/extensions/KHR_lights_punctual";
    const json& list = array(punctual, pp, "lights");
    light_count_ = list.size();
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = at(at(pp, "lights"), i);
      const std::string type = string(list[i], p, "type", true);
      if (type != "directional" && type != "point" && type != "spot")
        fail(at(p, "type"), fmt::format("'{}': expected directional, point or spot", type));
      if (type == "spot") object(list[i], p, "spot", true);
      numbers(list[i], p, "color", 3, 0, kBig, "a linear colour");
      number(list[i], p, "intensity", 0, kBig, false, "a non-negative intensity");
    }
  }

  void nodes() {
    const json& list = array(doc_, "", "nodes");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = at("/nodes", i);
      const json& n = list[i];
      index(n, p, "mesh", "meshes", false);
      index(n, p, "camera", "cameras", false);
      index(n, p, "skin", "skins", false);
      const json& children = array(n, p, "children", false);
      for (std::size_t c = 0; c < children.size(); ++c) {
        const std::string pc = at(at(p, "children"), c);
        if (!children[c].is_number_integer() || children[c].get<std::int64_t>() < 0 ||
            children[c].get<std::int64_t>() >= std::int64_t(list.size()))
          fail(pc, fmt::format("{} is not a node index (the file has {} nodes)", children[c].dump(), list.size()));
      }
      numbers(n, p, "matrix", 16, -kBig, kBig, "a column-major 4x4 matrix");
      numbers(n, p, "translation", 3, -kBig, kBig, "a translation");
      numbers(n, p, "rotation", 4, -1, 1, "a unit quaternion x, y, z, w");
      numbers(n, p, "scale", 3, -kBig, kBig, "a scale per axis");
      if (n.contains("matrix") && (n.contains("translation") || n.contains("rotation") || n.contains("scale")))
        fail(at(p, "matrix"), "a node has either a matrix or translation/rotation/scale, not both");
      if (n.contains("rotation")) {
        double q = 0;
        for (const auto& c : n["rotation"]) q += c.get<double>() * c.get<double>();
        if (std::fabs(q - 1) > 1e-3) fail(at(p, "rotation"), fmt::format("a quaternion of length {:g}: expected a unit quaternion", std::sqrt(q)));
      }
      const json& ext = object(n, p, "extensions", false);
      const json& lp = object(ext, at(p, "extensions"), "KHR_lights_punctual", false);
      if (!lp.empty())
        index(lp, at(at(p, "extensions"), "KHR_lights_punctual"), "light", "extensions/KHR_lights_punctual/lights", true,
              std::int64_t(light_count_));
    }
  }

  void scenes() {
    const json& list = array(doc_, "", "scenes");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = at("/scenes", i);
      const json& roots = array(list[i], p, "nodes", false);
      for (std::size_t r = 0; r < roots.size(); ++r)
        if (!roots[r].is_number_integer() || roots[r].get<std::int64_t>() < 0 ||
            roots[r].get<std::int64_t>() >= std::int64_t(count("nodes")))
          fail(at(at(p, "nodes"), r), fmt::format("{} is not a node index (the file has {} nodes)", roots[r].dump(), count("nodes")));
    }
    index(doc_, "", "scene", "scenes", false);
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = at(at("/scenes", i), "extras");
      const json& e = object(object(list[i], at("/scenes", i), "extras", false), p, "denoisebench", false);
      const std::string pe = at(p, "denoisebench");
      numbers(e, pe, "sky", 3, 0, kBig, "a sky radiance");
      const json& g = object(e, pe, "sky_gradient", false);
      for (const char* key : {"zenith", "horizon", "ground"}) numbers(g, at(pe, "sky_gradient"), key, 3, 0, kBig, "a sky radiance");
      numbers(g, at(pe, "sky_gradient"), "up", 3, -1, 1, "a unit direction");
    }
  }

  // Animations (docs/gltf.md, "Animations"): their structure here; the samplers' data (types,
  // counts, rising times) once decoded, by the import.
  void animations() {
    const json& list = array(doc_, "", "animations");
    const json& nodes = array(doc_, "", "nodes");
    for (std::size_t i = 0; i < list.size(); ++i) {
      const std::string p = at("/animations", i);
      const json& a = list[i];
      string(a, p, "name", false);
      const json& samplers = array(a, p, "samplers");
      if (samplers.empty()) fail(at(p, "samplers"), "missing or empty (expected at least one sampler)");
      for (std::size_t s = 0; s < samplers.size(); ++s) {
        const std::string ps = at(at(p, "samplers"), s);
        index(samplers[s], ps, "input", "accessors", true);
        index(samplers[s], ps, "output", "accessors", true);
        const std::string how = string(samplers[s], ps, "interpolation", false);
        if (!how.empty() && how != "LINEAR" && how != "STEP" && how != "CUBICSPLINE")
          fail(at(ps, "interpolation"), fmt::format("'{}': expected LINEAR, STEP or CUBICSPLINE", how));
      }
      const json& channels = array(a, p, "channels");
      if (channels.empty()) fail(at(p, "channels"), "missing or empty (expected at least one channel)");
      std::set<std::pair<std::int64_t, std::string>> targets;
      for (std::size_t c = 0; c < channels.size(); ++c) {
        const std::string pc = at(at(p, "channels"), c);
        index(channels[c], pc, "sampler", (p.substr(1) + "/samplers").c_str(), true, std::int64_t(samplers.size()));
        const json& target = object(channels[c], pc, "target", true);
        const std::string pt = at(pc, "target");
        const std::int64_t node = index(target, pt, "node", "nodes", false);
        const std::string path = string(target, pt, "path", true);
        if (path != "translation" && path != "rotation" && path != "scale") continue;  // weights, extensions: the import warns
        if (node < 0) continue;  // no node: the channel is ignored, as glTF says
        if (!targets.insert({node, path}).second)
          fail(pt, fmt::format("a second channel of the animation targets node {}'s {}", node, path));
        if (nodes[std::size_t(node)].contains("matrix"))
          fail(at(pt, "node"), fmt::format("node {} is animated but has a matrix (an animated node has translation, "
                                           "rotation and scale)",
                                           node));
      }
    }
  }

  const std::string& file_;
  const json& doc_;
  bool binary_;
  fs::path dir_;
  std::size_t bin_size_;
  std::vector<std::string>& warnings_;
  std::size_t light_count_ = 0;
};

// ---------------------------------------------------------------------------------------------
// The file's bytes, split into its JSON text and (for .glb) its binary chunk's size.
struct GltfFile {
  std::string bytes;
  std::string json_text;
  std::size_t bin_size = 0;
  bool binary = false;
};

GltfFile read_gltf_file(const fs::path& path) {
  GltfFile f;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("{}: cannot read the glTF file", path.string()));
  f.bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  f.binary = f.bytes.size() >= 4 && f.bytes.compare(0, 4, "glTF") == 0;
  if (!f.binary) {
    f.json_text = f.bytes;
    return f;
  }
  // GLB: a 12-byte header (magic, version 2, length), then chunks of (length, type, data): JSON
  // first, then optionally BIN.
  auto u32 = [&](std::size_t at) {
    std::uint32_t v = 0;
    std::memcpy(&v, f.bytes.data() + at, 4);
    return v;
  };
  const std::string where = path.string();
  if (f.bytes.size() < 20) throw InputError(fmt::format("{}: a binary glTF shorter than its 20-byte header", where));
  if (u32(4) != 2) throw InputError(fmt::format("{}: binary glTF version {} (expected 2)", where, u32(4)));
  if (u32(8) != f.bytes.size())
    throw InputError(fmt::format("{}: the GLB header says {} bytes, the file has {}", where, u32(8), f.bytes.size()));
  const std::size_t json_len = u32(12);
  if (u32(16) != 0x4E4F534Au || 20 + json_len > f.bytes.size())
    throw InputError(fmt::format("{}: the GLB's first chunk is not a JSON chunk within the file", where));
  f.json_text = f.bytes.substr(20, json_len);
  const std::size_t bin_at = 20 + ((json_len + 3) & ~std::size_t(3));
  if (bin_at + 8 <= f.bytes.size() && u32(bin_at + 4) == 0x004E4942u)
    f.bin_size = std::min<std::size_t>(u32(bin_at), f.bytes.size() - bin_at - 8);
  return f;
}

json parse_json(const std::string& text, const std::string& file, std::size_t base) {
  try {
    return json::parse(text);
  } catch (const json::parse_error& e) {
    // The line and column of the byte the parser stopped at.
    const std::size_t byte = std::min<std::size_t>(e.byte == 0 ? 0 : e.byte - 1, text.size());
    const std::size_t line = 1 + std::size_t(std::count(text.begin(), text.begin() + std::ptrdiff_t(byte), '\n'));
    const std::size_t nl = text.rfind('\n', byte == 0 ? 0 : byte - 1);
    const std::size_t col = byte - (nl == std::string::npos ? 0 : nl + 1) + 1;
    std::string why = e.what();
    if (auto p = why.find("syntax error"); p != std::string::npos) why = why.substr(p);
    throw InputError(fmt::format("{}:{}:{}: not valid JSON{}: {}", file, line, col,
                                 base ? fmt::format(" (the GLB's JSON chunk at byte {})", base) : "", why));
  } catch (const json::exception& e) {
    // A number the parser cannot hold (out_of_range 406: "0.3e26834"), found by fuzzing: bad
    // input too, not a crash.
    throw InputError(fmt::format("{}: not valid glTF JSON{}: {}", file,
                                 base ? fmt::format(" (the GLB's JSON chunk at byte {})", base) : "", e.what()));
  }
}

// tinygltf's image hook: keep the encoded bytes; OpenImageIO decodes them when a material uses
// the image, once per colour or data reading (import_gltf).
bool keep_image_bytes(tinygltf::Image* image, const int, std::string*, std::string*, int, int,
                      const unsigned char* bytes, int size, void*) {
  image->image.assign(bytes, bytes + size);
  image->as_is = true;
  return true;
}

// ---------------------------------------------------------------------------------------------
// Column-major 4x4 matrices (glTF's layout).
using Mat4 = std::array<double, 16>;
constexpr Mat4 kIdentity = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};

Mat4 mul(const Mat4& a, const Mat4& b) {
  Mat4 r{};
  for (int c = 0; c < 4; ++c)
    for (int row = 0; row < 4; ++row) {
      double s = 0;
      for (int k = 0; k < 4; ++k) s += a[k * 4 + row] * b[c * 4 + k];
      r[c * 4 + row] = s;
    }
  return r;
}

// A node's translation, rotation and scale where its animations put them at the import's time
// (each unset where no channel targets it: the node's own).
struct NodePose {
  std::optional<std::array<double, 3>> translation, scale;
  std::optional<std::array<double, 4>> rotation;  // x, y, z, w, unit length
};

Mat4 local_matrix(const tinygltf::Node& n, const NodePose* pose = nullptr) {
  if (n.matrix.size() == 16) {  // never animated (DocCheck::animations)
    Mat4 m;
    std::copy(n.matrix.begin(), n.matrix.end(), m.begin());
    return m;
  }
  std::vector<double> tr = n.translation, rot = n.rotation, sc = n.scale;
  if (pose && pose->translation) tr.assign(pose->translation->begin(), pose->translation->end());
  if (pose && pose->rotation) rot.assign(pose->rotation->begin(), pose->rotation->end());
  if (pose && pose->scale) sc.assign(pose->scale->begin(), pose->scale->end());
  Mat4 t = kIdentity, r = kIdentity, s = kIdentity;
  if (tr.size() == 3) {
    t[12] = tr[0];
    t[13] = tr[1];
    t[14] = tr[2];
  }
  if (rot.size() == 4) {
    double x = rot[0], y = rot[1], z = rot[2], w = rot[3];
    const double len = std::sqrt(x * x + y * y + z * z + w * w);
    x /= len, y /= len, z /= len, w /= len;
    r = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),     0,
         2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),     0,
         2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y), 0,
         0,                       0,                       0,                       1};
  }
  if (sc.size() == 3) {
    s[0] = sc[0];
    s[5] = sc[1];
    s[10] = sc[2];
  }
  return mul(t, mul(r, s));
}

Vec3 apply_point(const Mat4& m, const double p[3]) {
  return Vec3(float(m[0] * p[0] + m[4] * p[1] + m[8] * p[2] + m[12]), float(m[1] * p[0] + m[5] * p[1] + m[9] * p[2] + m[13]),
              float(m[2] * p[0] + m[6] * p[1] + m[10] * p[2] + m[14]));
}
Vec3 apply_dir(const Mat4& m, double x, double y, double z) {
  return Vec3(float(m[0] * x + m[4] * y + m[8] * z), float(m[1] * x + m[5] * y + m[9] * z),
              float(m[2] * x + m[6] * y + m[10] * z));
}
// The cofactor matrix of the upper 3x3 (the inverse transpose times the determinant): it maps
// normals, and keeps their side when the determinant is negative only after the caller's flip.
std::array<double, 9> normal_matrix(const Mat4& m, double& det) {
  const double a = m[0], b = m[4], c = m[8], d = m[1], e = m[5], f = m[9], g = m[2], h = m[6], i = m[10];
  det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
  // Rows of the cofactor matrix, used as n' = C n.
  return {e * i - f * h, -(d * i - f * g), d * h - e * g, -(b * i - c * h), a * i - c * g, -(a * h - b * g),
          b * f - c * e, -(a * f - c * d), a * e - b * d};
}

// ---------------------------------------------------------------------------------------------
// The mapping of a checked, decoded model onto the scene.
class Importer {
 public:
  Importer(Scene& scene, const fs::path& path, const Transform& x, std::optional<unsigned> forced,
           const tinygltf::Model& model, const json& doc, GltfImport& out, double time)
      : scene_(scene), path_(path), file_(path.string()), x_(x), forced_(forced), model_(model), doc_(doc), out_(out),
        time_(time) {}

  void run() {
    std::vector<int> roots;
    int scene = model_.defaultScene >= 0 ? model_.defaultScene : model_.scenes.empty() ? -1 : 0;
    if (scene >= 0) {
      roots = model_.scenes[std::size_t(scene)].nodes;
    } else {
      // No scene: spec-wise nothing to show; the root nodes (those no node has as a child) are
      // what a viewer shows, and they are shown, with a warning.
      std::vector<bool> child(model_.nodes.size());
      for (const auto& n : model_.nodes)
        for (int c : n.children) child[std::size_t(c)] = true;
      for (std::size_t i = 0; i < model_.nodes.size(); ++i)
        if (!child[i]) roots.push_back(int(i));
      warn("/", "the file has no scene: its root nodes are rendered");
    }
    if (scene > 0 && model_.scenes.size() > 1)
      warn("/scene", fmt::format("scene {} of {} is rendered; the others are left out", scene, model_.scenes.size()));
    else if (scene == 0 && model_.scenes.size() > 1)
      warn("/scenes", fmt::format("scene 0 of {} is rendered (no default scene); the others are left out", model_.scenes.size()));
    animate();
    walk(roots, scene >= 0 ? fmt::format("/scenes/{}/nodes", scene) : "/nodes");
    if (scene >= 0) sky(scene);
    if (!model_.skins.empty()) warn("/skins", "skins are not read: skinned meshes are rendered in their bind pose");
    mesh_.name = path_.stem().string();
    if (mesh_.triangles() == 0) throw InputError(fmt::format("{}: the default scene has no triangles", file_));
    if (std::int64_t(mesh_.triangles()) > bounds::kMaxTriangles)
      throw InputError(fmt::format("{}: {} triangles are more than {} in one mesh", file_, mesh_.triangles(), bounds::kMaxTriangles));
    const Vec3 lo = bmin_, hi = bmax_;
    scene_.meshes.push_back(std::move(mesh_));
    lights(length(hi - lo));
  }

 private:
  void warn(const std::string& ptr, const std::string& what) {
    const std::string w = fmt::format("{}: {}: {}", file_, ptr, what);
    if (std::find(out_.warnings.begin(), out_.warnings.end(), w) == out_.warnings.end()) out_.warnings.push_back(w);
  }
  // Once per kind of thing left out, naming its first place.
  void warn_once(const std::string& kind, const std::string& ptr, const std::string& what) {
    if (warned_.insert(kind).second) warn(ptr, what);
  }

  // ---- animations (docs/gltf.md, "Animations") ----
  // All of the file's animations play together from time 0, except that an animation which
  // targets a node property an earlier animation already drives is taken as an alternative clip
  // and left out (with a warning). Each played channel on a node's translation, rotation or
  // scale sets that property at time_ (tracer/gltf_animation.h); weights (morph targets) and
  // unknown paths are left out with a warning. Sets out_.animated, out_.duration, poses_ and
  // moved_by_.
  void animate() {
    std::set<std::pair<int, std::string>> driven;
    for (std::size_t ai = 0; ai < model_.animations.size(); ++ai) {
      const tinygltf::Animation& a = model_.animations[ai];
      const std::string ap = fmt::format("/animations/{}", ai);
      std::vector<std::pair<int, std::string>> mine;
      for (const auto& ch : a.channels)
        if (ch.target_node >= 0 && is_trs(ch.target_path)) mine.emplace_back(ch.target_node, ch.target_path);
      if (auto clash = std::find_if(mine.begin(), mine.end(), [&](const auto& t) { return driven.count(t); }); clash != mine.end()) {
        warn(ap, fmt::format("{} targets node {}'s {}, which an earlier animation drives: taken as an alternative clip and "
                             "left out (the file's animations play together where they target different properties)",
                             animation_name(ai), clash->first, clash->second));
        continue;
      }
      driven.insert(mine.begin(), mine.end());
      for (std::size_t ci = 0; ci < a.channels.size(); ++ci) {
        const tinygltf::AnimationChannel& ch = a.channels[ci];
        const std::string cp = fmt::format("{}/channels/{}", ap, ci);
        if (ch.target_path == "weights") {
          warn_once("anim-weights", cp + "/target/path", "morph target weights are not animated (morph targets are not read)");
          continue;
        }
        if (!is_trs(ch.target_path)) {
          warn_once("anim-path:" + ch.target_path, cp + "/target/path",
                    fmt::format("animation path '{}' is not read", ch.target_path));
          continue;
        }
        if (ch.target_node < 0) continue;  // glTF: a channel without a node is ignored
        const GltfSampler sampler = read_sampler(ai, ci);
        out_.animated = true;
        out_.duration = std::max(out_.duration, sampler.times.back());
        std::vector<double> v = sample_gltf(sampler, time_);
        // Bounded as a node's own values are (DocCheck::nodes): a cubic spline's tangents can
        // carry it far past its keys.
        for (double c : v)
          if (!std::isfinite(c) || std::fabs(c) > kBig)
            throw InputError(fmt::format("{}: {}: {}: the {} at {:g} s has a component {:g} (expected a finite number within "
                                         "[{:g}, {:g}])",
                                         file_, cp, channel_name(ai, ci), ch.target_path, time_, c, -kBig, kBig));
        NodePose& pose = poses_[ch.target_node];
        if (ch.target_path == "translation") {
          pose.translation = std::array<double, 3>{v[0], v[1], v[2]};
        } else if (ch.target_path == "scale") {
          pose.scale = std::array<double, 3>{v[0], v[1], v[2]};
        } else {
          if (!(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3] > 0.5))  // normalised, or all zero
            throw InputError(fmt::format("{}: {}: {}: the rotation at {:g} s is not a quaternion (all its components are 0)",
                                         file_, cp, channel_name(ai, ci), time_));
          pose.rotation = std::array<double, 4>{v[0], v[1], v[2], v[3]};
        }
        moved_by_.emplace(ch.target_node, fmt::format("{} ({})", cp, channel_name(ai, ci)));
      }
    }
  }
  static bool is_trs(const std::string& path) { return path == "translation" || path == "rotation" || path == "scale"; }
  std::string animation_name(std::size_t ai) const {
    const std::string& name = model_.animations[ai].name;
    return name.empty() ? fmt::format("animation {}", ai) : fmt::format("animation '{}'", name);
  }
  std::string channel_name(std::size_t ai, std::size_t ci) const {
    const tinygltf::AnimationChannel& ch = model_.animations[ai].channels[ci];
    return fmt::format("{} channel {}, node {} {}", animation_name(ai), ci, ch.target_node, ch.target_path);
  }

  // Channel ci of animation ai's sampler, its accessors decoded and checked: input times as
  // SCALAR floats, finite, from 0 on, strictly rising; output as VEC3 floats (translation,
  // scale) or VEC4 floats or normalised integers (rotation), one per time (three for
  // CUBICSPLINE: in-tangent, value, out-tangent).
  GltfSampler read_sampler(std::size_t ai, std::size_t ci) {
    const tinygltf::Animation& a = model_.animations[ai];
    const tinygltf::AnimationChannel& ch = a.channels[ci];
    const tinygltf::AnimationSampler& sm = a.samplers[std::size_t(ch.sampler)];
    const std::string where = fmt::format("{}: /animations/{}/channels/{}: {}: sampler {} (/animations/{}/samplers/{})", file_, ai,
                                          ci, channel_name(ai, ci), ch.sampler, ai, ch.sampler);
    GltfSampler s;
    s.rotation = ch.target_path == "rotation";
    s.width = s.rotation ? 4 : 3;
    s.interpolation = sm.interpolation == "STEP"          ? GltfInterpolation::kStep
                      : sm.interpolation == "CUBICSPLINE" ? GltfInterpolation::kCubicSpline
                                                          : GltfInterpolation::kLinear;
    const tinygltf::Accessor& in = model_.accessors[std::size_t(sm.input)];
    const tinygltf::Accessor& out = model_.accessors[std::size_t(sm.output)];
    if (in.type != TINYGLTF_TYPE_SCALAR || in.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
      throw InputError(fmt::format("{}: its input /accessors/{} holds {} of component type {}: key times are SCALAR floats "
                                   "(5126)",
                                   where, sm.input, type_name(in.type), in.componentType));
    const int want = s.rotation ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3;
    const bool float_out = out.componentType == TINYGLTF_COMPONENT_TYPE_FLOAT;
    const bool normalised_out = s.rotation && out.normalized &&
                                (out.componentType == TINYGLTF_COMPONENT_TYPE_BYTE || out.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                                 out.componentType == TINYGLTF_COMPONENT_TYPE_SHORT || out.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
    if (out.type != want || !(float_out || normalised_out))
      throw InputError(fmt::format("{}: its output /accessors/{} holds {} of component type {}{}: a {} is {} floats (5126){}",
                                   where, sm.output, type_name(out.type), out.componentType, out.normalized ? " (normalised)" : "",
                                   ch.target_path, type_name(want), s.rotation ? " or normalised integers" : ""));
    // The accessors' own errors (data past the buffer, a non-finite number), naming the channel too.
    auto floats = [&](int accessor, int n) {
      try {
        return read_floats(accessor, n, fmt::format("/animations/{}/samplers/{}", ai, ch.sampler));
      } catch (const InputError& e) {
        std::string what = e.what();
        if (what.rfind(file_ + ": ", 0) == 0) what = what.substr(file_.size() + 2);
        throw InputError(fmt::format("{}: {}", where, what));
      }
    };
    const std::vector<float> t = floats(sm.input, 1);
    const std::vector<float> v = floats(sm.output, s.width);
    const std::size_t per = s.interpolation == GltfInterpolation::kCubicSpline ? 3 : 1;
    if (v.size() != t.size() * per * std::size_t(s.width))
      throw InputError(fmt::format("{}: its input /accessors/{} has {} key times and its output /accessors/{} {} values "
                                   "(expected {}: {} a key for {})",
                                   where, sm.input, t.size(), sm.output, v.size() / std::size_t(s.width), t.size() * per,
                                   per == 3 ? "in-tangent, value and out-tangent" : "one value", sm.interpolation.empty() ? "LINEAR" : sm.interpolation));
    for (std::size_t k = 0; k < t.size(); ++k) {
      if (k == 0 && t[0] < 0)
        throw InputError(fmt::format("{}: its first key time is {:g} s (/accessors/{} element 0): times start at 0 or later",
                                     where, t[0], sm.input));
      if (k > 0 && !(t[k] > t[k - 1]))
        throw InputError(fmt::format("{}: key times must rise strictly: {:g} s after {:g} s (/accessors/{} elements {} and {})",
                                     where, t[k], t[k - 1], sm.input, k - 1, k));
    }
    s.times.assign(t.begin(), t.end());
    s.values.assign(v.begin(), v.end());
    return s;
  }
  static const char* type_name(int type) {
    switch (type) {
      case TINYGLTF_TYPE_SCALAR: return "SCALAR";
      case TINYGLTF_TYPE_VEC2: return "VEC2";
      case TINYGLTF_TYPE_VEC3: return "VEC3";
      case TINYGLTF_TYPE_VEC4: return "VEC4";
      case TINYGLTF_TYPE_MAT2: return "MAT2";
      case TINYGLTF_TYPE_MAT3: return "MAT3";
      case TINYGLTF_TYPE_MAT4: return "MAT4";
      default: return "elements";
    }
  }

  // Depth first over the node trees, with the world matrix of each node. A node reached twice is
  // refused (glTF's node hierarchy is a set of disjoint trees); that also ends cycles.
  void walk(const std::vector<int>& roots, const std::string& roots_ptr) {
    // `rest`: the world matrix without the animations (the nodes' own transforms); `moved_by`:
    // the channel that moves the node or its nearest animated ancestor (empty: it stays put).
    struct Item {
      int node;
      Mat4 parent, rest;
      std::string ptr, moved_by;
    };
    std::vector<Item> stack;
    for (std::size_t i = roots.size(); i-- > 0;)
      stack.push_back({roots[i], kIdentity, kIdentity, fmt::format("{}/{}", roots_ptr, i), {}});
    std::vector<bool> seen(model_.nodes.size());
    while (!stack.empty()) {
      Item it = std::move(stack.back());
      stack.pop_back();
      if (seen[std::size_t(it.node)])
        throw InputError(fmt::format("{}: {}: node {} is reached twice (a node has one parent, and no node is its own "
                                     "ancestor)",
                                     file_, it.ptr, it.node));
      seen[std::size_t(it.node)] = true;
      const tinygltf::Node& n = model_.nodes[std::size_t(it.node)];
      const std::string np = fmt::format("/nodes/{}", it.node);
      const auto pose = poses_.find(it.node);
      const Mat4 world = mul(it.parent, local_matrix(n, pose == poses_.end() ? nullptr : &pose->second));
      const Mat4 rest = mul(it.rest, local_matrix(n));
      if (auto m = moved_by_.find(it.node); m != moved_by_.end()) it.moved_by = m->second;
      if (n.mesh >= 0) add_mesh(n.mesh, world, rest, np, it.moved_by);
      if (n.camera >= 0) add_camera(n.camera, world, np);
      if (!n.weights.empty()) warn_once("weights", np + "/weights", "morph target weights are not read");
      if (auto e = n.extensions.find("KHR_lights_punctual"); e != n.extensions.end()) {
        const int light = e->second.Get("light").GetNumberAsInt();
        const json& l = doc_["extensions"]["KHR_lights_punctual"]["lights"][std::size_t(light)];
        // Spot lights are left out anyway (lights()); the others are emitters.
        if (!it.moved_by.empty() && l["type"].get<std::string>() != "spot")
          throw InputError(fmt::format("{}: {}/extensions/KHR_lights_punctual: light {} moves with {}: lights do not move "
                                       "(light sampling assumes emitters that stay where they are)",
                                       file_, np, light, it.moved_by));
        light_nodes_.push_back({light, world, np});
      }
      for (std::size_t c = n.children.size(); c-- > 0;)
        stack.push_back({n.children[c], world, rest, fmt::format("{}/children/{}", np, c), it.moved_by});
    }
  }

  // The sky export-gltf keeps in the scene's extras (glTF has none), unless the scene file has one.
  void sky(int scene) {
    const json& e = sub(sub(doc_["scenes"][std::size_t(scene)], "extras"), "denoisebench");
    if (!e.contains("sky") && !e.contains("sky_gradient")) return;
    const std::string p = fmt::format("/scenes/{}/extras/denoisebench", scene);
    if (scene_.sky.enabled) {
      warn(p, "the scene file's sky is kept; the glTF's is left out");
      return;
    }
    auto vec = [](const json& a) { return Vec3(float(a[0].get<double>()), float(a[1].get<double>()), float(a[2].get<double>())); };
    Sky& s = scene_.sky;
    s.enabled = true;
    if (e.contains("sky")) {
      s.color = s.average = vec(e["sky"]);
      return;
    }
    const json& g = e["sky_gradient"];
    s.gradient = true;
    s.zenith = vec(g.value("zenith", json::array({0, 0, 0})));
    s.horizon = vec(g.value("horizon", json::array({0, 0, 0})));
    s.ground = vec(g.value("ground", json::array({0, 0, 0})));
    const Vec3 up = vec(g.value("up", json::array({0, 1, 0})));
    if (!(length(up) > 0)) throw InputError(fmt::format("{}: {}/sky_gradient/up: expected a non-zero direction", file_, p));
    s.up = x_.rotate(normalize(up));
    s.average_gradient();
  }

  void add_camera(int index, const Mat4& world, const std::string& np) {
    const tinygltf::Camera& c = model_.cameras[std::size_t(index)];
    if (out_.camera) return;
    if (c.type != "perspective") {
      warn(fmt::format("/cameras/{}", index), "an orthographic camera is left out (the tracer's camera is perspective)");
      return;
    }
    const double origin[3] = {0, 0, 0};
    const Vec3 eye = apply_point(world, origin);
    const Vec3 fwd = apply_dir(world, 0, 0, -1), up = apply_dir(world, 0, 1, 0);
    if (!(length(fwd) > 0) || !(length(up) > 0) || !(length(cross(fwd, up)) > 0))
      throw InputError(fmt::format("{}: {}: the camera's node matrix collapses its view direction", file_, np));
    Camera cam;
    cam.eye = x_.point(eye);
    // As a scene file's eye is bounded (core/bounds.h); Embree refuses rays from far beyond
    // (an assertion, not an error).
    const float far = float(bounds::kCoordinate.max);
    if (!(std::fabs(cam.eye.x) <= far && std::fabs(cam.eye.y) <= far && std::fabs(cam.eye.z) <= far))
      throw InputError(fmt::format("{}: {}: the camera is at ({:g}, {:g}, {:g}){}: expected coordinates within [{:g}, {:g}] ({})",
                                   file_, np, cam.eye.x, cam.eye.y, cam.eye.z,
                                   time_ > 0 ? fmt::format(" at {:g} s", time_) : std::string(), -far, far, bounds::kCoordinate.why));
    cam.look_at = x_.point(eye + normalize(fwd));
    cam.up = x_.rotate(normalize(up));
    cam.vfov_degrees = float(c.perspective.yfov * 180 / kPi);
    out_.camera = cam;
  }

  // One accessor's elements as floats (normalised integers scaled as glTF says; others as they
  // are), `n` components each; `use` is the pointer of what reads it (for messages).
  std::vector<float> read_floats(int index, int n, const std::string& use) {
    const tinygltf::Accessor& a = model_.accessors[std::size_t(index)];
    const std::string ap = fmt::format("/accessors/{}", index);
    const int comps = tinygltf::GetNumComponentsInType(std::uint32_t(a.type));
    if (comps != n) throw InputError(fmt::format("{}: {}: {} reads {} components per element; {} has {}", file_, use, use, n, ap, comps));
    if (a.sparse.isSparse) throw InputError(fmt::format("{}: {}/sparse: sparse accessors are not supported", file_, ap));
    std::vector<float> out(a.count * std::size_t(n), 0.0f);
    if (a.bufferView < 0) return out;
    const auto [data, stride] = element_bytes(a, ap);
    const int size = tinygltf::GetComponentSizeInBytes(std::uint32_t(a.componentType));
    for (std::size_t e = 0; e < a.count; ++e)
      for (int k = 0; k < n; ++k) {
        const unsigned char* p = data + e * stride + std::size_t(k * size);
        float v = 0;
        switch (a.componentType) {
          case TINYGLTF_COMPONENT_TYPE_FLOAT: std::memcpy(&v, p, 4); break;
          case TINYGLTF_COMPONENT_TYPE_BYTE: v = float(std::int8_t(*p)); if (a.normalized) v = std::max(v / 127.0f, -1.0f); break;
          case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: v = float(*p); if (a.normalized) v /= 255.0f; break;
          case TINYGLTF_COMPONENT_TYPE_SHORT: { std::int16_t s; std::memcpy(&s, p, 2); v = float(s); if (a.normalized) v = std::max(v / 32767.0f, -1.0f); break; }
          case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { std::uint16_t s; std::memcpy(&s, p, 2); v = float(s); if (a.normalized) v /= 65535.0f; break; }
          default: throw InputError(fmt::format("{}: {}/componentType: {} needs bytes, shorts or floats", file_, ap, use));
        }
        if (!std::isfinite(v) || std::fabs(v) > 1e30f)
          throw InputError(fmt::format("{}: {}: element {} component {} is {} (expected a finite number)", file_, ap, e, k, v));
        out[e * std::size_t(n) + std::size_t(k)] = v;
      }
    return out;
  }
  std::vector<std::uint32_t> read_indices(int index, const std::string& use) {
    const tinygltf::Accessor& a = model_.accessors[std::size_t(index)];
    const std::string ap = fmt::format("/accessors/{}", index);
    if (a.type != TINYGLTF_TYPE_SCALAR)
      throw InputError(fmt::format("{}: {}/type: the indices of {} are SCALAR", file_, ap, use));
    if (a.sparse.isSparse) throw InputError(fmt::format("{}: {}/sparse: sparse accessors are not supported", file_, ap));
    std::vector<std::uint32_t> out(a.count, 0);
    if (a.bufferView < 0) return out;
    const auto [data, stride] = element_bytes(a, ap);
    for (std::size_t e = 0; e < a.count; ++e) {
      const unsigned char* p = data + e * stride;
      switch (a.componentType) {
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: out[e] = *p; break;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: { std::uint16_t s; std::memcpy(&s, p, 2); out[e] = s; break; }
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: std::memcpy(&out[e], p, 4); break;
        default:
          throw InputError(fmt::format("{}: {}/componentType: indices are unsigned bytes, shorts or ints (5121, 5123, 5125)", file_, ap));
      }
    }
    return out;
  }
  // The first element's bytes and the stride, within the decoded buffer (checked again here: the
  // document check compared declared lengths, this the bytes tinygltf decoded).
  std::pair<const unsigned char*, std::size_t> element_bytes(const tinygltf::Accessor& a, const std::string& ap) {
    const tinygltf::BufferView& v = model_.bufferViews[std::size_t(a.bufferView)];
    const tinygltf::Buffer& b = model_.buffers[std::size_t(v.buffer)];
    const std::size_t elem = std::size_t(tinygltf::GetComponentSizeInBytes(std::uint32_t(a.componentType)) *
                                         tinygltf::GetNumComponentsInType(std::uint32_t(a.type)));
    const std::size_t stride = v.byteStride ? v.byteStride : elem;
    const std::size_t end = v.byteOffset + a.byteOffset + stride * (a.count - 1) + elem;
    if (end > b.data.size() || end > v.byteOffset + v.byteLength)
      throw InputError(fmt::format("{}: {}: its data ends at byte {} of /buffers/{}, which holds {} bytes", file_, ap, end,
                                   v.buffer, b.data.size()));
    return {b.data.data() + v.byteOffset + a.byteOffset, stride};
  }

  // `rest`: the node's world matrix without animations; `moved_by`: the animation channel that
  // moves it (empty: none). An animated node's triangles are the same in every frame, so that the
  // motion layer finds each one by its index (tracer/render_sequence.cpp): a triangle is left
  // out only when it is degenerate in the mesh itself, and one the animation flattens at this
  // instant stays (it is hit by no ray).
  void add_mesh(int index, const Mat4& world, const Mat4& rest, const std::string& np, const std::string& moved_by) {
    const tinygltf::Mesh& m = model_.meshes[std::size_t(index)];
    const bool animated = !moved_by.empty();
    double det = 0;
    const auto nm = normal_matrix(world, det);
    if (!(std::fabs(det) > 0) && !animated) {
      warn(np, "a node matrix of determinant 0 flattens its mesh: left out");
      return;
    }
    for (std::size_t k = 0; k < m.primitives.size(); ++k) {
      const tinygltf::Primitive& prim = m.primitives[k];
      const std::string pp = fmt::format("/meshes/{}/primitives/{}", index, k);
      if (prim.mode >= 0 && prim.mode < TINYGLTF_MODE_TRIANGLES) {
        warn_once("mode", pp + "/mode", "points and lines are left out (the tracer renders triangles)");
        continue;
      }
      auto pos_it = prim.attributes.find("POSITION");
      if (pos_it == prim.attributes.end()) {
        warn(pp + "/attributes", "a primitive without POSITION is left out (as glTF says)");
        continue;
      }
      for (const auto& [name, acc] : prim.attributes) {
        if (name == "POSITION" || name == "NORMAL" || name == "TEXCOORD_0") continue;
        if (name == "TANGENT")
          warn_once(name, pp + "/attributes/TANGENT",
                    "TANGENT is not read: normal maps use each triangle's frame from its texture coordinates");
        else if (name.rfind("COLOR_", 0) == 0)
          warn_once("COLOR", pp + "/attributes/" + name, "vertex colours are not read");
        else if (name.rfind("TEXCOORD_", 0) == 0)
          warn_once("TEXCOORD", pp + "/attributes/" + name, "texture coordinate sets other than TEXCOORD_0 are not read");
        else if (name.rfind("JOINTS_", 0) == 0 || name.rfind("WEIGHTS_", 0) == 0)
          warn_once("skin", pp + "/attributes/" + name, "skinning is not read: the bind pose is rendered");
        else
          warn_once("attr:" + name, pp + "/attributes/" + escape_pointer(name), fmt::format("attribute {} is not read", name));
      }
      if (!prim.targets.empty()) warn_once("targets", pp + "/targets", "morph targets are not read: the base shape is rendered");
      const std::vector<float> pos = read_floats(pos_it->second, 3, pp + "/attributes/POSITION");
      const std::size_t nv = pos.size() / 3;
      std::vector<float> nor, uv;
      if (auto it = prim.attributes.find("NORMAL"); it != prim.attributes.end()) {
        nor = read_floats(it->second, 3, pp + "/attributes/NORMAL");
        if (nor.size() != pos.size())
          throw InputError(fmt::format("{}: {}/attributes/NORMAL: {} normals for {} positions", file_, pp, nor.size() / 3, nv));
      }
      if (auto it = prim.attributes.find("TEXCOORD_0"); it != prim.attributes.end()) {
        uv = read_floats(it->second, 2, pp + "/attributes/TEXCOORD_0");
        if (uv.size() / 2 != nv)
          throw InputError(fmt::format("{}: {}/attributes/TEXCOORD_0: {} coordinates for {} positions", file_, pp, uv.size() / 2, nv));
      }
      std::vector<std::uint32_t> idx;
      if (prim.indices >= 0) {
        idx = read_indices(prim.indices, pp + "/indices");
        for (std::size_t e = 0; e < idx.size(); ++e)
          if (idx[e] >= nv)
            throw InputError(fmt::format("{}: {}/indices: index {} (element {} of /accessors/{}) is not below the {} "
                                         "vertices of POSITION",
                                         file_, pp, idx[e], e, prim.indices, nv));
      } else {
        idx.resize(nv);
        for (std::size_t e = 0; e < nv; ++e) idx[e] = std::uint32_t(e);
      }
      const std::vector<std::array<std::uint32_t, 3>> tris = triangles(idx, prim.mode < 0 ? TINYGLTF_MODE_TRIANGLES : prim.mode);
      const std::optional<unsigned> mat = material(prim.material);
      if (!mat) continue;  // wholly transparent (alphaMode MASK below the cutoff): nothing to hit
      if (animated && scene_.materials[*mat].is_emitter())
        throw InputError(fmt::format("{}: {}: mesh {} moves with {}, and its material '{}' emits: a moving object cannot "
                                     "emit (light sampling assumes emitters that stay where they are)",
                                     file_, np, index, moved_by, scene_.materials[*mat].name));
      if (std::int64_t(mesh_.triangles() + tris.size()) > bounds::kMaxTriangles)
        throw InputError(fmt::format("{}: {}: more than {} triangles in the file", file_, pp, bounds::kMaxTriangles));
      if (!nor.empty() && mesh_.triangles() > 0 && mesh_.normals.empty()) flat_normals_so_far();
      for (const auto& t : tris) {
        // A mirroring node matrix (negative determinant) reverses the winding: glTF says the
        // front face stays the one the unmirrored mesh had, so two corners are swapped.
        std::array<std::uint32_t, 3> c = det < 0 ? std::array<std::uint32_t, 3>{t[0], t[2], t[1]} : t;
        Vec3 p[3], local[3], at_rest[3];
        for (int j = 0; j < 3; ++j) {
          const double q[3] = {pos[3 * c[j]], pos[3 * c[j] + 1], pos[3 * c[j] + 2]};
          p[j] = x_.point(apply_point(world, q));
          local[j] = Vec3(float(q[0]), float(q[1]), float(q[2]));
          at_rest[j] = animated ? x_.point(apply_point(rest, q)) : p[j];
        }
        const Vec3 ng = cross(p[1] - p[0], p[2] - p[0]);
        if (animated ? !(length(cross(local[1] - local[0], local[2] - local[0])) > 0) : !(length(ng) > 0))
          continue;  // degenerate
        // The extent at rest sizes the point lights' spheres (lights()): the same in every frame.
        for (const Vec3& v : at_rest) {
          bmin_ = vmin(bmin_, v);
          bmax_ = vmax(bmax_, v);
        }
        const Vec3 flat = length(ng) > 0 ? normalize(ng) : Vec3(0, 1, 0);  // flattened by its animation: never hit
        mesh_.positions.insert(mesh_.positions.end(), {p[0], p[1], p[2]});
        if (!nor.empty() || !mesh_.normals.empty()) {
          for (int j = 0; j < 3; ++j) {
            Vec3 n = flat;
            if (!nor.empty()) {
              const double* r = nm.data();
              const double a = nor[3 * c[j]], b = nor[3 * c[j] + 1], d = nor[3 * c[j] + 2];
              // Cofactor times n, signed by the determinant (so a mirror keeps the outside out).
              const double s = det < 0 ? -1 : 1;
              Vec3 w(float(s * (r[0] * a + r[3] * b + r[6] * d)), float(s * (r[1] * a + r[4] * b + r[7] * d)),
                     float(s * (r[2] * a + r[5] * b + r[8] * d)));
              if (length(w) > 0) n = x_.normal(normalize(w));
            }
            mesh_.normals.push_back(n);
          }
        }
        if (!uv.empty() || !mesh_.uvs.empty()) {
          if (mesh_.uvs.size() < 6 * (mesh_.triangles() - 1)) mesh_.uvs.resize(6 * (mesh_.triangles() - 1), 0.0f);
          for (int j = 0; j < 3; ++j) {
            // glTF's v runs down the image; the tracer's (OBJ's) up.
            mesh_.uvs.push_back(uv.empty() ? 0.0f : uv[2 * c[j]]);
            mesh_.uvs.push_back(uv.empty() ? 0.0f : 1.0f - uv[2 * c[j] + 1]);
          }
        }
        mesh_.material.push_back(*mat);
      }
    }
  }
  // Shading normals for the triangles added before the first primitive that has normals.
  void flat_normals_so_far() {
    for (std::size_t t = 0; t < mesh_.triangles(); ++t) {
      const Vec3* p = &mesh_.positions[3 * t];
      const Vec3 ng = cross(p[1] - p[0], p[2] - p[0]);
      const Vec3 n = length(ng) > 0 ? normalize(ng) : Vec3(0, 1, 0);  // flattened by an animation: never hit
      mesh_.normals.insert(mesh_.normals.end(), {n, n, n});
    }
  }

  static std::vector<std::array<std::uint32_t, 3>> triangles(const std::vector<std::uint32_t>& idx, int mode) {
    std::vector<std::array<std::uint32_t, 3>> t;
    if (mode == TINYGLTF_MODE_TRIANGLES) {
      for (std::size_t i = 0; i + 2 < idx.size(); i += 3) t.push_back({idx[i], idx[i + 1], idx[i + 2]});
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      for (std::size_t i = 0; i + 2 < idx.size(); ++i)
        t.push_back(i % 2 ? std::array<std::uint32_t, 3>{idx[i + 1], idx[i], idx[i + 2]}
                          : std::array<std::uint32_t, 3>{idx[i], idx[i + 1], idx[i + 2]});
    } else {  // fan
      for (std::size_t i = 1; i + 1 < idx.size(); ++i) t.push_back({idx[0], idx[i], idx[i + 1]});
    }
    return t;
  }

  // ---- materials ----
  const json& material_json(int index) const {
    static const json empty = json::object();
    if (index < 0) return empty;
    return doc_["materials"][std::size_t(index)];
  }
  static double get(const json& o, const char* key, double def) {
    auto it = o.find(key);
    return it == o.end() ? def : it->get<double>();
  }
  static const json& sub(const json& o, const char* key) {
    static const json empty = json::object();
    auto it = o.find(key);
    return it == o.end() ? empty : *it;
  }

  // The scene material of glTF material `index` (-1: glTF's default material), made on first use;
  // empty when it is wholly transparent.
  std::optional<unsigned> material(int index) {
    if (forced_) return forced_;
    if (auto it = materials_.find(index); it != materials_.end()) return it->second;
    return materials_[index] = make_material(index);
  }

  std::optional<unsigned> make_material(int index) {
    const std::string mp = index < 0 ? "/meshes (no material: glTF's default)" : fmt::format("/materials/{}", index);
    const json& mj = material_json(index);
    const json& pbr = sub(mj, "pbrMetallicRoughness");
    const json& ext = sub(mj, "extensions");
    Material m;
    m.name = fmt::format("{}/{}", path_.stem().string(), index < 0 ? std::string("(default)") : mj.value("name", fmt::format("material{}", index)));
    Vec3 base(1.0f);
    float base_alpha = 1;
    if (auto it = pbr.find("baseColorFactor"); it != pbr.end()) {
      base = Vec3(float((*it)[0].get<double>()), float((*it)[1].get<double>()), float((*it)[2].get<double>()));
      base_alpha = float((*it)[3].get<double>());
    }
    const float metallic = float(get(pbr, "metallicFactor", 1));
    const float roughness = float(get(pbr, "roughnessFactor", 1));
    const json& tr = sub(ext, "KHR_materials_transmission");
    const float transmission = float(get(tr, "transmissionFactor", 0));
    float ior = float(get(sub(ext, "KHR_materials_ior"), "ior", 1.5));
    if (ior == 0) ior = 1.5f;  // KHR_materials_ior: 0 means 1.5 for dielectric layers' purposes here
    const int base_tex = texture(pbr, mp + "/pbrMetallicRoughness/baseColorTexture", false);

    const json& specular = sub(ext, "KHR_materials_specular");
    const double specular_factor = get(specular, "specularFactor", 1);
    if (metallic >= 0.5f) m.type = MaterialType::kConductor;
    else if (transmission >= 0.5f) m.type = MaterialType::kDielectric;
    else if (specular_factor == 0 && !specular.contains("specularTexture")) m.type = MaterialType::kDiffuse;
    else m.type = MaterialType::kPlastic;
    if (m.type == MaterialType::kPlastic && specular_factor != 1)
      warn(mp + "/extensions/KHR_materials_specular",
           "a specular layer of strength other than 0 (none: diffuse) or 1 is rendered at 1");
    if (metallic > 0 && metallic < 1)
      warn(mp + "/pbrMetallicRoughness/metallicFactor",
           fmt::format("metalness {:g} is rendered as {} (the tracer's material is a metal or not)", metallic,
                       metallic >= 0.5f ? "a metal" : "a dielectric"));
    if (transmission > 0 && transmission < 1 && metallic < 0.5f)
      warn(mp + "/extensions/KHR_materials_transmission/transmissionFactor",
           fmt::format("transmission {:g} is rendered as {}", transmission, transmission >= 0.5f ? "glass" : "opaque"));
    if (pbr.contains("metallicRoughnessTexture"))
      warn_once("metal-tex", mp + "/pbrMetallicRoughness/metallicRoughnessTexture",
                "its metalness (blue channel) is not read: metallicFactor decides metal or not per material; its roughness "
                "(green) is");
    if (tr.contains("transmissionTexture"))
      warn_once("trans-tex", mp + "/extensions/KHR_materials_transmission/transmissionTexture",
                "transmission textures are not read: transmissionFactor decides glass or not per material");

    // GGX's alpha is glTF's (perceptual) roughness squared.
    m.alpha_x = m.alpha_y = roughness * roughness < 1e-3f ? 0.0f : roughness * roughness;
    if (m.alpha_x > 0 && pbr.contains("metallicRoughnessTexture")) {
      const int t = texture(pbr, mp + "/pbrMetallicRoughness/metallicRoughnessTexture", true);
      if (t >= 0) {
        scene_.textures.push_back(channel_texture(*scene_.textures[std::size_t(t)], 1, 2));
        m.roughness_map = int(scene_.textures.size() - 1);
      }
    }
    if (m.type == MaterialType::kDiffuse) {
      m.albedo = base;
      m.texture = base_tex;
      m.alpha_x = m.alpha_y = 0;
      m.roughness_map = -1;
    } else if (m.type == MaterialType::kPlastic) {
      m.albedo = base;
      m.texture = base_tex;
      m.ior = std::max(ior, 1.0001f);
      m.base_inner_reflectance = fresnel_diffuse_reflectance(1.0f / m.ior);
    } else {
      // Conductor and dielectric colours are constant in the tracer: a base colour texture is
      // taken at its mean.
      Vec3 tint = base;
      if (base_tex >= 0) {
        tint = tint * texture_mean(*scene_.textures[std::size_t(base_tex)]);
        warn(mp + "/pbrMetallicRoughness/baseColorTexture",
             fmt::format("the tracer's {} colour is constant: the texture is taken at its mean",
                         m.type == MaterialType::kConductor ? "metal" : "glass"));
      }
      if (m.type == MaterialType::kConductor) {
        m.schlick = true;
        m.tint = vmin(tint, Vec3(1.0f));
      } else {
        m.ior = std::max(ior, 1.0001f);
        m.transmittance = vmin(tint, Vec3(1.0f));
        const json& vol = sub(ext, "KHR_materials_volume");
        if (get(vol, "thicknessFactor", 0) > 0) {
          // Beer's law: attenuationColor is what is left after attenuationDistance (world units).
          const double d = get(vol, "attenuationDistance", 0);
          if (d > 0 && vol.contains("attenuationColor"))
            for (int c = 0; c < 3; ++c)
              m.absorption[c] = float(-std::log(std::max(1e-6, vol["attenuationColor"][std::size_t(c)].get<double>())) / d / x_.scale);
        } else if (m.alpha_x == 0) {
          m.thin = true;  // glTF transmission without a volume is a thin wall
        } else {
          warn(mp + "/extensions/KHR_materials_transmission",
               "rough transmission without KHR_materials_volume (a thin wall) is rendered as a solid rough glass");
        }
      }
    }
    if (m.roughness_map >= 0 && m.alpha_x == 0) m.roughness_map = -1;

    if (const int t = texture(mj, mp + "/normalTexture", true); t >= 0) {
      if (const std::string why = scene_.textures[std::size_t(t)]->data_problem(3); !why.empty())
        throw InputError(fmt::format("{}: {}/normalTexture: {}", file_, mp, why));
      m.normal_map = t;
      if (get(sub(mj, "normalTexture"), "scale", 1) != 1)
        warn(mp + "/normalTexture/scale", "a normal map's scale is not read (taken as 1)");
    }
    if (mj.contains("occlusionTexture"))
      warn_once("occlusion", mp + "/occlusionTexture", "occlusion textures are not read: the path tracer finds occlusion itself");

    Vec3 emission(0.0f);
    if (auto it = mj.find("emissiveFactor"); it != mj.end())
      emission = Vec3(float((*it)[0].get<double>()), float((*it)[1].get<double>()), float((*it)[2].get<double>()));
    emission = emission * float(get(sub(ext, "KHR_materials_emissive_strength"), "emissiveStrength", 1));
    if (const int t = texture(mj, mp + "/emissiveTexture", false); t >= 0 && !is_black(emission)) {
      emission = emission * texture_mean(*scene_.textures[std::size_t(t)]);
      warn(mp + "/emissiveTexture", "emission is constant per material in the tracer: the texture is taken at its mean");
    }
    m.emission = emission;
    m.two_sided = mj.value("doubleSided", false);
    exact(sub(sub(mj, "extras"), "denoisebench"), base_tex, m);

    const std::string mode = mj.value("alphaMode", std::string("OPAQUE"));
    if (mode != "OPAQUE") {
      const float cutoff = mode == "MASK" ? float(get(mj, "alphaCutoff", 0.5)) : 0.5f;
      if (mode == "BLEND") warn(mp + "/alphaMode", "BLEND is rendered as a cut-out at alpha 0.5 (the tracer has no partial coverage)");
      const bool tex_alpha = base_tex >= 0 && scene_.textures[std::size_t(base_tex)]->channels() == 4;
      if (tex_alpha) {
        m.opacity = base_tex;
        if (std::fabs(cutoff / std::max(base_alpha, 1e-6f) - 0.5f) > 1e-6f)
          warn(mp + "/alphaCutoff", fmt::format("the cut-out is at texture alpha 0.5, not at {:g}", cutoff / std::max(base_alpha, 1e-6f)));
      } else if (base_alpha < cutoff) {
        warn(mp + "/alphaMode", "wholly transparent (base colour alpha below the cutoff): its triangles are left out");
        return std::nullopt;
      }
    }
    scene_.materials.push_back(m);
    return unsigned(scene_.materials.size() - 1);
  }

  // A material export-gltf wrote: its exact parameters from extras.denoisebench (checked by
  // DocCheck::exact_material) replace the glTF mapping's, so that the tracer's own scenes come back
  // as they were. The base colour texture stays the glTF's.
  static void exact(const json& e, int base_tex, Material& m) {
    if (e.empty()) return;
    auto vec = [&](const char* key, Vec3 def) {
      auto it = e.find(key);
      return it == e.end() ? def : Vec3(float((*it)[0].get<double>()), float((*it)[1].get<double>()), float((*it)[2].get<double>()));
    };
    const std::string type = e["type"].get<std::string>();
    Material x;
    x.name = m.name;
    x.type = type == "diffuse" ? MaterialType::kDiffuse : type == "mirror" ? MaterialType::kMirror
           : type == "coated" ? MaterialType::kCoated : type == "conductor" ? MaterialType::kConductor
           : type == "dielectric" ? MaterialType::kDielectric : MaterialType::kPlastic;
    x.albedo = vec("albedo", x.albedo);
    x.tint = vec("tint", x.tint);
    x.transmittance = vec("transmittance", x.transmittance);
    x.absorption = vec("absorption", x.absorption);
    x.eta_c = vec("eta", x.eta_c);
    x.k_c = vec("k", x.k_c);
    x.emission = vec("emission", Vec3(0.0f));
    x.ior = float(get(e, "ior", 1.5));
    x.alpha_x = x.alpha_y = x.is_hard() ? float(get(e, "alpha", 0)) : 0.0f;
    x.schlick = e.value("schlick", false);
    x.thin = e.value("thin", false);
    x.two_sided = e.value("two_sided", false);
    if (x.type == MaterialType::kPlastic) x.base_inner_reflectance = fresnel_diffuse_reflectance(1.0f / x.ior);
    if (x.type == MaterialType::kDiffuse || x.type == MaterialType::kPlastic || x.type == MaterialType::kCoated)
      x.texture = base_tex;
    x.normal_map = m.normal_map;
    if (x.is_hard() && x.alpha_x > 0) x.roughness_map = m.roughness_map;
    m = x;
  }

  // The scene texture of the texture info `key`'s owner `o` (pointer `ptr` of the info itself), as
  // colour (sRGB-decoded) or data; -1 without one. One image read once per reading.
  int texture(const json& o, const std::string& ptr, bool data) {
    const std::string key = ptr.substr(ptr.rfind('/') + 1);
    auto it = o.find(key);
    if (it == o.end()) return -1;
    const json& info = *it;
    const int ti = info["index"].get<int>();
    if (info.value("texCoord", 0) != 0) warn_once("texcoord", ptr + "/texCoord", "only TEXCOORD_0 is read: textures on other sets use it");
    if (info.contains("extensions") && info["extensions"].contains("KHR_texture_transform"))
      warn_once("tt", ptr + "/extensions/KHR_texture_transform", "KHR_texture_transform is not read: textures are untransformed");
    const tinygltf::Texture& t = model_.textures[std::size_t(ti)];
    if (t.source < 0) {
      warn(fmt::format("/textures/{}", ti), "a texture without a source image (an extension's format) is left out");
      return -1;
    }
    if (t.sampler >= 0) {
      const tinygltf::Sampler& s = model_.samplers[std::size_t(t.sampler)];
      if (s.wrapS != TINYGLTF_TEXTURE_WRAP_REPEAT || s.wrapT != TINYGLTF_TEXTURE_WRAP_REPEAT)
        warn_once("wrap", fmt::format("/samplers/{}", t.sampler), "clamped and mirrored wrapping are rendered as repeat");
    }
    const auto cache_key = std::pair(t.source, data);
    if (auto c = textures_.find(cache_key); c != textures_.end()) return c->second;
    const tinygltf::Image& img = model_.images[std::size_t(t.source)];
    std::string name;
    if (!img.uri.empty() && !is_data_uri(img.uri)) {
      name = (path_.parent_path() / uri_decode(img.uri)).string();
      if (std::find(scene_.files.begin(), scene_.files.end(), name) == scene_.files.end()) scene_.files.push_back(name);
    } else {
      const std::string mime = img.mimeType;
      const char* ext = mime == "image/jpeg" ? "jpg" : mime == "image/png" ? "png" : mime == "image/webp" ? "webp" : "img";
      name = fmt::format("{}#/images/{}.{}", file_, t.source, ext);
    }
    if (img.image.empty()) throw InputError(fmt::format("{}: /images/{}: the image holds no bytes", file_, t.source));
    scene_.textures.push_back(load_image_texture(name, img.image.data(), img.image.size(), data));
    return textures_[cache_key] = int(scene_.textures.size() - 1);
  }

  // ---- lights, after the geometry (a point light's sphere is sized by it) ----
  void lights(float diagonal) {
    const json& list = sub(sub(doc_, "extensions"), "KHR_lights_punctual").value("lights", json::array());
    for (const auto& ln : light_nodes_) {
      const json& l = list[std::size_t(ln.light)];
      const std::string lp = fmt::format("/extensions/KHR_lights_punctual/lights/{}", ln.light);
      Vec3 color(1.0f);
      if (auto it = l.find("color"); it != l.end())
        color = Vec3(float((*it)[0].get<double>()), float((*it)[1].get<double>()), float((*it)[2].get<double>()));
      // Units as Blender's glTF I/O takes them (its default "standard" lighting mode), so that a
      // scene exported from Blender is lit as Blender lit it: a directional light's lux as
      // irradiance (W/m^2), a point light's candela divided by 683 lm/W as radiant intensity.
      const Vec3 power = color * float(get(l, "intensity", 1));
      const std::string type = l["type"].get<std::string>();
      if (type == "spot") {
        warn(lp, "spot lights are left out (the tracer has none)");
        continue;
      }
      if (type == "directional") {
        if (scene_.sun.enabled) {
          warn(lp, "a second sun: left out (the tracer has one)");
          continue;
        }
        const Vec3 toward = apply_dir(ln.world, 0, 0, 1);  // the light shines along the node's -z
        if (!(length(toward) > 0)) throw InputError(fmt::format("{}: {}: the node matrix collapses the light's direction", file_, ln.ptr));
        scene_.sun.enabled = true;
        scene_.sun.direction = x_.rotate(normalize(toward));
        // The sun's own angular radius, or what export-gltf kept in the light's extras.
        const double radius = get(sub(sub(l, "extras"), "denoisebench"), "angular_radius_degrees", 0.27);
        if (!(radius > 0 && radius < 30))
          throw InputError(fmt::format("{}: {}/extras/denoisebench/angular_radius_degrees: expected degrees in (0, 30)", file_, lp));
        scene_.sun.cos_max = std::cos(float(radius) * kPi / 180);
        scene_.sun.radiance = power / scene_.sun.solid_angle();
        continue;
      }
      // A point light of radiant intensity I becomes a sphere of radius r and radiance
      // I / (pi r^2), which has that intensity in every direction; r is 0.5% of the glTF's extent.
      constexpr float kLumensPerWatt = 683;
      const float r = std::max(1e-4f, 0.005f * diagonal);
      const double origin[3] = {0, 0, 0};
      const Vec3 c = x_.point(apply_point(ln.world, origin));
      Material em;
      em.name = fmt::format("{}/light{}", path_.stem().string(), ln.light);
      em.albedo = Vec3(0.0f);
      em.emission = power / (kLumensPerWatt * kPi * r * r);
      if (max_component(em.emission) > bounds::kRadiance.max)
        throw InputError(fmt::format("{}: {}/intensity: a radiance of {:g} on its sphere of radius {:g} is beyond {:g}", file_, lp,
                                     max_component(em.emission), r, bounds::kRadiance.max));
      scene_.materials.push_back(em);
      MeshBuilder b;
      b.mesh.name = em.name;
      build_sphere(b, c, r, 24, Transform{}, 1, 1, unsigned(scene_.materials.size() - 1), false, true);
      scene_.sphere_lights.push_back(SphereLight{unsigned(scene_.meshes.size()), c, r});
      scene_.meshes.push_back(std::move(b.mesh));
      warn(lp, fmt::format("a point light is rendered as a sphere light of radius {:g}", r));
    }
  }

  struct LightNode {
    int light;
    Mat4 world;
    std::string ptr;
  };
  Scene& scene_;
  fs::path path_;
  std::string file_;
  Transform x_;
  std::optional<unsigned> forced_;
  const tinygltf::Model& model_;
  const json& doc_;
  GltfImport& out_;
  Mesh mesh_;
  Vec3 bmin_{1e30f}, bmax_{-1e30f};
  std::map<int, std::optional<unsigned>> materials_;
  std::map<std::pair<int, bool>, int> textures_;
  std::vector<LightNode> light_nodes_;
  std::set<std::string> warned_;
  double time_ = 0;                       // seconds: where the animations are evaluated
  std::map<int, NodePose> poses_;         // per animated node, its animated properties at time_
  std::map<int, std::string> moved_by_;   // per animated node, its first channel (for messages)
};

}  // namespace

bool is_gltf_path(const fs::path& path) {
  std::string e = path.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e == ".gltf" || e == ".glb";
}

GltfImport import_gltf(Scene& scene, const fs::path& path, const Transform& x, std::optional<unsigned> material,
                       double time) {
  const std::string file = path.string();
  GltfFile f = read_gltf_file(path);
  const json doc = parse_json(f.json_text, file, f.binary ? 20 : 0);
  GltfImport out;
  DocCheck(file, doc, f.binary, path.parent_path(), f.bin_size, out.warnings).run();

  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(keep_image_bytes, nullptr);
  tinygltf::Model model;
  std::string err, warn;
  const std::string dir = path.parent_path().string();
  const bool ok = f.binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(f.bytes.data()),
                                                         unsigned(f.bytes.size()), dir)
                           : loader.LoadASCIIFromString(&model, &err, &warn, f.json_text.data(), unsigned(f.json_text.size()), dir);
  if (!ok || !err.empty()) {
    while (!err.empty() && err.back() == '\n') err.pop_back();
    throw InputError(fmt::format("{}: tinygltf could not read it: {}", file, err.empty() ? warn : err));
  }
  scene.files.push_back(file);
  for (const auto& b : model.buffers)
    if (!b.uri.empty() && !is_data_uri(b.uri)) scene.files.push_back((path.parent_path() / uri_decode(b.uri)).string());
  Importer(scene, path, x, material, model, doc, out, time).run();
  return out;
}

}  // namespace dnb::rt
