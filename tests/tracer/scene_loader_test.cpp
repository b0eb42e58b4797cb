// Scene files and OBJ/MTL loading: strict keys, the OBJ edge cases of real scene collections
// (letter case of texture names, negative indices, CRLF, missing normals and uvs), clear errors.
#include <gtest/gtest.h>

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>

#include "core/errors.h"
#include "test_util.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

using rt::Vec3;

std::string error_of(const std::function<void()>& f) { return test::error_of<InputError>(f); }

void write_png(const std::string& path, float r, float g, float b) {
  auto out = OIIO::ImageOutput::create(path);
  ASSERT_TRUE(out);
  OIIO::ImageSpec spec(2, 2, 3, OIIO::TypeDesc::UINT8);
  unsigned char px[12];
  for (int i = 0; i < 4; ++i) {
    px[3 * i] = (unsigned char)(r * 255);
    px[3 * i + 1] = (unsigned char)(g * 255);
    px[3 * i + 2] = (unsigned char)(b * 255);
  }
  ASSERT_TRUE(out->open(path, spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::UINT8, px));
  out->close();
}

// A unit quad in the z = 0 plane facing +z, written with CRLF line endings, negative (relative)
// face indices, no normals and no texture coordinates; its material's texture is named in
// another letter case than the file on disk.
const char* kObj =
    "# test\r\nmtllib quad.mtl\r\nv -1 -1 0\r\nv 1 -1 0\r\nv 1 1 0\r\nv -1 1 0\r\nusemtl red\r\n"
    "f -4 -3 -2 -1\r\n"
    "v -1 -1 -2\r\nv 1 -1 -2\r\nv 1 1 -2\r\nusemtl shiny\r\nf -3 -2 -1\r\n";

std::string obj_scene(const std::string& obj) {
  return "[camera]\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\nvfov = 40\n[[objects]]\ntype = \"obj\"\nfile = \"" + obj +
         "\"\n";
}

TEST(ObjLoader, HandlesCrlfNegativeIndicesMissingNormalsAndTextureCase) {
  test::TempDir dir;
  write_png(dir.file("red_tex.png"), 1, 0, 0);
  test::write_text(dir.file("quad.mtl"),
                   "newmtl red\r\nKd 1 1 1\r\nmap_Kd RED_TEX.PNG\r\n\r\nnewmtl shiny\r\nKd 0 0 0\r\nKs 0.9 0.9 0.9\r\n"
                   "illum 3\r\n");
  test::write_text(dir.file("quad.obj"), kObj);
  auto scene = load_scene(test::write_text(dir.file("s.toml"), obj_scene("quad.obj")));
  EXPECT_EQ(scene->triangle_count(), 3u);
  rt::SurfaceHit hit;
  ASSERT_TRUE(scene->intersect(rt::Ray{Vec3(0.2f, 0.1f, 3), Vec3(0, 0, -1), 1e30f}, hit));
  EXPECT_NEAR(hit.t, 3.0f, 1e-5);
  EXPECT_NEAR(hit.ng.z, 1.0f, 1e-6);  // flat normal from the winding when the file has none
  EXPECT_NEAR(hit.albedo.x, 1.0f, 1e-3);  // the texture was found despite the letter case
  EXPECT_NEAR(hit.albedo.y, 0.0f, 1e-3);
  // illum 3 with a black Kd becomes a tinted mirror.
  ASSERT_TRUE(scene->intersect(rt::Ray{Vec3(0.5f, -0.5f, -1), Vec3(0, 0, -1), 1e30f}, hit));
  EXPECT_EQ(hit.material->type, rt::MaterialType::kMirror);
  EXPECT_NEAR(hit.material->tint.x, 0.9f, 1e-6);
  // The content hash covers the texture: changing it changes the hash.
  std::string h1 = scene_content_hash(*scene);
  write_png(dir.file("red_tex.png"), 0, 1, 0);
  EXPECT_NE(h1, scene_content_hash(*load_scene(dir.file("s.toml"))));
}

TEST(ObjLoader, MissingTextureFileIsNamed) {
  test::TempDir dir;
  test::write_text(dir.file("quad.mtl"), "newmtl red\nKd 1 1 1\nmap_Kd no_such_texture.jpg\nnewmtl shiny\nKd 1 1 1\n");
  test::write_text(dir.file("quad.obj"), kObj);
  std::string msg = error_of([&] { load_scene(test::write_text(dir.file("s.toml"), obj_scene("quad.obj"))); });
  EXPECT_NE(msg.find("no_such_texture.jpg"), std::string::npos) << msg;
  EXPECT_NE(msg.find("quad.obj"), std::string::npos) << msg;
}

TEST(ObjLoader, EmittersAreOneSided) {
  test::TempDir dir;
  test::write_text(dir.file("quad.mtl"), "newmtl red\nKd 0.5 0.5 0.5\nKe 4 3 2\nnewmtl shiny\nKd 1 1 1\n");
  test::write_text(dir.file("quad.obj"), kObj);
  auto scene = load_scene(test::write_text(dir.file("s.toml"), obj_scene("quad.obj")));
  rt::SurfaceHit hit;
  ASSERT_TRUE(scene->intersect(rt::Ray{Vec3(0.2f, 0.1f, 3), Vec3(0, 0, -1), 1e30f}, hit));
  EXPECT_EQ(hit.emitted().x, 4.0f);  // front (counter-clockwise) side
  ASSERT_TRUE(scene->intersect(rt::Ray{Vec3(0.2f, 0.1f, -1), Vec3(0, 0, 1), 1e30f}, hit));
  EXPECT_EQ(hit.emitted().x, 0.0f);  // back side
  EXPECT_TRUE(scene->has_lights());
}

TEST(SceneFile, ImageAndProceduralTexturesAreLookedUp) {
  test::TempDir dir;
  write_png(dir.file("wall.png"), 0.5f, 1.0f, 0.0f);
  std::string text =
      "[camera]\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\n"
      "[textures.img]\ntype = \"image\"\nfile = \"wall.png\"\n"
      "[textures.chk]\ntype = \"checker\"\nscale = 2\ncolor_a = [1, 0, 0]\ncolor_b = [0, 0, 1]\n"
      "[materials.a]\ntexture = \"img\"\nalbedo = [0.5, 0.5, 0.5]\n"
      "[materials.b]\ntexture = \"chk\"\nalbedo = [1, 1, 1]\n"
      "[[objects]]\ntype = \"quad\"\nmaterial = \"a\"\n"
      "vertices = [-1, -1, 0,  1, -1, 0,  1, 1, 0,  -1, 1, 0]\n"
      "[[objects]]\ntype = \"quad\"\nmaterial = \"b\"\n"
      "vertices = [-1, -1, -1,  1, -1, -1,  1, 1, -1,  -1, 1, -1]\n";
  auto scene = load_scene(test::write_text(dir.file("t.toml"), text));
  rt::SurfaceHit hit;
  ASSERT_TRUE(scene->intersect(rt::Ray{Vec3(0.3f, 0.2f, 3), Vec3(0, 0, -1), 1e30f}, hit));
  // 8-bit texels are sRGB-decoded: 128/255 -> 0.2158 linear (0.5 of 255 truncates to 127:
  // 0.2122), times the albedo 0.5; 255 -> 1.
  EXPECT_NEAR(hit.albedo.x, 0.5 * 0.2122, 2e-3);
  EXPECT_NEAR(hit.albedo.y, 0.5, 1e-5);
  EXPECT_NEAR(hit.albedo.z, 0.0, 1e-6);
  // The checker: uv (0.25, 0.25) -> cell (0, 0) = color_a; uv (0.75, 0.25) -> color_b.
  ASSERT_TRUE(scene->intersect(rt::Ray{Vec3(-0.5f, -0.5f, -0.5f), Vec3(0, 0, -1), 1e30f}, hit));
  EXPECT_EQ(hit.albedo.x, 1.0f);
  ASSERT_TRUE(scene->intersect(rt::Ray{Vec3(0.5f, -0.5f, -0.5f), Vec3(0, 0, -1), 1e30f}, hit));
  EXPECT_EQ(hit.albedo.z, 1.0f);
  // A texture file that is missing is named.
  std::string missing = text;
  missing.replace(missing.find("wall.png"), 8, "gone.png");
  std::string msg = error_of([&] { load_scene(test::write_text(dir.file("m.toml"), missing)); });
  EXPECT_NE(msg.find("gone.png"), std::string::npos) << msg;
}

TEST(SceneFile, UnknownKeysAreRejectedWithFileAndKey) {
  test::TempDir dir;
  std::string base = test::furnace_scene(0.5, 1.0);
  std::string p1 = test::write_text(dir.file("a.toml"), "fov = 30\n" + base);
  std::string msg = error_of([&] { load_scene(p1); });
  EXPECT_NE(msg.find("a.toml"), std::string::npos) << msg;
  EXPECT_NE(msg.find("'fov'"), std::string::npos) << msg;
  std::string p2 = test::write_text(dir.file("b.toml"), base + "radius_typo = 2\n");
  msg = error_of([&] { load_scene(p2); });
  EXPECT_NE(msg.find("b.toml"), std::string::npos) << msg;
  EXPECT_NE(msg.find("objects[0].radius_typo"), std::string::npos) << msg;
  std::string p3 = test::write_text(dir.file("c.toml"), base + "[materials.x]\nalbedo = [1, 1, 1]\ncolour = 1\n");
  msg = error_of([&] { load_scene(p3); });
  EXPECT_NE(msg.find("materials.x.colour"), std::string::npos) << msg;
  msg = error_of([&] { load_scene("no-such-scene"); });
  EXPECT_NE(msg.find("cornell-box"), std::string::npos) << msg;  // lists the built-in scenes
}

TEST(SceneFile, McGuireCornellBoxLoadsFromTheScenesFolder) {
  // The McGuire scenes are data outside the repository (../shared/scenes); skip where absent.
  // As the loader looks: $DENOISEBENCH_SCENES, else shared/scenes beside the repository or up
  // to two folders further up (git worktrees).
  std::string dir;
  if (const char* e = std::getenv("DENOISEBENCH_SCENES")) dir = e;
  for (auto p = std::filesystem::absolute(test::source_dir()).parent_path(); dir.empty() && p != p.parent_path();
       p = p.parent_path())
    if (std::filesystem::exists(p / "shared" / "scenes")) dir = (p / "shared" / "scenes").string();
  if (!std::filesystem::exists(dir + "/cornell_box/CornellBox-Original.obj"))
    GTEST_SKIP() << "no McGuire scenes (" << (dir.empty() ? std::string("no shared/scenes beside the repository") : "'" + dir + "'")
                 << "; $DENOISEBENCH_SCENES names the folder)";
  SceneLoadOptions o;
  o.scenes_dir = dir;
  auto scene = load_scene("mcguire-cornell-box", o);
  EXPECT_EQ(scene->triangle_count(), 36u);  // the README's count (duplicated faces included)
  EXPECT_TRUE(scene->has_lights());
  // The light (Ke 17 12 4) faces down: seen from below it emits, from above it does not.
  rt::SurfaceHit hit;
  ASSERT_TRUE(scene->intersect(rt::Ray{Vec3(0.0f, 1.5f, 0.0f), Vec3(0, 1, 0), 1e30f}, hit));
  EXPECT_EQ(hit.emitted().x, 17.0f);
  // The unknown folder is an input error that says how to point at the scenes.
  o.scenes_dir = "/nonexistent-scenes";
  std::string msg = error_of([&] { load_scene("mcguire-cornell-box", o); });
  EXPECT_NE(msg.find("nonexistent-scenes"), std::string::npos) << msg;
}

TEST(SceneFile, BuiltInScenesLoadAndRender) {
  for (const auto& name : builtin_scene_names()) {
    if (name.rfind("mcguire-", 0) == 0) continue;  // need ../shared/scenes (tested separately)
    auto scene = load_scene(name);
    EXPECT_EQ(scene_name(*scene), name);
    EXPECT_TRUE(scene->has_lights()) << name;
    RenderSettings s;
    s.width = 16;
    s.height = 12;
    s.spp = 1;
    AovFrame f = render_frame(*scene, s);
    EXPECT_EQ(f.meta.dropped_samples, 0) << name;
    // Something was seen and lit: a finite positive mean and pixels that differ (a black or
    // flat image, such as a camera looking away or lights that emit nothing, fails here).
    const Image& color = f.layer(layer::kColor);
    double sum = 0;
    float lo = color.data()[0], hi = lo;
    bool finite = true;
    for (std::size_t k = 0; k < color.size(); ++k) {
      const float v = color.data()[k];
      finite = finite && std::isfinite(v);
      sum += v;
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    EXPECT_TRUE(finite) << name;
    EXPECT_GT(sum / double(color.size()), 0.0) << name << ": the mean is not positive";
    EXPECT_LT(lo, hi) << name << ": every value of the image is " << lo << " (no variance across pixels)";
  }
}

}  // namespace
}  // namespace dnb
