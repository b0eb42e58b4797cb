// The cache keys of render products (tracer/render_cache_keys.h) and the scene content hash they start
// with are pinned here to their exact text: a change to either invalidates every cached
// reference and input frame, so it must be deliberate (and change these expectations).
#include <gtest/gtest.h>

#include "test_util.h"
#include "tracer/render_cache_keys.h"
#include "tracer/reference.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

// A scene file, the OBJ it names and the OBJ's MTL file: the three files of the content hash.
std::shared_ptr<const Scene> three_file_scene(const test::TempDir& dir) {
  test::write_text(dir.file("tri.obj"), "mtllib tri.mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nusemtl grey\nf 1 2 3\n");
  test::write_text(dir.file("tri.mtl"), "newmtl grey\nKd 0.5 0.5 0.5\n");
  return load_scene(test::write_text(
      dir.file("s.toml"),
      "[camera]\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\nvfov = 40\n[[objects]]\ntype = \"obj\"\nfile = \"tri.obj\"\n"));
}

// FNV-1a 64 over (file name, NUL, bytes) of s.toml, tri.obj, tri.mtl, in the order read.
constexpr const char* kThreeFileHash = "7689a28d135865a2";

TEST(SceneContentHash, IsFnv1aOverFileNamesAndBytesInReadOrder) {
  test::TempDir dir;
  auto scene = three_file_scene(dir);
  ASSERT_EQ(scene->files.size(), 3u);
  EXPECT_EQ(scene_content_hash(*scene), kThreeFileHash);
}

TEST(CacheKeys, FrameKeyPartsAndOrderArePinned) {
  test::TempDir dir;
  auto scene = three_file_scene(dir);
  // threads is not part of the key: the image does not depend on it.
  const RenderSettings s{.width = 64, .height = 48, .spp = 16, .seed = 3, .threads = 1, .max_depth = 5,
                         .reflection_levels = 1, .edge_subpixels = false, .on_progress = {}};
  EXPECT_EQ(frame_cache_key(*scene, s).canonical(),
            std::string("frame\nscene=") + kThreeFileHash +
                "\nwidth=64\nheight=48\nspp=16\nseed=3\nmax_depth=5\nreflection_levels=1\nedge_subpixels=0\n"
                "tracer=" + kTracerVersion + "\nlayers=" + kFrameLayers + "\n");
}

TEST(CacheKeys, ReferenceKeyPartsAndOrderArePinned) {
  test::TempDir dir;
  auto scene = three_file_scene(dir);
  const ReferenceSettings s{.width = 64, .height = 48, .spp = 256, .seed = 9, .max_depth = 8, .block_spp = 32};
  EXPECT_EQ(reference_cache_key(*scene, s).canonical(),
            std::string("reference\nscene=") + kThreeFileHash +
                "\nwidth=64\nheight=48\nspp=256\nseed=9\nmax_depth=8\nblock_spp=32\ntracer=" + kTracerVersion + "\n");
}

// A scene with a sun carries kSunVersion after max_depth in both keys (its images changed alone,
// tracer/render.h); the keys above, without a sun, do not.
TEST(CacheKeys, OnlyScenesWithASunCarryTheSunVersion) {
  test::TempDir dir;
  auto scene = load_scene(test::write_text(
      dir.file("sun.toml"),
      "[camera]\neye = [0, 1, 3]\nlook_at = [0, 0, 0]\nvfov = 40\n[sun]\ndirection = [0, 1, 1]\n"
      "irradiance = [3, 3, 3]\n[materials.m]\nalbedo = [0.5, 0.5, 0.5]\n[[objects]]\ntype = \"quad\"\n"
      "material = \"m\"\nsize = [10, 10]\n"));
  const std::string sun = std::string("max_depth=8\nsun=") + kSunVersion + "\n";
  const RenderSettings f{.width = 8, .height = 6, .spp = 4, .seed = 1, .threads = 1, .max_depth = 8,
                         .reflection_levels = 1, .edge_subpixels = false, .on_progress = {}};
  EXPECT_NE(frame_cache_key(*scene, f).canonical().find(sun + "reflection_levels=1"), std::string::npos);
  const ReferenceSettings r{.width = 8, .height = 6, .spp = 16, .seed = 9, .max_depth = 8, .block_spp = 16};
  EXPECT_NE(reference_cache_key(*scene, r).canonical().find(sun + "block_spp=16"), std::string::npos);
}

}  // namespace
}  // namespace dnb
