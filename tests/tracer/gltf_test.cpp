// glTF 2.0 scenes (tracer/gltf_import.h): a small room written as glTF renders as the same room
// written as TOML (within the seeds' noise); the material, transform, camera, light and texture
// mappings; the warnings for what is left out; and one malformed file per failure kind, each
// refused naming the file and the JSON pointer. The tests write their own files: text .gltf with
// base64-embedded buffers, a .glb, and external .bin and image files.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>
#include <nlohmann/json.hpp>

#include "core/errors.h"
#include "test_util.h"
#include "tracer/gltf_export.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "frame_checks.h"
#include "gltf_builder.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

using json = nlohmann::json;
using test::base64;
using test::Gltf;
using test::kQuad;
using test::quad_positions;
using test::read_bytes;
using test::write_checker_png;
using rt::MaterialType;
using rt::Vec3;

constexpr double kPi = 3.14159265358979323846;

// ---- The same room in glTF and in TOML ----
//
// A floor with a checker texture (embedded PNG) and a back wall of grey plastic (glTF's
// non-metal, roughness 0.5), a rough gold metal cube turned 30 degrees about y by its node's
// quaternion and scaled by its node, and a ceiling lamp (emissiveFactor x
// KHR_materials_emissive_strength), seen by the glTF's camera. The TOML says the same with its
// own keys: plastic alpha 0.25 = 0.5^2, conductor schlick alpha 0.09 = 0.3^2, the lamp a black
// rough plastic of emission 8.
const float kFloor[12] = {-2, 0, 2, 2, 0, 2, 2, 0, -2, -2, 0, -2};
const float kWall[12] = {-2, 0, -2, 2, 0, -2, 2, 3, -2, -2, 3, -2};
const float kLamp[12] = {-0.5f, 2.5f, -0.5f, 0.5f, 2.5f, -0.5f, 0.5f, 2.5f, 0.5f, -0.5f, 2.5f, 0.5f};

Gltf room(const std::string& png_bytes) {
  Gltf g;
  g.doc["images"] = {{{"uri", "data:image/png;base64," + base64(png_bytes)}}};
  g.doc["textures"] = {{{"source", 0}}};
  const int floor = g.material({{"pbrMetallicRoughness",
                                 {{"baseColorFactor", {0.8, 0.8, 0.8, 1}}, {"baseColorTexture", {{"index", 0}}},
                                  {"metallicFactor", 0}, {"roughnessFactor", 0.5}}}});
  const int grey = g.material({{"pbrMetallicRoughness", {{"baseColorFactor", {0.6, 0.6, 0.6, 1}}, {"metallicFactor", 0}, {"roughnessFactor", 0.5}}}});
  const int gold = g.material({{"pbrMetallicRoughness", {{"baseColorFactor", {0.9, 0.7, 0.3, 1}}, {"metallicFactor", 1}, {"roughnessFactor", 0.3}}}});
  const int lamp = g.material({{"pbrMetallicRoughness", {{"baseColorFactor", {0, 0, 0, 1}}, {"metallicFactor", 0}, {"roughnessFactor", 1}}},
                               {"emissiveFactor", {1, 1, 1}},
                               {"extensions", {{"KHR_materials_emissive_strength", {{"emissiveStrength", 8}}}}}});
  g.doc["extensionsUsed"] = {"KHR_materials_emissive_strength"};
  // glTF's v runs down the image: (u, 1 - v) of the TOML quad's (0,0) (1,0) (1,1) (0,1).
  g.mesh(quad_positions(kFloor), kQuad, floor, {0, 1, 1, 1, 1, 0, 0, 0});
  g.mesh(quad_positions(kWall), kQuad, grey);
  g.mesh(quad_positions(kLamp), kQuad, lamp);
  // A unit cube about the origin; the node scales it by 0.6, turns it 30 degrees about y and
  // lifts it onto the floor.
  std::vector<float> cube;
  std::vector<std::uint32_t> idx;
  const int faces[6][4][3] = {{{-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}},     {{1, -1, -1}, {-1, -1, -1}, {-1, 1, -1}, {1, 1, -1}},
                              {{1, -1, 1}, {1, -1, -1}, {1, 1, -1}, {1, 1, 1}},     {{-1, -1, -1}, {-1, -1, 1}, {-1, 1, 1}, {-1, 1, -1}},
                              {{-1, 1, 1}, {1, 1, 1}, {1, 1, -1}, {-1, 1, -1}},     {{-1, -1, -1}, {1, -1, -1}, {1, -1, 1}, {-1, -1, 1}}};
  for (int f = 0; f < 6; ++f) {
    const auto base = std::uint32_t(cube.size() / 3);
    for (int k = 0; k < 4; ++k)
      for (int c = 0; c < 3; ++c) cube.push_back(0.5f * float(faces[f][k][c]));
    for (std::uint32_t i : kQuad) idx.push_back(base + i);
  }
  const double h = 15 * kPi / 180;
  g.mesh(cube, idx, gold, {}, {{"translation", {0.3, 0.3, -0.4}}, {"rotation", {0, std::sin(h), 0, std::cos(h)}}, {"scale", {0.6, 0.6, 0.6}}});
  g.doc["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 40 * kPi / 180}, {"znear", 0.01}}}}};
  g.root({{"camera", 0}, {"translation", {0, 1.2, 4}}});
  return g;
}

std::string room_toml(const std::string& png) {
  auto list = [](const float (&p)[12]) {
    std::string s;
    for (int i = 0; i < 12; ++i) s += (i ? ", " : "") + std::to_string(p[i]);
    return s;
  };
  return "[camera]\neye = [0, 1.2, 4]\nlook_at = [0, 1.2, 3]\nvfov = 40\n"
         "[textures.checker]\ntype = \"image\"\nfile = \"" + png + "\"\n"
         "[materials.floor]\ntype = \"plastic\"\nalbedo = [0.8, 0.8, 0.8]\ntexture = \"checker\"\nroughness = 0.25\n"
         "[materials.grey]\ntype = \"plastic\"\nalbedo = [0.6, 0.6, 0.6]\nroughness = 0.25\n"
         "[materials.gold]\ntype = \"conductor\"\nschlick = true\ntint = [0.9, 0.7, 0.3]\nroughness = 0.09\n"
         "[materials.lamp]\ntype = \"plastic\"\nalbedo = [0, 0, 0]\nroughness = 1\nemission = [8, 8, 8]\n"
         "[[objects]]\ntype = \"quad\"\nmaterial = \"floor\"\nvertices = [" + list(kFloor) + "]\n"
         "[[objects]]\ntype = \"quad\"\nmaterial = \"grey\"\nvertices = [" + list(kWall) + "]\n"
         "[[objects]]\ntype = \"quad\"\nmaterial = \"lamp\"\nvertices = [" + list(kLamp) + "]\n"
         "[[objects]]\ntype = \"box\"\nmaterial = \"gold\"\nsize = [1, 1, 1]\nscale = 0.6\nrotate = [0, 30, 0]\ntranslate = [0.3, 0.3, -0.4]\n";
}

AovFrame render(const Scene& scene, std::uint64_t seed) {
  RenderSettings s;
  s.width = 40;
  s.height = 30;
  s.spp = 64;
  s.seed = seed;
  return render_frame(scene, s);
}

// Two renders of one scene (two seeds, or a scene and its glTF) that differ by noise only.
void expect_same_within_noise(const AovFrame& fa, const AovFrame& fb, const std::string& what) {
  // Per channel, the means of 5 x 5 blocks agree within 5 standard errors of their difference
  // (from the frames' variance of the mean; pixels are independent): 75 tests at 5 sigma, a false
  // alarm about once in 20 000 runs if the noise were normal.
  const Image &ca = fa.layer(layer::kColor), &cb = fb.layer(layer::kColor);
  const Image &va = fa.layer(layer::kVariance), &vb = fb.layer(layer::kVariance);
  const int bw = ca.width() / 5, bh = ca.height() / 5;
  for (int c = 0; c < 3; ++c)
    for (int by = 0; by < 5; ++by)
      for (int bx = 0; bx < 5; ++bx) {
        double d = 0, v = 0;
        for (int y = by * bh; y < by * bh + bh; ++y)
          for (int x = bx * bw; x < bx * bw + bw; ++x) {
            d += double(ca.at(x, y, c)) - cb.at(x, y, c);
            v += double(va.at(x, y, c)) + vb.at(x, y, c);
          }
        EXPECT_LT(std::fabs(d), 5 * std::sqrt(v) + 1e-6) << what << ": block " << bx << "," << by << " channel " << c;
      }
}

TEST(Gltf, ARoomRendersAsTheSameRoomWrittenAsToml) {
  test::TempDir dir;
  const std::string png = write_checker_png(dir);
  const std::string gltf = room(read_bytes(png)).write(dir, "room.gltf");
  const auto a = load_scene(gltf);  // the glTF alone: its camera, its lamp
  const auto b = load_scene(test::write_text(dir.file("room.toml"), room_toml(png)));
  ASSERT_NEAR(a->camera.vfov_degrees, b->camera.vfov_degrees, 1e-4);
  const AovFrame fa = render(*a, 1), fb = render(*b, 2);
  // Different seeds: the two estimates differ by noise only (expect_same_within_noise). The
  // texture, the metal and the lamp make any mapping error (a flipped v, alpha not squared, a
  // turned cube, a lamp facing up) many sigma.
  const Image &ca = fa.layer(layer::kColor), &cb = fb.layer(layer::kColor);
  const Image &va = fa.layer(layer::kVariance), &vb = fb.layer(layer::kVariance);
  for (int c = 0; c < 3; ++c) {
    double ma, sa, mb, sb;
    test::image_mean(ca, va, c, ma, sa);
    test::image_mean(cb, vb, c, mb, sb);
    EXPECT_GT(ma, 0.05) << "the room is lit";
    EXPECT_LT(std::fabs(ma - mb), 5 * std::hypot(sa, sb)) << "channel " << c << ": " << ma << " vs " << mb;
  }
  expect_same_within_noise(fa, fb, "room");
}

// export-gltf then the import: the built-in scenes come back as they were (their exact materials
// from the extras, the textures baked), so both render the same within the seeds' noise.
TEST(Gltf, ExportedBuiltInScenesReadBackAsThemselves) {
  test::TempDir dir;
  for (const char* name : {"cornell-box", "window-room", "bedroom"}) {
    const auto original = load_scene(name);
    const std::string path = export_gltf(*original, {.width = 40, .height = 30}, dir.file(std::string(name) + ".gltf"));
    const auto back = load_scene(path);
    EXPECT_EQ(back->materials.size() >= 1, true);
    EXPECT_NEAR(back->camera.vfov_degrees, original->camera.vfov_degrees, 1e-4) << name;
    EXPECT_EQ(back->sky.enabled, original->sky.enabled) << name;
    EXPECT_EQ(back->sun.enabled, original->sun.enabled) << name;
    expect_same_within_noise(render(*original, 1), render(*back, 2), name);
  }
  // What has no glTF form yet is refused, naming it.
  try {
    export_gltf(*load_scene("still-life"), {}, dir.file("still-life.gltf"));
    ADD_FAILURE() << "a thin lens was exported";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("thin lens"), std::string::npos) << e.what();
  }
}

TEST(Gltf, AGlbAndExternalFilesReadAsTheEmbeddedText) {
  test::TempDir dir;
  const std::string png = write_checker_png(dir);
  Gltf g = room(read_bytes(png));
  const auto embedded = load_scene(g.write(dir, "room.gltf"));
  const auto glb = load_scene(g.write_glb(dir, "room.glb"));
  // External: the buffer as a .bin file and the image as a file beside the glTF, named by URIs
  // (one percent-encoded).
  json d = g.doc;
  std::ofstream(dir.file("room data.bin"), std::ios::binary) << g.bin;
  d["buffers"] = {{{"byteLength", g.bin.size()}, {"uri", "room%20data.bin"}}};
  d["images"] = {{{"uri", "checker.png"}}};
  const auto external = load_scene(test::write_text(dir.file("room-ext.gltf"), d.dump()));
  for (const Scene* s : {glb.get(), external.get()}) {
    ASSERT_EQ(s->meshes.size(), embedded->meshes.size());
    EXPECT_EQ(s->meshes[0].positions.size(), embedded->meshes[0].positions.size());
    for (std::size_t i = 0; i < s->meshes[0].positions.size(); ++i)
      ASSERT_EQ(s->meshes[0].positions[i].y, embedded->meshes[0].positions[i].y);
    EXPECT_EQ(s->textures.size(), embedded->textures.size());
    EXPECT_EQ(s->textures[0]->eval(0.1f, 0.1f).x, embedded->textures[0]->eval(0.1f, 0.1f).x);
  }
  // The content hash reads the external files: changing the .bin changes it.
  const std::string before = external->content_hash;
  std::string changed = g.bin;
  changed[0] ^= 1;
  std::ofstream(dir.file("room data.bin"), std::ios::binary) << changed;
  EXPECT_NE(load_scene(dir.file("room-ext.gltf"))->content_hash, before);
}

// A glTF of one floor quad with `material` (null: none), seen by a camera, with whatever
// `extra` adds to the document.
std::shared_ptr<const Scene> load_quad(const test::TempDir& dir, const json& material, const json& extra = json::object(),
                                       const std::vector<float>& uv = {}) {
  Gltf g;
  const int mi = material.is_null() ? -1 : g.material(material);
  g.mesh(quad_positions(kFloor), kQuad, mi, uv);
  g.doc["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 0.7}, {"znear", 0.01}}}}};
  g.root({{"camera", 0}, {"translation", {0, 2, 4}}});
  g.doc.update(extra, true);
  return load_scene(g.write(dir, "q.gltf"));
}

TEST(Gltf, MaterialsMapOntoTheTracers) {
  test::TempDir dir;
  {
    const auto s = load_quad(dir, {{"pbrMetallicRoughness", {{"baseColorFactor", {0.2, 0.4, 0.6, 1}}, {"metallicFactor", 0}, {"roughnessFactor", 0.4}}}});
    const rt::Material& m = s->materials[0];
    EXPECT_EQ(m.type, MaterialType::kPlastic);
    EXPECT_FLOAT_EQ(m.albedo.y, 0.4f);
    EXPECT_FLOAT_EQ(m.alpha_x, 0.16f);  // GGX alpha = roughness^2
    EXPECT_FLOAT_EQ(m.ior, 1.5f);
    EXPECT_GT(m.base_inner_reflectance, 0.5f);  // set, as the loader sets it for plastic
  }
  {
    const auto s = load_quad(dir, {{"pbrMetallicRoughness", {{"baseColorFactor", {1, 0.8, 0.4, 1}}, {"metallicFactor", 1}, {"roughnessFactor", 0}}}});
    EXPECT_EQ(s->materials[0].type, MaterialType::kConductor);
    EXPECT_TRUE(s->materials[0].schlick);
    EXPECT_FLOAT_EQ(s->materials[0].tint.z, 0.4f);
    EXPECT_EQ(s->materials[0].alpha_x, 0.0f);
  }
  {
    const auto s = load_quad(dir, {{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"roughnessFactor", 0}}},
                                   {"extensions", {{"KHR_materials_transmission", {{"transmissionFactor", 1}}},
                                                   {"KHR_materials_ior", {{"ior", 1.33}}}}}});
    EXPECT_EQ(s->materials[0].type, MaterialType::kDielectric);
    EXPECT_TRUE(s->materials[0].thin);  // no KHR_materials_volume: a thin wall
    EXPECT_FLOAT_EQ(s->materials[0].ior, 1.33f);
  }
  {
    const auto s = load_quad(dir, {{"pbrMetallicRoughness", {{"metallicFactor", 0}, {"roughnessFactor", 0.2}}},
                                   {"extensions", {{"KHR_materials_transmission", {{"transmissionFactor", 1}}},
                                                   {"KHR_materials_volume", {{"thicknessFactor", 1}, {"attenuationDistance", 2},
                                                                             {"attenuationColor", {0.5, 1, 1}}}}}}});
    EXPECT_FALSE(s->materials[0].thin);
    EXPECT_NEAR(s->materials[0].absorption.x, std::log(2.0) / 2, 1e-6);  // Beer: 0.5 left after 2 units
    EXPECT_EQ(s->materials[0].absorption.y, 0.0f);
  }
  {
    // No material: glTF's default, a white rough metal.
    const auto s = load_quad(dir, nullptr);
    EXPECT_EQ(s->materials[0].type, MaterialType::kConductor);
    EXPECT_FLOAT_EQ(s->materials[0].alpha_x, 1.0f);
  }
}

TEST(Gltf, CutOutsRoughnessAndNormalMapsReadTheirTextures) {
  test::TempDir dir;
  // A 2 x 1 RGBA PNG: the left texel opaque, the right transparent; a 2 x 1 metallic-roughness
  // PNG with green 255 and 128; a normal map.
  auto png = [&](const std::string& name, int c, std::vector<unsigned char> px) {
    const std::string p = dir.file(name);
    auto out = OIIO::ImageOutput::create(p);
    out->open(p, OIIO::ImageSpec(2, 1, c, OIIO::TypeDesc::UINT8));
    out->write_image(OIIO::TypeDesc::UINT8, px.data());
    out->close();
    return "data:image/png;base64," + base64(read_bytes(p));
  };
  json extra = {{"images", {{{"uri", png("a.png", 4, {255, 255, 255, 255, 255, 255, 255, 0})}},
                            {{"uri", png("mr.png", 3, {0, 255, 0, 0, 128, 0})}},
                            {{"uri", png("n.png", 3, {128, 128, 255, 128, 128, 255})}}}},
                {"textures", {{{"source", 0}}, {{"source", 1}}, {{"source", 2}}}}};
  const auto s = load_quad(dir,
                           {{"alphaMode", "MASK"},
                            {"normalTexture", {{"index", 2}}},
                            {"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}, {"metallicFactor", 0}, {"roughnessFactor", 0.5},
                                                      {"metallicRoughnessTexture", {{"index", 1}}}}}},
                           extra, {0, 0, 1, 0, 1, 1, 0, 1});
  const rt::Material& m = s->materials[0];
  ASSERT_GE(m.opacity, 0);
  // Texel centres at u = 0.25 and 0.75 (bilinear wraps, so at the centres the texel itself).
  EXPECT_NEAR(s->textures[std::size_t(m.opacity)]->opacity(0.25f, 0.5f), 1.0f, 1e-6);
  EXPECT_NEAR(s->textures[std::size_t(m.opacity)]->opacity(0.75f, 0.5f), 0.0f, 1e-6);
  ASSERT_GE(m.roughness_map, 0);
  // alpha = (0.5 g)^2 = 0.25 g^2: the map is g^2, read as data (128/255, not sRGB-decoded).
  EXPECT_FLOAT_EQ(m.alpha_x, 0.25f);
  EXPECT_NEAR(s->textures[std::size_t(m.roughness_map)]->eval(0.25f, 0.5f).x, 1.0f, 1e-6);
  EXPECT_NEAR(s->textures[std::size_t(m.roughness_map)]->eval(0.75f, 0.5f).x, std::pow(128 / 255.0, 2), 1e-5);
  ASSERT_GE(m.normal_map, 0);
  EXPECT_NEAR(s->textures[std::size_t(m.normal_map)]->eval(0.25f, 0.5f).z, 1.0f, 1e-6);
}

TEST(Gltf, NodeMatricesCamerasAndLightsPlaceWhatTheySay) {
  test::TempDir dir;
  Gltf g;
  // A parent turned 90 degrees about y (matrix) with a translated child holding the quad.
  g.doc["meshes"].push_back({{"primitives", {{{"attributes", {{"POSITION", g.floats(quad_positions(kFloor), "VEC3")}}},
                                              {"indices", g.indices(kQuad)}}}}});
  g.doc["nodes"].push_back({{"mesh", 0}, {"translation", {1, 0, 0}}});
  g.root({{"matrix", {0, 0, -1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 5, 0, 1}}, {"children", {0}}});
  g.doc["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 0.5}, {"znear", 0.01}}}}};
  // The camera at (0, 1, 10) turned 90 degrees about y: looking along -x.
  g.root({{"camera", 0}, {"translation", {0, 1, 10}}, {"rotation", {0, std::sqrt(0.5), 0, std::sqrt(0.5)}}});
  g.doc["extensionsUsed"] = {"KHR_lights_punctual"};
  g.doc["extensions"] = {{"KHR_lights_punctual", {{"lights", {{{"type", "point"}, {"intensity", 3}, {"color", {1, 1, 1}}},
                                                              {{"type", "directional"}, {"intensity", 2}},
                                                              {{"type", "spot"}, {"spot", json::object()}}}}}}};
  g.root({{"translation", {0, 4, 0}}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  g.root({{"rotation", {-std::sqrt(0.5), 0, 0, std::sqrt(0.5)}}, {"extensions", {{"KHR_lights_punctual", {{"light", 1}}}}}});
  g.root({{"extensions", {{"KHR_lights_punctual", {{"light", 2}}}}}});
  const auto s = load_scene(g.write(dir, "n.gltf"));
  // The child's corner (-2, 0, 2) moves by (1, 0, 0) to (-1, 0, 2), then the parent's matrix
  // (columns (0,0,-1), (0,1,0), (1,0,0), translation (0,5,0)) takes it to (2, 5, 1).
  const Vec3 p = s->meshes[0].positions[0];
  EXPECT_NEAR(p.x, 2, 1e-6);
  EXPECT_NEAR(p.y, 5, 1e-6);
  EXPECT_NEAR(p.z, 1, 1e-6);
  EXPECT_NEAR(s->camera.look_at.x - s->camera.eye.x, -1, 1e-6);
  EXPECT_NEAR(s->camera.vfov_degrees, 0.5 * 180 / kPi, 1e-4);
  // The point light: a sphere light at (0, 4, 0) whose radiant intensity pi r^2 L is 3 cd at
  // 683 lm/W (Blender's glTF reading).
  ASSERT_EQ(s->sphere_lights.size(), 1u);
  const rt::SphereLight& l = s->sphere_lights[0];
  EXPECT_NEAR(l.center.y, 4, 1e-6);
  const float L = s->materials[s->meshes[l.mesh].material[0]].emission.x;
  EXPECT_NEAR(kPi * l.radius * l.radius * L, 3.0 / 683, 1e-7);
  // The directional light shines along its node's -z, turned -90 degrees about x: down; the sun
  // is up, with irradiance 2.
  ASSERT_TRUE(s->sun.enabled);
  EXPECT_NEAR(s->sun.direction.y, 1, 1e-6);
  EXPECT_NEAR(s->sun.radiance.x * s->sun.solid_angle(), 2, 1e-4);
}

TEST(Gltf, WhatIsLeftOutIsListedByRender) {
  test::TempDir dir;
  Gltf g;
  g.doc["extensionsUsed"] = {"KHR_lights_punctual", "KHR_materials_clearcoat", "KHR_texture_transform"};
  g.doc["extensions"] = {{"KHR_lights_punctual", {{"lights", {{{"type", "spot"}, {"spot", json::object()}}}}}}};
  const int quad = g.mesh(quad_positions(kFloor), kQuad, -1);
  g.doc["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 0.7}, {"znear", 0.01}}}}};
  g.root({{"camera", 0}, {"translation", {0, 2, 4}}});
  g.root({{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  g.channel(0, quad, "weights", {0, 1}, {0, 1});
  const std::string path = g.write(dir, "w.gltf");
  auto r = test::run_denoisebench("render " + path + " --spp 1 --size 8x6 -o " + dir.file("w.exr"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* said : {"/extensionsUsed/1: extension KHR_materials_clearcoat is not read",
                           "/extensionsUsed/2: extension KHR_texture_transform is not read",
                           "/extensions/KHR_lights_punctual/lights/0: spot lights are left out",
                           "/animations/0/channels/0/target/path: morph target weights are not animated"})
    EXPECT_NE(r.output.find(said), std::string::npos) << said << " in:\n" << r.output;
}

// One malformed file per failure kind: each refused with exit status 2, naming the file and
// where in it (the JSON pointer, or line and column for JSON syntax).
TEST(Gltf, MalformedFilesAreRefusedNamingTheFileAndThePointer) {
  test::TempDir dir;
  Gltf good;
  good.mesh(quad_positions(kFloor), kQuad, -1);
  good.doc["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 0.7}, {"znear", 0.01}}}}};
  good.root({{"camera", 0}, {"translation", {0, 2, 4}}});
  ASSERT_NO_THROW(load_scene(good.write(dir, "good.gltf")));

  struct Case {
    const char* name;
    std::function<std::string(Gltf)> make;  // the file's text
    const char* expected;
  };
  auto edit = [](std::function<void(Gltf&)> f) {
    return [f](Gltf g) {
      f(g);
      return g.text();
    };
  };
  const std::vector<Case> cases = {
      {"syntax", [](Gltf g) { std::string t = g.text(); return t.substr(0, t.size() / 2); }, ": not valid JSON"},
      // A number too large for a double (the fuzzer's find: nlohmann's out_of_range, not a parse error).
      {"overflow", [](Gltf g) { std::string t = g.text(); return t.replace(t.find("\"2.0\""), 5, "0.3e26834"); },
       ": not valid glTF JSON"},
      {"version", edit([](Gltf& g) { g.doc["asset"]["version"] = "1.0"; }), "/asset/version: '1.0': expected a glTF 2.x file"},
      {"missing", edit([](Gltf& g) { g.doc["accessors"][0].erase("count"); }), "/accessors/0/count: missing"},
      {"type", edit([](Gltf& g) { g.doc["accessors"][0]["componentType"] = "float"; }), "/accessors/0/componentType: expected an integer"},
      {"index", edit([](Gltf& g) { g.doc["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 9; }),
       "/meshes/0/primitives/0/attributes/POSITION: accessors 9 does not exist"},
      {"past-end", edit([](Gltf& g) { g.doc["accessors"][0]["count"] = 400; }), "/accessors/0: 400 elements"},
      {"vertex-index", edit([](Gltf& g) { reinterpret_cast<std::uint32_t*>(&g.bin[48])[2] = 7; }),
       "/meshes/0/primitives/0/indices: index 7"},
      {"nan", edit([](Gltf& g) { const float nan = std::nanf(""); std::memcpy(&g.bin[4], &nan, 4); }),
       "/accessors/0: element 0 component 1 is nan"},
      {"required-extension", edit([](Gltf& g) { g.doc["extensionsRequired"] = {"KHR_draco_mesh_compression"}; }),
       "/extensionsRequired/0: the file requires extension KHR_draco_mesh_compression"},
      {"cycle", edit([](Gltf& g) { g.doc["nodes"][0]["children"] = {1}; g.doc["nodes"][1]["children"] = {0}; }),
       "is reached twice"},
      {"quaternion", edit([](Gltf& g) { g.doc["nodes"][1]["rotation"] = {0, 0, 0, 0.5}; }), "/nodes/1/rotation: a quaternion of length 0.5"},
      {"camera", edit([](Gltf& g) { g.doc["cameras"][0]["perspective"].erase("yfov"); }), "/cameras/0/perspective/yfov: missing"},
      {"far-camera", edit([](Gltf& g) { g.doc["nodes"][1]["translation"] = {0, 2, -9e27}; }),
       "/nodes/1: the camera is at (0, 2, -9e+27): expected coordinates within [-1e+06, 1e+06]"},
      {"no-camera", edit([](Gltf& g) { g.doc["nodes"][1].erase("camera"); }), "no perspective camera"},
      {"missing-file", edit([](Gltf& g) { g.doc["images"] = {{{"uri", "nowhere.png"}}}; }), "/images/0/uri: the image file"},
  };
  for (const Case& c : cases) {
    const std::string path = test::write_text(dir.file(std::string(c.name) + ".gltf"), c.make(good));
    try {
      load_scene(path);
      ADD_FAILURE() << c.name << ": accepted";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(path, 0), 0u) << c.name << ": " << what;
      EXPECT_NE(what.find(c.expected), std::string::npos) << c.name << ": " << what;
    }
  }
  // A bad GLB header, and the command line's exit status.
  std::ofstream(dir.file("bad.glb"), std::ios::binary) << std::string("glTF\x01\0\0\0\x14\0\0\0", 12) << std::string(8, '\0');
  EXPECT_THROW(load_scene(dir.file("bad.glb")), InputError);
  auto r = test::run_denoisebench("render " + dir.file("index.gltf") + " --spp 1 --size 8x6 -o " + dir.file("x.exr"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("/meshes/0/primitives/0/attributes/POSITION"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir.file("x.exr")));
}

TEST(Gltf, ASceneTomlPlacesAGltfObjectAndKeepsItsOwnCamera) {
  test::TempDir dir;
  Gltf g;
  g.mesh(quad_positions(kFloor), kQuad, -1);
  g.write(dir, "floor.gltf");
  const auto s = load_scene(test::write_text(
      dir.file("s.toml"), "[camera]\neye = [0, 3, 6]\nlook_at = [0, 0, 0]\n[materials.red]\nalbedo = [0.8, 0.1, 0.1]\n"
                          "[[objects]]\ntype = \"gltf\"\nfile = \"floor.gltf\"\nmaterial = \"red\"\ntranslate = [0, 1, 0]\n"));
  EXPECT_EQ(s->camera.eye.z, 6);
  EXPECT_NEAR(s->meshes[0].positions[0].y, 1, 1e-6);
  EXPECT_EQ(s->materials[s->meshes[0].material[0]].name, "red");
  // Without a [camera], the glTF must have one.
  EXPECT_THROW(load_scene(test::write_text(dir.file("t.toml"), "[[objects]]\ntype = \"gltf\"\nfile = \"floor.gltf\"\n")), InputError);
}

}  // namespace
}  // namespace dnb
