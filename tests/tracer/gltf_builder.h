// glTF files written by the tracer tests (gltf_test.cpp, gltf_animation_test.cpp): a document
// built in the test with its accessors over one buffer, written as text with the buffer
// embedded as a data URI, or as a .glb.
#pragma once

#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>
#include <nlohmann/json.hpp>

#include "test_util.h"
#include "tracer_scenes.h"

namespace dnb::test {

using json = nlohmann::json;

// Data URIs carry base64; OpenImageIO's encoder is the one the exporter uses too.
inline std::string base64(const std::string& in) { return OIIO::Strutil::base64_encode(in); }

inline std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// A glTF document under construction: accessors over one buffer, embedded as a data URI (or
// written beside the file, or into a .glb) by text()/write().
struct Gltf {
  json doc = {{"asset", {{"version", "2.0"}}}, {"scene", 0}, {"scenes", {{{"nodes", json::array()}}}}};
  std::string bin;

  int view(const std::string& bytes) {
    while (bin.size() % 4) bin += '\0';
    doc["bufferViews"].push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes.size()}});
    bin += bytes;
    return int(doc["bufferViews"].size() - 1);
  }
  // An accessor of float elements: SCALAR, VEC2, VEC3 or VEC4.
  int floats(const std::vector<float>& v, const char* type) {
    const std::string t = type;
    const std::size_t n = t == "SCALAR" ? 1 : t == "VEC2" ? 2 : t == "VEC3" ? 3 : 4;
    doc["accessors"].push_back({{"bufferView", view(std::string(reinterpret_cast<const char*>(v.data()), v.size() * 4))},
                                {"componentType", 5126}, {"count", v.size() / n}, {"type", type}});
    return int(doc["accessors"].size() - 1);
  }
  int indices(const std::vector<std::uint32_t>& v) {
    doc["accessors"].push_back({{"bufferView", view(std::string(reinterpret_cast<const char*>(v.data()), v.size() * 4))},
                                {"componentType", 5125}, {"count", v.size()}, {"type", "SCALAR"}});
    return int(doc["accessors"].size() - 1);
  }
  // A mesh of one primitive (positions, optional uvs, indices, material) and a node showing it.
  int mesh(const std::vector<float>& pos, const std::vector<std::uint32_t>& idx, int material,
           const std::vector<float>& uv = {}, json node = json::object()) {
    json prim = {{"attributes", {{"POSITION", floats(pos, "VEC3")}}}, {"indices", indices(idx)}};
    if (material >= 0) prim["material"] = material;
    if (!uv.empty()) prim["attributes"]["TEXCOORD_0"] = floats(uv, "VEC2");
    doc["meshes"].push_back({{"primitives", {prim}}});
    node["mesh"] = doc["meshes"].size() - 1;
    return root(node);
  }
  int root(const json& node) {
    doc["nodes"].push_back(node);
    const int n = int(doc["nodes"].size() - 1);
    doc["scenes"][0]["nodes"].push_back(n);
    return n;
  }
  // A channel of animation `anim` (the next one is created) on `node`'s `path`, with a sampler of
  // key `times` and `values` (one element a key, three for CUBICSPLINE: in-tangent, value,
  // out-tangent). Returns the channel's index.
  int channel(int anim, int node, const std::string& path, const std::vector<float>& times, const std::vector<float>& values,
              const std::string& interpolation = "LINEAR") {
    const char* type = path == "rotation" ? "VEC4" : path == "weights" ? "SCALAR" : "VEC3";
    if (anim == int(doc["animations"].size())) doc["animations"].push_back({{"channels", json::array()}, {"samplers", json::array()}});
    json& a = doc["animations"][std::size_t(anim)];
    a["samplers"].push_back({{"input", floats(times, "SCALAR")}, {"output", floats(values, type)}, {"interpolation", interpolation}});
    a["channels"].push_back({{"sampler", a["samplers"].size() - 1}, {"target", {{"node", node}, {"path", path}}}});
    return int(a["channels"].size() - 1);
  }
  int material(const json& m) {
    doc["materials"].push_back(m);
    return int(doc["materials"].size() - 1);
  }
  std::string text() const {
    json d = doc;
    if (!bin.empty())
      d["buffers"] = {{{"byteLength", bin.size()}, {"uri", "data:application/octet-stream;base64," + base64(bin)}}};
    return d.dump(1);
  }
  std::string write(const test::TempDir& dir, const std::string& name) const { return test::write_text(dir.file(name), text()); }
  std::string write_glb(const test::TempDir& dir, const std::string& name) const {
    json d = doc;
    d["buffers"] = {{{"byteLength", bin.size()}}};
    std::string js = d.dump();
    while (js.size() % 4) js += ' ';
    std::string b = bin;
    while (b.size() % 4) b += '\0';
    auto u32 = [](std::uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
    const std::string out = "glTF" + u32(2) + u32(std::uint32_t(12 + 8 + js.size() + 8 + b.size())) + u32(std::uint32_t(js.size())) +
                            "JSON" + js + u32(std::uint32_t(b.size())) + std::string("BIN\0", 4) + b;
    std::ofstream(dir.file(name), std::ios::binary) << out;
    return dir.file(name);
  }
};

inline std::vector<float> quad_positions(const float (&p)[12]) { return std::vector<float>(p, p + 12); }
inline const std::vector<std::uint32_t> kQuad = {0, 1, 2, 0, 2, 3};

// A 4 x 4 checker PNG (8-bit sRGB texels 200 and 40 alternating) written as DIR/checker.png.
inline std::string write_checker_png(const test::TempDir& dir) {
  // 4 x 4 texels of 8-bit sRGB: 200 and 40 alternating.
  std::vector<unsigned char> px(4 * 4 * 3);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x)
      for (int c = 0; c < 3; ++c) px[std::size_t((y * 4 + x) * 3 + c)] = ((x + y) & 1) ? 40 : (c == 0 ? 220 : 200);
  const std::string path = dir.file("checker.png");
  auto out = OIIO::ImageOutput::create(path);
  out->open(path, OIIO::ImageSpec(4, 4, 3, OIIO::TypeDesc::UINT8));
  out->write_image(OIIO::TypeDesc::UINT8, px.data());
  out->close();
  return path;
}

}  // namespace dnb::test
