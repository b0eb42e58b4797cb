// Values of scene files (TOML, OBJ, MTL) are checked where they are read: non-finite or
// negative emission and albedo, non-finite transforms and unbounded counts are InputErrors
// naming file, line and key; only regular files are read as meshes and textures; and a legal
// but extreme emitter (1e30) still gives a finite frame, its variance layers included.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <vector>

#include "core/errors.h"
#include "core/image.h"
#include "test_util.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

namespace fs = std::filesystem;
std::string error_of(const std::function<void()>& f) { return test::error_of<InputError>(f); }

bool names(const std::string& msg, const std::string& what) { return msg.find(what) != std::string::npos; }

// The furnace scene (tracer_scenes.h) with one line replaced: `from` -> `to`.
std::string furnace_with(const std::string& from, const std::string& to) {
  std::string s = test::furnace_scene(0.5, 1.0);
  const auto at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

TEST(SceneValues, NonFiniteOrNegativeValuesNameFileLineAndKey) {
  test::TempDir dir;
  struct Case {
    std::string from, to, where;
  };
  const std::string emission = "emission = [1.000000, 1.000000, 1.000000]";
  const std::string albedo = "albedo = [0.500000, 0.500000, 0.500000]";
  const Case cases[] = {
      {emission, "emission = [nan, 1, 1]", ":7: key 'materials.wall.emission'"},
      {emission, "emission = [inf, 1, 1]", ":7: key 'materials.wall.emission'"},
      {emission, "emission = [-1, 1, 1]", ":7: key 'materials.wall.emission'"},
      {albedo, "albedo = [-0.5, 0.5, 0.5]", ":6: key 'materials.wall.albedo'"},
      {albedo, "albedo = [nan, 0.5, 0.5]", ":6: key 'materials.wall.albedo'"},
      {"radius = 1.0", "radius = inf", ":11: key 'objects[0].radius'"},
      {"radius = 1.0", "radius = 1.0\ntranslate = [0, nan, 0]", ":12: key 'objects[0].translate'"},
      {"radius = 1.0", "radius = 1.0\nscale = -inf", ":12: key 'objects[0].scale'"},
      {"radius = 1.0", "radius = 1.0\nrotate = [0, inf, 0]", ":12: key 'objects[0].rotate'"},
      // A huge sphere `segments` hung the loader for minutes; 99999999999 wrapped to an int.
      {"segments = 24", "segments = 1000000", ":14: key 'objects[0].segments'"},
      {"segments = 24", "segments = 99999999999", ":14: key 'objects[0].segments'"},
      {"vfov = 70", "vfov = nan", ":4: key 'camera.vfov'"},
  };
  for (const Case& c : cases) {
    const std::string path = test::write_text(dir.file("s.toml"), furnace_with(c.from, c.to));
    const std::string msg = error_of([&] { load_scene(path); });
    EXPECT_TRUE(names(msg, path + c.where)) << c.to << " -> " << msg;
  }
  // The bound says why.
  const std::string path = test::write_text(dir.file("s.toml"), furnace_with("segments = 24", "segments = 1000000"));
  EXPECT_TRUE(names(error_of([&] { load_scene(path); }), "triangles")) << "the segments bound gives no reason";
}

// A one-triangle OBJ whose material `m` has the MTL lines `mtl`.
void write_obj(const test::TempDir& dir, const std::string& mtl) {
  test::write_text(dir.file("t.mtl"), "newmtl other\nKd 0.5 0.5 0.5\nnewmtl m\n" + mtl);
  test::write_text(dir.file("t.obj"), "mtllib t.mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nusemtl m\nf 1 2 3\n");
}

std::string obj_scene() {
  return "[camera]\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\nvfov = 40\n[[objects]]\ntype = \"obj\"\nfile = \"t.obj\"\n";
}

TEST(SceneValues, MtlColoursAreCheckedWithFileAndLine) {
  test::TempDir dir;
  for (const std::string& bad : {std::string("Kd -1 0.5 0.5"), std::string("Ke nan 1 1"), std::string("Ke inf 1 1"),
                                 std::string("Ke 1e31 1 1")}) {
    write_obj(dir, "Kd 0.5 0.5 0.5\n" + bad + "\n");
    const std::string msg = error_of([&] { load_scene(test::write_text(dir.file("s.toml"), obj_scene())); });
    const std::string key = bad.substr(0, 2);
    EXPECT_TRUE(names(msg, dir.file("t.mtl") + ":")) << bad << " -> " << msg;
    EXPECT_TRUE(names(msg, "'" + key + "'")) << bad << " -> " << msg;
    EXPECT_TRUE(names(msg, "material 'm'")) << bad << " -> " << msg;
  }
  // The line is the bad value's own: line 4 (Kd) and 5 (Ke) of t.mtl.
  write_obj(dir, "Kd 0.5 0.5 0.5\nKe -2 1 1\n");
  std::string msg = error_of([&] { load_scene(test::write_text(dir.file("s.toml"), obj_scene())); });
  EXPECT_TRUE(names(msg, dir.file("t.mtl") + ":5:")) << msg;
  write_obj(dir, "Kd 0.5 -0.5 0.5\n");
  msg = error_of([&] { load_scene(test::write_text(dir.file("s.toml"), obj_scene())); });
  EXPECT_TRUE(names(msg, dir.file("t.mtl") + ":4:")) << msg;
}

// Ke 1e30 is legal: the frame is finite in every layer. The squares of its samples (1e60) used
// to be summed in float, which put Inf into the variance layers.
TEST(SceneValues, ExtremeEmitterGivesAFiniteFrame) {
  test::TempDir dir;
  write_obj(dir, "Kd 0.5 0.5 0.5\nKe 1e30 1e30 1e30\n");
  auto scene = load_scene(test::write_text(dir.file("s.toml"), obj_scene()));
  RenderSettings s;
  s.width = 12;
  s.height = 8;
  s.spp = 4;
  s.threads = 1;
  AovFrame f = render_frame(*scene, s);
  float brightest = 0;
  for (const auto& [name, img] : f.layers()) {
    EXPECT_EQ(count_non_finite(img.view()), 0u) << "layer " << name;
    if (name == layer::kColor)
      for (std::size_t k = 0; k < img.size(); ++k) brightest = std::max(brightest, img.data()[k]);
  }
  EXPECT_GT(brightest, 1e29f) << "the emitter is not seen: the test proves nothing";
  EXPECT_EQ(f.meta.dropped_samples, 0) << "samples of the emitter were dropped instead of summed";
}

TEST(SceneValues, OnlyRegularFilesAreReadAsMeshesAndTextures) {
  test::TempDir dir;
  std::filesystem::create_directory(dir.file("folder.obj"));
  std::filesystem::create_directory(dir.file("folder.png"));
  const std::string head = "[camera]\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\n";
  for (const std::string& file : {dir.file("folder.obj"), std::string("/dev/zero")}) {
    const std::string path =
        test::write_text(dir.file("s.toml"), head + "[[objects]]\ntype = \"obj\"\nfile = \"" + file + "\"\n");
    const std::string msg = error_of([&] { load_scene(path); });
    EXPECT_TRUE(names(msg, "'" + file + "'")) << msg;
    EXPECT_TRUE(names(msg, "not a regular file")) << msg;
    EXPECT_TRUE(names(msg, path + ":6: key 'objects[0].file'")) << msg;
  }
  for (const std::string& file : {dir.file("folder.png"), std::string("/dev/zero")}) {
    const std::string path = test::write_text(
        dir.file("s.toml"), head + "[textures.t]\ntype = \"image\"\nfile = \"" + file +
                                "\"\n[materials.a]\ntexture = \"t\"\n[[objects]]\ntype = \"sphere\"\nmaterial = \"a\"\n"
                                "radius = 1\n");
    const std::string msg = error_of([&] { load_scene(path); });
    EXPECT_TRUE(names(msg, "'" + file + "'")) << msg;
    EXPECT_TRUE(names(msg, "not a regular file")) << msg;
  }
  // An MTL map_Kd that names a folder.
  test::write_text(dir.file("t.mtl"), "newmtl m\nKd 1 1 1\nmap_Kd folder.png\n");
  test::write_text(dir.file("t.obj"), "mtllib t.mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nusemtl m\nf 1 2 3\n");
  const std::string msg = error_of([&] { load_scene(test::write_text(dir.file("s.toml"), obj_scene())); });
  EXPECT_TRUE(names(msg, "folder.png")) << msg;
  EXPECT_TRUE(names(msg, "not a regular file")) << msg;
}

TEST(SceneValues, ObjIndexErrorsNameTheLine) {
  test::TempDir dir;
  test::write_text(dir.file("t.mtl"), "newmtl m\nKd 1 1 1\n");
  // A triangle and a quad, each with an index past the 4 vertices (line 7; line 8), and a
  // relative index before the first vertex (line 3).
  const char* objs[][2] = {
      {"mtllib t.mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nv 0 2 0\nf 1 2 3\nf 1 2 9\n", ":7:"},
      {"mtllib t.mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nv 0 2 0\nf 1 2 3\nf 1 2 3 4\nf 1 2 3 7\n", ":8:"},
      {"mtllib t.mtl\nv -1 -1 0\nf -1 -2 -3\nv 1 -1 0\nv 0 1 0\n", ":3:"},
      // A normal index past the one normal (line 6) and a texture coordinate past the one (line
      // 8): used to be read as "no normal" and "no texture coordinate" without a word.
      {"mtllib t.mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//5\n", ":6:"},
      {"mtllib t.mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1 3/1/1\nf 1/1 2/3 3/1\n", ":8:"},
  };
  for (const auto& [obj, line] : objs) {
    test::write_text(dir.file("t.obj"), obj);
    const std::string msg = error_of([&] { load_scene(test::write_text(dir.file("s.toml"), obj_scene())); });
    EXPECT_TRUE(names(msg, dir.file("t.obj") + line)) << obj << " -> " << msg;
  }
  test::write_text(dir.file("t.obj"), objs[3][0]);
  const std::string msg = error_of([&] { load_scene(test::write_text(dir.file("s.toml"), obj_scene())); });
  EXPECT_TRUE(names(msg, "face index 3//5 (normal 5) is out of range (the file has 1 normals)")) << msg;
}

// A texture larger than the bound is refused from its header, before its texels are allocated.
TEST(SceneValues, OversizedTextureIsRefusedFromItsHeader) {
  test::TempDir dir;
  // A PGM header claiming 16384 x 8192 grey texels (2^27), and no texels: only the header is read.
  test::write(dir.file("big.pgm"), "P5\n16384 8192\n255\n");
  const std::string path = test::write_text(
      dir.file("s.toml"), "[camera]\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\n[textures.t]\ntype = \"image\"\nfile = \"big.pgm\"\n"
                          "[materials.a]\ntexture = \"t\"\n[[objects]]\ntype = \"sphere\"\nmaterial = \"a\"\nradius = 1\n");
  const std::string msg = error_of([&] { load_scene(path); });
  EXPECT_TRUE(names(msg, "16384x8192")) << msg;
  EXPECT_TRUE(names(msg, "big.pgm")) << msg;
}

TEST(SceneValues, NonFiniteObjVerticesNameTheLine) {
  test::TempDir dir;
  test::write_text(dir.file("t.obj"), "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\nv 1e39 -1 0\nv 0 1 -1\nf 1 4 5\n");
  const std::string msg = error_of([&] { load_scene(test::write_text(dir.file("s.toml"), obj_scene())); });
  EXPECT_TRUE(names(msg, dir.file("t.obj") + ":5:")) << msg;
  EXPECT_TRUE(names(msg, "1e39")) << msg;
}

// Found by fuzz/scene_fuzz.cpp (CI's one-minute run): a mesh or material file name longer than
// the system allows made std::filesystem throw its own error out of the loader ("File name too
// long"). It is a file not found: an InputError naming the scene.
TEST(SceneValues, FuzzAFileNameTooLongForTheSystemIsAnInputError) {
  test::TempDir dir;
  const std::string long_name(5000, 'm');
  std::string scene = obj_scene();
  scene.replace(scene.find("t.obj"), 5, long_name + ".obj");
  const std::string msg = error_of([&] { load_scene(test::write_text(dir.file("s.toml"), scene)); });
  EXPECT_TRUE(names(msg, dir.file("s.toml"))) << msg;
  test::write_text(dir.file("t.obj"), "mtllib " + long_name + ".mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n");
  EXPECT_NO_THROW(load_scene(test::write_text(dir.file("s2.toml"), obj_scene())));  // a missing MTL is no error
  EXPECT_FALSE(error_of([&] { load_scene(long_name); }).empty());
}

// A folder or a device named as the scene was "no such scene file" (it exists): now it says what
// it is. A folder beside the program named like a built-in scene does not hide the built-in one.
TEST(SceneValues, AFolderOrADeviceIsNotASceneFile) {
  test::TempDir dir;
  fs::create_directory(dir.file("s.toml"));
  for (const std::string& path : {dir.file("s.toml"), std::string("/dev/null")}) {
    const std::string msg = error_of([&] { load_scene(path); });
    EXPECT_NE(msg.find("scene '" + path + "': exists but is not a regular file"), std::string::npos) << msg;
  }
  const fs::path here = fs::current_path();
  fs::create_directory(dir.file("cornell-box"));
  fs::current_path(dir.path());
  const std::string msg = error_of([&] { load_scene("cornell-box"); });
  fs::current_path(here);
  EXPECT_EQ(msg, "(no error)") << msg;
}

}  // namespace
}  // namespace dnb
