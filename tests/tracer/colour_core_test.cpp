// tracer/colour_core.h, the vectorised core of docs/speed.md's go/no-go experiment: with the
// tracer's own numbers it traces the tracer's paths (images equal up to rounding), with
// independent numbers its layers have the tracer's means, its colour image does not depend on
// the thread count, and it refuses what it does not cover.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/errors.h"
#include "core/stats.h"
#include "test_util.h"
#include "thread_count.h"
#include "tracer/colour_core.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

// A diffuse room (open at the front) with coloured walls, a block and a one-sided ceiling light
// a centimetre under the ceiling, facing down: the paths bounce, play roulette and meet the
// light after several vertices. A small two-sided light seen from both sides, and a one-sided
// light a centimetre in front of the back wall, facing it: its light reaches the room off the
// wall, and paths from the wall meet it at a distance comparable to the rays' offset, where an
// emitter's MIS density depends on the point it is measured from.
std::string room_scene() {
  return "[camera]\neye = [0.0, 1.0, 2.6]\nlook_at = [0.0, 1.0, 0.0]\nvfov = 50.0\n"
         "[materials.white]\nalbedo = [0.75, 0.74, 0.7]\n"
         "[materials.red]\nalbedo = [0.65, 0.07, 0.05]\n"
         "[materials.green]\nalbedo = [0.12, 0.48, 0.09]\n"
         "[[objects]]\ntype = \"quad\"\nmaterial = \"white\"\n"
         "vertices = [-1, 0, 1,  1, 0, 1,  1, 0, -1,  -1, 0, -1]\n"  // floor, facing up
         "[[objects]]\ntype = \"quad\"\nmaterial = \"white\"\n"
         "vertices = [-1, 2, -1,  1, 2, -1,  1, 2, 1,  -1, 2, 1]\n"  // ceiling
         "[[objects]]\ntype = \"quad\"\nmaterial = \"white\"\n"
         "vertices = [-1, 0, -1,  1, 0, -1,  1, 2, -1,  -1, 2, -1]\n"  // back wall
         "[[objects]]\ntype = \"quad\"\nmaterial = \"red\"\n"
         "vertices = [-1, 0, 1,  -1, 0, -1,  -1, 2, -1,  -1, 2, 1]\n"  // left wall
         "[[objects]]\ntype = \"quad\"\nmaterial = \"green\"\n"
         "vertices = [1, 0, -1,  1, 0, 1,  1, 2, 1,  1, 2, -1]\n"  // right wall
         "[[objects]]\ntype = \"box\"\nmaterial = \"white\"\nsize = [0.5, 0.9, 0.5]\n"
         "rotate = [0, 25, 0]\ntranslate = [-0.35, 0.45, -0.3]\n"
         "[[lights]]\ntype = \"quad\"\nvertices = [-0.25, 1.99, -0.25,  0.25, 1.99, -0.25,  0.25, 1.99, 0.25,  -0.25, 1.99, 0.25]\n"
         "emission = [12.0, 10.0, 7.0]\n"
         "[[lights]]\ntype = \"quad\"\nsize = [0.12, 0.12]\nrotate = [90, 0, 0]\ntranslate = [0.55, 0.6, 0.2]\n"
         "emission = [4.0, 4.0, 4.0]\ntwo_sided = true\n"
         "[[lights]]\ntype = \"quad\"\nvertices = [-0.1, 0.9, -0.99,  -0.1, 1.1, -0.99,  0.1, 1.1, -0.99,  0.1, 0.9, -0.99]\n"
         "emission = [6.0, 6.0, 6.0]\n";
}

// The mean over pixels and channels of a - b in standard errors of that mean (pixels are
// independent: z is close to normal when a and b have one expectation).
double mean_difference_z(const Image& a, const Image& b) { return stats::paired_z(a.data(), b.data(), a.size()); }

struct Room {
  test::TempDir dir;
  std::shared_ptr<const Scene> scene = load_scene(test::write_text(dir.file("room.toml"), room_scene()));
};

RenderSettings small(int spp) {
  RenderSettings s;
  s.width = 64;
  s.height = 48;
  s.spp = spp;
  return s;
}

ColourCore::Options core_options(const RenderSettings& s, ColourCore::Numbers numbers, std::uint64_t seed) {
  ColourCore::Options o;
  o.width = s.width;
  o.height = s.height;
  o.spp = s.spp;
  o.max_depth = s.max_depth;
  o.numbers = numbers;
  o.seed = seed;
  return o;
}

TEST(ColourCore, WithTheTracersNumbersItTracesTheTracersPaths) {
  Room room;
  ASSERT_EQ(ColourCore::supported(*room.scene), "");
  const RenderSettings s = small(32);
  const AovFrame tracer = render_frame(*room.scene, s);
  const ColourCore core(*room.scene, core_options(s, ColourCore::Numbers::kTracer, s.seed));
  const AovFrame f = render_frame(*room.scene, s, core);
  // The same random numbers for the same purposes, so the same paths: values equal up to the
  // rounding of other arithmetic (vector sine and cosine, products in another order), which can
  // flip a roulette or occlusion test on a rare path (the bench saw 2 values in a million).
  for (const char* name : {layer::kColor, layer::kDirect, layer::kIndirect, layer::kAlbedo, layer::kEmission,
                           layer::kNormal, layer::kDepth}) {
    const Image& a = f.layer(name);
    const Image& b = tracer.layer(name);
    std::size_t close = 0;
    for (std::size_t i = 0; i < a.size(); ++i)
      close += std::abs(a.data()[i] - b.data()[i]) <= 1e-4f * std::max(1.0f, std::abs(b.data()[i]));
    EXPECT_GE(double(close) / double(a.size()), 0.999) << name;
  }
  // The same work: the rays of the main pass agree as closely.
  const double core_rays = std::stod(f.meta.extra.at("rays")), tracer_rays = std::stod(tracer.meta.extra.at("rays"));
  EXPECT_NEAR(core_rays / tracer_rays, 1.0, 1e-3);
}

TEST(ColourCore, WithIndependentNumbersItsLayersHaveTheTracersMeans) {
  Room room;
  const RenderSettings s = small(64);
  const AovFrame tracer = render_frame(*room.scene, s);
  const ColourCore core(*room.scene, core_options(s, ColourCore::Numbers::kIndependent, 5));
  const AovFrame f = render_frame(*room.scene, s, core);
  // Independent estimates of the same expectations: |z| > 4.5 happens by chance 7e-6 of the time
  // per layer (seven layers here).
  for (const char* name : {layer::kColor, layer::kDirect, layer::kIndirect, layer::kAlbedo, layer::kEmission,
                           layer::kNormal, layer::kDepth})
    EXPECT_LT(std::abs(mean_difference_z(f.layer(name), tracer.layer(name))), 4.5) << name;
  // The colour-only render as well.
  const std::vector<float> img = core.render();
  Image c(s.width, s.height, 3);
  std::copy(img.begin(), img.end(), c.data());
  EXPECT_LT(std::abs(mean_difference_z(c, tracer.layer(layer::kColor))), 4.5);
}

TEST(ColourCore, AnEstimatorThatCutsPathsShortIsCaught) {
  // The checks above can fail: paths of 3 vertices instead of 8 lose the indirect light.
  Room room;
  const RenderSettings s = small(64);
  const AovFrame tracer = render_frame(*room.scene, s);
  ColourCore::Options o = core_options(s, ColourCore::Numbers::kIndependent, 5);
  o.max_depth = 3;
  const ColourCore core(*room.scene, o);
  RenderSettings cut = s;
  cut.max_depth = 3;
  EXPECT_GT(std::abs(mean_difference_z(render_frame(*room.scene, cut, core).layer(layer::kIndirect),
                                       tracer.layer(layer::kIndirect))),
            4.5);  // the bound the agreement above holds to (|z| = 9.9 and 6.7 were seen)
}

TEST(ColourCore, TheColourImageDoesNotDependOnTheThreadCount) {
  Room room;
  const RenderSettings s = small(8);
  const ColourCore core(*room.scene, core_options(s, ColourCore::Numbers::kIndependent, 3));
  std::vector<float> one, two;
  test::run_on_threads(1, [&] { one = core.render(); });
  ASSERT_GT(test::run_on_threads(3, [&] { two = core.render(); }), 1);
  ASSERT_EQ(one.size(), std::size_t(s.width) * s.height * 3);
  EXPECT_EQ(one, two);
  double sum = 0;
  for (float v : one) sum += v;
  EXPECT_GT(sum, 0.0);  // not an empty image
}

TEST(ColourCore, RefusesWhatItDoesNotCover) {
  auto cornell = load_scene("cornell-box");  // a mirror sphere, a coated block, a texture
  const std::string why = ColourCore::supported(*cornell);
  EXPECT_NE(why, "");
  EXPECT_THROW(ColourCore(*cornell, ColourCore::Options{}), std::invalid_argument);
  Room room;
  ColourCore::Options o;
  o.lanes = 4;
  EXPECT_THROW(ColourCore(*room.scene, o), std::invalid_argument);
}

}  // namespace
}  // namespace dnb
