// Normal maps and roughness textures: a flat map changes nothing, a tilted one turns the shading
// normal by its angle on either side (and the light a surface receives with it), a roughness
// texture scales GGX's alpha, and the refusals of maps that hold colour rather than data.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include <OpenImageIO/imageio.h>

#include "core/errors.h"
#include "test_util.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

using rt::Vec3;

constexpr double kPi = 3.14159265358979323846;

// A quad of albedo 0.5 in the plane z = 0 facing +z, u along +x and v along +y, seen squarely from
// z = 3, lit by a sun from 30 degrees towards +x (irradiance 2 on a surface facing it); `material`
// adds keys to its material, `textures` adds texture tables.
std::string plane_scene(const std::string& textures, const std::string& material) {
  return "[camera]\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\nvfov = 20\n"
         "[sun]\ndirection = [0.5, 0, 0.8660254037844386]\nirradiance = [2, 2, 2]\n" +
         textures + "\n[materials.m]\nalbedo = [0.5, 0.5, 0.5]\n" + material +
         "\n[[objects]]\ntype = \"quad\"\nmaterial = \"m\"\nvertices = [-2, -2, 0,  2, -2, 0,  2, 2, 0,  -2, 2, 0]\n";
}

// A 1 x 1 normal map of the unit normal tilted by `deg` towards +u, stored as (n + 1) / 2.
std::string tilted_map(const test::TempDir& dir, double deg) {
  const float s = float(std::sin(deg * kPi / 180)), c = float(std::cos(deg * kPi / 180));
  const std::string path = dir.file("normal" + std::to_string(int(deg)) + ".exr");
  test::write_exr(path, 1, 1, {{"R", {0.5f + 0.5f * s}}, {"G", {0.5f}}, {"B", {0.5f + 0.5f * c}}});
  return path;
}

AovFrame render_text(const test::TempDir& dir, const std::string& text, int spp = 4) {
  auto scene = load_scene(test::write_text(dir.file("s.toml"), text));
  RenderSettings s;
  s.width = 16;
  s.height = 16;
  s.spp = spp;
  return render_frame(*scene, s);
}

TEST(NormalMap, AFlatMapChangesNothing) {
  // (0.5, 0.5, 1) is the unperturbed normal exactly: every layer is the same to the bit.
  test::TempDir dir;
  const std::string map = tilted_map(dir, 0);
  const AovFrame plain = render_text(dir, plane_scene("", ""));
  const AovFrame mapped = render_text(dir, plane_scene("[textures.n]\ntype = \"image\"\nfile = \"" + map + "\"", "normal_map = \"n\""));
  for (const char* l : {layer::kColor, layer::kNormal, layer::kDirect}) {
    const Image &a = plain.layer(l), &b = mapped.layer(l);
    for (std::size_t k = 0; k < a.size(); ++k) ASSERT_EQ(a.data()[k], b.data()[k]) << l << " " << k;
  }
}

TEST(NormalMap, ATiltedMapTurnsTheShadingNormalOnEitherSide) {
  test::TempDir dir;
  const std::string text =
      plane_scene("[textures.n]\ntype = \"image\"\nfile = \"" + tilted_map(dir, 30) + "\"", "normal_map = \"n\"");
  auto scene = load_scene(test::write_text(dir.file("s.toml"), text));
  // From the front the normal leans 30 degrees towards +x; from the back it is that normal's
  // opposite (the map is relative to the surface's front, then faces the ray as every shading
  // normal does). float rounding of the map's texels and the frame: 1e-6.
  rt::SurfaceHit hit;
  ASSERT_TRUE(scene->intersect(rt::Ray{Vec3(0.3f, 0.2f, 3), Vec3(0, 0, -1)}, hit));
  EXPECT_NEAR(hit.ns.x, 0.5f, 1e-6f);
  EXPECT_NEAR(hit.ns.y, 0.0f, 1e-6f);
  EXPECT_NEAR(hit.ns.z, 0.8660254f, 1e-6f);
  ASSERT_TRUE(scene->intersect(rt::Ray{Vec3(0.3f, 0.2f, -3), Vec3(0, 0, 1)}, hit));
  EXPECT_NEAR(hit.ns.x, -0.5f, 1e-6f);
  EXPECT_NEAR(hit.ns.z, -0.8660254f, 1e-6f);
  // The sun, 30 degrees off the geometric normal towards +x, now falls along the shading normal:
  // direct light 0.5 E / pi (E = 2), against 0.5 E cos 30 / pi unmapped (a 15% difference). The
  // image means are compared within 1%: a sample's cosine varies by at most 0.24% over the
  // 0.27-degree disc, and about 0.1% of the sun's cone samples round to just outside the disc and
  // count nothing (Scene::sample_light: such a direction is the sky's, black here).
  const double lit = 0.5 * 2 / kPi;
  auto mean = [](const AovFrame& f) {
    double s = 0;
    for (int y = 0; y < 16; ++y)
      for (int x = 0; x < 16; ++x) s += f.layer(layer::kColor).at(x, y, 0);
    return s / 256;
  };
  EXPECT_NEAR(mean(render_text(dir, text, 16)), lit, 1e-2 * lit);
  EXPECT_NEAR(mean(render_text(dir, plane_scene("", ""), 16)), lit * 0.8660254, 1e-2 * lit);
}

TEST(RoughnessTexture, ScalesGgxAlpha) {
  // roughness 0.4 times a texture of 0.5 is roughness 0.2 (0.4f * 0.5f is 0.2f exactly): the
  // same frame to the bit.
  test::TempDir dir;
  test::write_exr(dir.file("half.exr"), 1, 1, {{"Y", {0.5f}}});
  const std::string tex = "[textures.r]\ntype = \"image\"\nfile = \"" + dir.file("half.exr") + "\"";
  auto frame = [&](const std::string& textures, const std::string& material) {
    std::string text = plane_scene(textures, material);
    text.replace(text.find("albedo = [0.5, 0.5, 0.5]"), 24, "type = \"conductor\"\nmetal = \"Cu\"");
    return render_text(dir, text, 8);
  };
  const AovFrame a = frame(tex, "roughness = 0.4\nroughness_texture = \"r\"");
  const AovFrame b = frame("", "roughness = 0.2");
  const AovFrame c = frame("", "roughness = 0.4");
  const Image &fa = a.layer(layer::kColor), &fb = b.layer(layer::kColor), &fc = c.layer(layer::kColor);
  bool differs_from_unscaled = false;
  for (std::size_t k = 0; k < fa.size(); ++k) {
    ASSERT_EQ(fa.data()[k], fb.data()[k]) << k;
    differs_from_unscaled |= fa.data()[k] != fc.data()[k];
  }
  EXPECT_TRUE(differs_from_unscaled);
}

TEST(TextureMaps, MapsOfColourOrTooFewChannelsAreRefusedByName) {
  test::TempDir dir;
  // An 8-bit PNG is sRGB colour unless its texture says linear = true.
  {
    std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(dir.file("n.png"));
    ASSERT_TRUE(out);
    const unsigned char px[3] = {128, 128, 255};
    ASSERT_TRUE(out->open(dir.file("n.png"), OIIO::ImageSpec(1, 1, 3, OIIO::TypeDesc::UINT8)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px));
    out->close();
  }
  const std::string png = "[textures.n]\ntype = \"image\"\nfile = \"" + dir.file("n.png") + "\"";
  test::expect_scene_refused(plane_scene(png, "normal_map = \"n\""), "linear = true");
  test::TempDir ok_dir;
  EXPECT_NO_THROW(load_scene(test::write_text(ok_dir.file("ok.toml"), plane_scene(png + "\nlinear = true", "normal_map = \"n\""))));
  // A normal map needs three channels.
  test::write_exr(dir.file("grey.exr"), 1, 1, {{"Y", {0.5f}}});
  test::expect_scene_refused(plane_scene("[textures.g]\ntype = \"image\"\nfile = \"" + dir.file("grey.exr") + "\"", "normal_map = \"g\""),
                 "1 channel");
  test::expect_scene_refused(plane_scene("", "normal_map = \"missing\""), "normal_map");
  // A roughness texture belongs to a rough hard material.
  const std::string rough = "[textures.r]\ntype = \"checker\"";
  test::expect_scene_refused(plane_scene(rough, "roughness_texture = \"r\""), "roughness_texture");  // diffuse: no such key
  std::string smooth = plane_scene(rough, "roughness_texture = \"r\"");
  smooth.replace(smooth.find("albedo = [0.5, 0.5, 0.5]"), 24, "type = \"conductor\"");
  test::expect_scene_refused(smooth, "scales the roughness");
}

}  // namespace
}  // namespace dnb
