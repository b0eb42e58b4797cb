// The Blender Cycles back-end (renderers/cycles, docs/renderers.md "Blender Cycles") through the
// harness's protocol: a small scene of every material type the tracer has, exported with
// `denoisebench export-gltf`, rendered by one Blender process: the layers exist and are finite,
// F = (D + I) T + R + E per pixel, a malformed scene file fails naming it, and the same worker
// serves every request. Skipped (saying why) where Blender is not installed; CI has none
// (tests/allowed_skips.txt); DNB_SETUP_BLENDER=1 scripts/setup installs it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <sstream>

#include "core/errors.h"
#include "interop/renderers.h"
#include "test_util.h"

namespace dnb::interop {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;
using test::write;

// Open to a gradient sky and a sun, lit also by an emitting quad: a textured diffuse floor, a
// coated, a mirror, a rough gold, a rough plastic, an absorbing glass and a thin-sheet sphere.
const char* kScene = R"(description = "every material under sky, sun and an area light"
[camera]
eye = [0, 1.2, 4]
look_at = [0, 0.4, 0]
up = [0, 1, 0]
vfov = 40
[sky]
type = "gradient"
zenith = [0.2, 0.3, 0.6]
horizon = [0.6, 0.6, 0.6]
ground = [0.1, 0.1, 0.1]
[sun]
direction = [0.4, 1, 0.3]
irradiance = [3, 2.8, 2.5]
angular_radius = 2
[textures.checker]
type = "checker"
scale = 8
color_a = [0.8, 0.8, 0.8]
color_b = [0.2, 0.2, 0.2]
[materials.floor]
texture = "checker"
albedo = [0.9, 0.8, 0.7]
[materials.coat]
type = "coated"
albedo = [0.7, 0.2, 0.2]
ior = 1.5
[materials.mirror]
type = "mirror"
tint = [0.9, 0.9, 0.9]
[materials.gold]
type = "conductor"
metal = "Au"
roughness = 0.1
[materials.plastic]
type = "plastic"
albedo = [0.1, 0.3, 0.7]
ior = 1.5
roughness = 0.05
[materials.glass]
type = "dielectric"
ior = 1.5
absorption = [0.5, 0.1, 0.1]
[materials.pane]
type = "dielectric"
ior = 1.5
thin = true
[materials.lamp]
albedo = [0.5, 0.5, 0.5]
emission = [4, 4, 4]
[[objects]]
type = "quad"
material = "floor"
vertices = [-3, 0, -3,  -3, 0, 3,  3, 0, 3,  3, 0, -3]
[[objects]]
type = "quad"
material = "lamp"
vertices = [-1, 2.5, -1,  1, 2.5, -1,  1, 2.5, 1,  -1, 2.5, 1]
[[objects]]
type = "sphere"
material = "coat"
center = [-1.5, 0.4, 0]
radius = 0.4
[[objects]]
type = "sphere"
material = "mirror"
center = [-0.5, 0.4, 0]
radius = 0.4
[[objects]]
type = "sphere"
material = "gold"
center = [0.5, 0.4, 0]
radius = 0.4
[[objects]]
type = "sphere"
material = "plastic"
center = [1.5, 0.4, 0]
radius = 0.4
[[objects]]
type = "sphere"
material = "glass"
center = [-0.6, 0.3, 1.2]
radius = 0.3
[[objects]]
type = "sphere"
material = "pane"
center = [0.6, 0.3, 1.2]
radius = 0.3
)";


RendererBackend cycles() {
  return RendererBackend(find_renderers({test::source_dir() + "/renderers"}).at("cycles"));
}

RenderRequest request(const std::string& scene, std::uint32_t seed) {
  RenderRequest r;
  r.scene = scene;
  r.width = 32;
  r.height = 24;
  r.spp = 8;
  r.seed = seed;
  r.max_depth = 6;
  r.threads = 2;
  r.layers = {"color", "direct", "indirect", "albedo", "reflection", "emission", "normal", "depth"};
  return r;
}

struct ExportedScene {
  test::TempDir dir;
  std::string gltf = dir.file("scene.gltf");
  ExportedScene() {
    write(dir.path() / "scene.toml", kScene);
    const auto r = test::run_in(dir, "export-gltf " + dir.file("scene.toml") + " -o " + gltf + " --size 32x24");
    if (r.exit_code != 0) ADD_FAILURE() << r.output;
  }
};

TEST(CyclesBackend, RendersAnExportedSceneWhoseLayersAddUpToTheColourPerPixel) {
  if (const std::string why = test::blender_missing(); !why.empty()) GTEST_SKIP() << why;
  ExportedScene s;
  RendererBackend b = cycles();
  const AovFrame f = b.render(request(s.gltf, 11));
  ASSERT_EQ(f.width(), 32);
  ASSERT_EQ(f.height(), 24);
  EXPECT_GT(f.meta.render_seconds, 0.0);
  EXPECT_THAT(f.meta.tracer_version, HasSubstr("cycles: Blender 3."));
  for (const char* l : {"color", "direct", "indirect", "albedo", "reflection", "emission", "normal", "depth"}) {
    ASSERT_TRUE(f.has(l)) << l;
    const Image& im = f.layer(l);
    for (std::size_t i = 0; i < im.size(); ++i) ASSERT_TRUE(std::isfinite(im.data()[i])) << l << " " << i;
  }
  const Image &F = f.layer(layer::kColor), &D = f.layer(layer::kDirect), &I = f.layer(layer::kIndirect),
              &T = f.layer(layer::kAlbedo), &R = f.layer(layer::kReflection), &E = f.layer(layer::kEmission);
  double worst = 0, sum_r = 0, sum_e = 0, sum_d = 0;
  for (int y = 0; y < f.height(); ++y)
    for (int x = 0; x < f.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        const double split = (double(D.at(x, y, c)) + I.at(x, y, c)) * T.at(x, y, c) + R.at(x, y, c) + E.at(x, y, c);
        worst = std::max(worst, std::abs(split - F.at(x, y, c)) / std::max(1.0, double(std::abs(F.at(x, y, c)))));
        sum_r += R.at(x, y, c);
        sum_e += E.at(x, y, c);
        sum_d += D.at(x, y, c) * T.at(x, y, c);
      }
  EXPECT_LT(worst, 1e-5) << "F = (D + I) T + R + E per pixel";
  // Every part has light in it: the metals and glass in R, the sky and lamp in E, the floor in D.
  EXPECT_GT(sum_r, 0.5);
  EXPECT_GT(sum_e, 0.5);
  EXPECT_GT(sum_d, 0.5);
  // Normals in the glTF file's frame (Y up): the floor at the bottom of the image faces +Y.
  EXPECT_NEAR(f.layer(layer::kNormal).at(16, 23, 1), 1.0f, 0.05f);
  EXPECT_GT(f.layer(layer::kDepth).at(16, 23, 0), 1.0f);
}

TEST(CyclesBackend, OneBlenderServesEveryRequestAndAMalformedFileFailsNamingIt) {
  if (const std::string why = test::blender_missing(); !why.empty()) GTEST_SKIP() << why;
  ExportedScene s;
  const std::string log = s.dir.file("requests.log");
  ::setenv("DENOISEBENCH_CYCLES_LOG", log.c_str(), 1);
  RendererBackend b = cycles();
  const AovFrame a = b.render(request(s.gltf, 1));
  write(s.dir.path() / "broken.gltf", "{\"asset\": {\"version\": \"2.0\"}, \"scenes\": [\n");
  const std::string msg = test::error_of<WorkError>([&] { b.render(request(s.dir.file("broken.gltf"), 1)); });
  EXPECT_THAT(msg, HasSubstr("renderer 'cycles'"));
  EXPECT_THAT(msg, HasSubstr(s.dir.file("broken.gltf") + ": Blender could not read the scene file"));
  const std::string missing = test::error_of<WorkError>([&] { b.render(request(s.dir.file("nothere.blend"), 1)); });
  EXPECT_THAT(missing, HasSubstr(s.dir.file("nothere.blend")));
  // The worker goes on: the same request gives the same image, another seed another.
  const AovFrame again = b.render(request(s.gltf, 1));
  const AovFrame other = b.render(request(s.gltf, 2));
  ::unsetenv("DENOISEBENCH_CYCLES_LOG");
  const Image &c1 = a.layer(layer::kColor), &c2 = again.layer(layer::kColor), &c3 = other.layer(layer::kColor);
  double same = 0, diff = 0;
  for (std::size_t i = 0; i < c1.size(); ++i) {
    same = std::max(same, double(std::abs(c1.data()[i] - c2.data()[i])));
    diff = std::max(diff, double(std::abs(c1.data()[i] - c3.data()[i])));
  }
  EXPECT_EQ(same, 0.0);
  EXPECT_GT(diff, 1e-3);
  // One process rendered the three images.
  std::istringstream lines(test::slurp(log));
  std::set<std::string> pids;
  int n = 0;
  for (std::string pid, scene, secs; lines >> pid >> scene >> secs; ++n) pids.insert(pid);
  EXPECT_EQ(n, 3);
  EXPECT_EQ(pids.size(), 1u);
  EXPECT_GT(b.setup_seconds(), 0.0);
}

}  // namespace
}  // namespace dnb::interop
