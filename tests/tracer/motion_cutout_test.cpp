// Motion blur and alpha cut-outs in whole renders: a blurred occluder's profile against its
// analytic coverage (object and camera motion alike), every layer an average over the sample
// times, rotation steps that follow the arc, cut-out holes seen by camera rays, AOVs, shadow
// rays and shadow packets, and the loader's refusals.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "core/errors.h"
#include "test_util.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "tracer/shapes.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

using rt::Vec3;

// ---- Motion blur ----
//
// A grey (albedo 0.5) quad, 2 wide and tall enough to fill the view's height, moves in x by
// d = 4 over the frame interval in front of a constant sky of radiance 1, in the plane z = 0
// that the camera at z = 5 looks at squarely. Its front sees only the sky, so it shows exactly
// its albedo (a white furnace); the sky pixels are 1. At time t it covers X in
// [L + d t, R + d t] (L = -3, R = -1), so the point X is covered for the fraction of the shutter
//   c(X) = max(0, min(1, (X - L) / d) - max(0, (X - R) / d))
// and a pixel's expected colour is 1 - (1 - 0.5) c averaged over its footprint in X (linear
// in the film position: the plane is square to the view), its albedo 0.5 c.
constexpr int kW = 48, kH = 6;
constexpr double kL = -3, kR = -1, kD = 4, kAlbedo = 0.5;
constexpr double kTanHalf = 0.36397023426620234;  // tan(20 degrees): vfov 40

std::string blur_scene(const std::string& camera_extra, const std::string& object_extra) {
  return "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40\nshutter = [0, 1]\n" + camera_extra +
         "\n[sky]\ntype = \"constant\"\ncolor = [1, 1, 1]\n[materials.grey]\nalbedo = [0.5, 0.5, 0.5]\n"
         "[[objects]]\ntype = \"quad\"\nmaterial = \"grey\"\nvertices = [-1, -3, 0,  1, -3, 0,  1, 3, 0,  -1, 3, 0]\n"
         "translate = [-2, 0, 0]\n" +
         object_extra + "\n";
}

double coverage_at(double X) {
  return std::max(0.0, std::min(1.0, (X - kL) / kD) - std::max(0.0, (X - kR) / kD));
}

// The coverage averaged over column x's footprint (midpoint rule, 2000 points: c is piecewise
// linear with two kinks, so the rule's error is under 1e-6).
double column_coverage(int x) {
  const double half_width = kTanHalf * (double(kW) / kH) * 5.0;
  const int n = 2000;
  double s = 0;
  for (int i = 0; i < n; ++i) {
    const double fx = x + (i + 0.5) / n;
    s += coverage_at((2 * fx / kW - 1) * half_width);
  }
  return s / n;
}

AovFrame render_text(const std::string& text, int spp, int threads = 0) {
  test::TempDir dir;
  auto scene = load_scene(test::write_text(dir.file("scene.toml"), text));
  RenderSettings s;
  s.width = kW;
  s.height = kH;
  s.spp = spp;
  s.threads = threads;
  return render_frame(*scene, s);
}

// Every column of a blur frame against the analytic profile: the colour's column mean within
// 5 standard errors of its own variance layer (pixels independent; 48 columns, so a 5-sigma
// bound leaves a false alarm about once in 30 000 runs); the albedo's within 5 binomial
// standard errors of a coverage estimate from kH * spp samples (each sample's albedo is 0 or
// 0.5: variance at most 0.25 c (1 - c), an upper bound since the film position is stratified).
void expect_profile(const AovFrame& f, int spp, const std::string& what) {
  const Image& F = f.layer(layer::kColor);
  const Image& V = f.layer(layer::kVariance);
  const Image& T = f.layer(layer::kAlbedo);
  int blurred = 0;
  for (int x = 0; x < kW; ++x) {
    double s = 0, v = 0, t = 0;
    for (int y = 0; y < kH; ++y) {
      s += F.at(x, y, 1);
      v += V.at(x, y, 1);
      t += T.at(x, y, 1);
    }
    const double c = column_coverage(x);
    const double mean = s / kH, se = std::sqrt(v) / kH;
    EXPECT_NEAR(mean, 1 - (1 - kAlbedo) * c, 5 * se + 1e-6) << what << ": column " << x << ", coverage " << c;
    const double n = double(kH) * spp;
    EXPECT_NEAR(t / kH, kAlbedo * c, 5 * kAlbedo * std::sqrt(c * (1 - c) / n) + 1e-6) << what << ": column " << x;
    if (c > 0.1 && c < 0.9) ++blurred;
  }
  // The streak covers X in [-3, 3] (13 columns), its ramps of c in (0.1, 0.9) 8 of them; a
  // sharp edge would make at most 2.
  EXPECT_GE(blurred, 6) << what;
}

TEST(MotionBlur, AMovingOccludersProfileIsItsCoverageOverTheShutter) {
  expect_profile(render_text(blur_scene("", "translate_end = [2, 0, 0]"), 64), 64, "object motion");
}

TEST(MotionBlur, ACameraMovingTheOtherWayGivesTheSameProfile) {
  // The camera moving by -d sees the static quad move by +d: the same expected image.
  expect_profile(render_text(blur_scene("eye_end = [-4, 0, 5]\nlook_at_end = [-4, 0, 0]", ""), 64), 64,
                 "camera motion");
}

TEST(MotionBlur, AClosedShutterIsOneInstantAndFramesDoNotDependOnThreads) {
  // shutter = [t, t]: the quad stands where time t puts it, with sharp edges.
  std::string text = blur_scene("", "translate_end = [2, 0, 0]");
  text.replace(text.find("shutter = [0, 1]"), 16, "shutter = [0.5, 0.5]");
  const AovFrame f = render_text(text, 8);
  const Image& T = f.layer(layer::kAlbedo);
  const double half_width = kTanHalf * (double(kW) / kH) * 5.0;
  for (int x = 0; x < kW; ++x) {
    const double X0 = (2.0 * x / kW - 1) * half_width, X1 = (2.0 * (x + 1) / kW - 1) * half_width;
    if (X1 < -1 || X0 > 1) {
      EXPECT_EQ(T.at(x, 2, 0), 0.0f) << x;  // at t = 0.5 the quad spans [-1, 1]
    }
    if (X0 > -1 && X1 < 1) {
      EXPECT_EQ(T.at(x, 2, 0), 0.5f) << x;
    }
  }
  // The same seed gives the same bits with one thread or all, with motion as without.
  const std::string moving = blur_scene("eye_end = [-1, 0, 5]", "translate_end = [2, 0, 0]\nrotate_end = [0, 0, 30]");
  const AovFrame a = render_text(moving, 8, 1), b = render_text(moving, 8, 2);
  const Image &fa = a.layer(layer::kColor), &fb = b.layer(layer::kColor);
  ASSERT_EQ(fa.size(), fb.size());
  for (std::size_t k = 0; k < fa.size(); ++k) ASSERT_EQ(fa.data()[k], fb.data()[k]) << k;
}

TEST(MotionBlur, RotationStepsFollowTheArcAndEndAtTheEndTransform) {
  // A box turning 90 degrees about y: 19 time steps (one per 5 degrees); every corner keeps its
  // distance from the axis at every step, and the last step is the box built at the end
  // transform (float rounding of the inverse-then-forward transform: 1e-5).
  rt::Transform start, end;
  start.translate = Vec3(1, 0, 0);
  end = start;
  end.rot_deg = Vec3(0, 90, 0);
  rt::MeshBuilder a, b;
  rt::build_box(a, Vec3(0.4f, 0.2f, 0.6f), start, 1, 1, 0);
  rt::build_box(b, Vec3(0.4f, 0.2f, 0.6f), end, 1, 1, 0);
  rt::add_motion(a.mesh, start, end);
  ASSERT_EQ(a.mesh.time_steps(), 19u);
  for (const auto& step : a.mesh.later_positions)
    for (std::size_t i = 0; i < step.size(); ++i) {
      const Vec3 p0 = a.mesh.positions[i] - start.translate, p = step[i] - start.translate;
      EXPECT_NEAR(std::hypot(p.x, p.z), std::hypot(p0.x, p0.z), 1e-5) << i;
      EXPECT_NEAR(p.y, p0.y, 1e-5) << i;
    }
  const auto& last = a.mesh.later_positions.back();
  for (std::size_t i = 0; i < last.size(); ++i) EXPECT_NEAR(rt::length(last[i] - b.mesh.positions[i]), 0.0f, 1e-5f) << i;
  // Translation alone: two steps, Embree's linear interpolation is then exact.
  rt::MeshBuilder c;
  rt::build_box(c, Vec3(1.0f), start, 1, 1, 0);
  rt::Transform moved = start;
  moved.translate = Vec3(3, 0, 0);
  rt::add_motion(c.mesh, start, moved);
  EXPECT_EQ(c.mesh.time_steps(), 2u);
}

// ---- Alpha cut-outs ----
//
// A black (albedo 0) quad 4 x 4 at z = 0 whose opacity is a checker of 1 x 1 cells (white
// opaque, black a hole), seen squarely from z = 5 with a field of view that shows exactly
// [-1, 1]^2: four cells, the lower-left and upper-right opaque (cell (i, j) = floor(X + 2),
// floor(Y + 2); opaque where i + j is even). Cell edges fall on pixel edges (32 x 32).
std::string cutout_scene(const std::string& extra = "") {
  return "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 22.619864948040426\n"
         "[sky]\ntype = \"constant\"\ncolor = [1, 1, 1]\n"
         "[textures.mask]\ntype = \"checker\"\nscale = 4\ncolor_a = [1, 1, 1]\ncolor_b = [0, 0, 0]\n"
         "[materials.leaf]\nalbedo = [0, 0, 0]\nopacity = \"mask\"\n"
         "[[objects]]\ntype = \"quad\"\nmaterial = \"leaf\"\nvertices = [-2, -2, 0,  2, -2, 0,  2, 2, 0,  -2, 2, 0]\n" +
         extra;
}

// A 32 x 32, 4-spp frame of a scene's text.
AovFrame render_32(const std::string& text) {
  test::TempDir dir;
  auto scene = load_scene(test::write_text(dir.file("scene.toml"), text));
  RenderSettings s;
  s.width = 32;
  s.height = 32;
  s.spp = 4;
  return render_frame(*scene, s);
}

TEST(Cutout, CameraRaysAndEveryLayerSeeTheHoles) {
  const AovFrame f = render_32(cutout_scene());
  const Image& F = f.layer(layer::kColor);
  const Image& N = f.layer(layer::kNormal);
  const Image& Z = f.layer(layer::kDepth);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x) {
      if (x == 15 || x == 16 || y == 15 || y == 16) continue;  // samples within rounding of a cell edge
      const bool left = x < 16, bottom = y >= 16;
      const bool opaque = left == bottom;
      // Opaque: black, facing the camera, 5 to 5.2 away (the distance along the ray, 5 / cos of
      // at most 16 degrees); a hole: the sky, no normal, no depth.
      EXPECT_EQ(F.at(x, y, 0), opaque ? 0.0f : 1.0f) << x << "," << y;
      EXPECT_EQ(N.at(x, y, 2), opaque ? 1.0f : 0.0f) << x << "," << y;
      if (opaque) {
        EXPECT_GT(Z.at(x, y, 0), 4.999f) << x << "," << y;
        EXPECT_LT(Z.at(x, y, 0), 5.21f) << x << "," << y;
      } else {
        EXPECT_EQ(Z.at(x, y, 0), 0.0f) << x << "," << y;
      }
    }
}

TEST(Cutout, ShadowRaysAndPacketsPassThroughTheHoles) {
  test::TempDir dir;
  auto scene = load_scene(test::write_text(dir.file("cut.toml"), cutout_scene()));
  // Closest hits: through a hole nothing is hit; on an opaque cell the quad is.
  rt::SurfaceHit hit;
  EXPECT_FALSE(scene->intersect(rt::Ray{Vec3(0.5f, -0.5f, 5), Vec3(0, 0, -1)}, hit));
  ASSERT_TRUE(scene->intersect(rt::Ray{Vec3(-0.5f, -0.5f, 5), Vec3(0, 0, -1)}, hit));
  EXPECT_NEAR(hit.t, 5.0f, 1e-5f);
  // Shadow rays, one by one and as packets (16 and a remainder), agree on every ray: a grid of
  // 7 x 7 points across the four cells, some 0.05 from a cell edge, none on one (a ray along an
  // edge meets the texture's u = 0.5 within rounding, and which side it lands on is Embree's
  // last bit: it changed with Embree's kernels).
  std::vector<rt::Ray> rays;
  std::vector<std::uint8_t> expected;
  for (int j = 0; j < 7; ++j)
    for (int i = 0; i < 7; ++i) {
      const float X = -1.75f + 0.6f * i, Y = -1.75f + 0.6f * j;
      rays.push_back(rt::Ray{Vec3(X, Y, -1), Vec3(0, 0, 1), 10});
      const int cx = int(std::floor(X + 2)), cy = int(std::floor(Y + 2));
      expected.push_back((cx + cy) % 2 == 0 ? 1 : 0);
    }
  std::vector<std::uint8_t> hidden(rays.size());
  scene->occluded(rays.data(), int(rays.size()), hidden.data());
  for (std::size_t k = 0; k < rays.size(); ++k) {
    EXPECT_EQ(scene->occluded(rays[k]) ? 1 : 0, expected[k]) << k;
    EXPECT_EQ(hidden[k], expected[k]) << k;
  }
}

TEST(Cutout, ShadowsOnTheFloorHaveTheHolesShape) {
  // A sun straight above a floor of albedo 0.5; the cut-out quad, turned horizontal, hangs 1
  // above it, and a camera under the quad looks straight down. No sky, and the quad's underside
  // is black, so a floor point under a hole shows only the sun's direct light, 0.5 E / pi
  // (E = 3: the irradiance on a surface facing the sun), and under an opaque cell nothing. The
  // sun's disc (0.27 degrees) casts a penumbra of 0.005 about each cell edge (X, Z = -1, 0, 1:
  // the image's middle and its border), inside the pixels left out there.
  const std::string text =
      "[camera]\neye = [0, 0.5, 0]\nlook_at = [0, 0, 0]\nup = [0, 0, -1]\nvfov = 126.86989764584402\n"
      "[sun]\ndirection = [0, 1, 0]\nirradiance = [3, 3, 3]\n"
      "[textures.mask]\ntype = \"checker\"\nscale = 4\ncolor_a = [1, 1, 1]\ncolor_b = [0, 0, 0]\n"
      "[materials.leaf]\nalbedo = [0, 0, 0]\nopacity = \"mask\"\n[materials.floor]\nalbedo = [0.5, 0.5, 0.5]\n"
      "[[objects]]\ntype = \"quad\"\nmaterial = \"leaf\"\nvertices = [-2, 1, 2,  2, 1, 2,  2, 1, -2,  -2, 1, -2]\n"
      "[[objects]]\ntype = \"quad\"\nmaterial = \"floor\"\nsize = [10, 10]\n";
  const AovFrame f = render_32(text);
  const Image& F = f.layer(layer::kColor);
  // vfov 2 atan(2): the camera at height 0.5 sees the floor's [-1, 1]^2, one cell per quadrant.
  int lit = 0, dark = 0;
  const double sunlit = 0.5 * 3.0 / 3.14159265358979;
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x) {
      auto edge = [](int i) { return i == 0 || i == 15 || i == 16 || i == 31; };
      if (edge(x) || edge(y)) continue;
      // World X grows with x; with up = -z, image rows go towards +z as y grows, so the quad's
      // (u, v) cell of floor point (X, Z) is (floor(X + 2), floor(2 - Z)).
      const double X = (x + 0.5) / 16 - 1, Z = (y + 0.5) / 16 - 1;
      const int cx = int(std::floor(X + 2)), cy = int(std::floor(2 - Z));
      const bool shadowed = (cx + cy) % 2 == 0;
      const float v = F.at(x, y, 0);
      if (shadowed) {
        // Only a BSDF-sampled ray through a neighbouring hole onto the sun's disc lights it, with
        // the power heuristic's weight of ~1e-9 against the light sample's density.
        EXPECT_LT(v, 1e-4f) << x << "," << y;
        ++dark;
      } else {
        // Each sample is the sun's cone sample: cos and the cone's density vary by 1e-5.
        EXPECT_NEAR(v, sunlit, 1e-3 * sunlit) << x << "," << y;
        ++lit;
      }
    }
  EXPECT_GT(lit, 350);
  EXPECT_GT(dark, 350);
}

// ---- Refusals ----

TEST(MotionAndCutouts, BadValuesAreRefusedNamingFileLineAndKey) {
  const std::string moving = blur_scene("", "translate_end = [2, 0, 0]");
  auto with_shutter = [&](const std::string& s) {
    std::string t = moving;
    return t.replace(t.find("shutter = [0, 1]"), 16, s);
  };
  test::expect_scene_refused(with_shutter("shutter = [0.6, 0.2]"), "shutter");  // opens after it closes
  test::expect_scene_refused(with_shutter("shutter = [0, 2]"), "shutter");      // outside the frame interval
  test::expect_scene_refused(with_shutter("shutter = [0.5]"), "shutter");
  test::expect_scene_refused(with_shutter("shutter = [nan, 1]"), "shutter");
  test::expect_scene_refused(blur_scene("eye_end = [0, 0, 0]", ""), "look_at_end");  // looks at itself
  test::expect_scene_refused(blur_scene("", "translate_end = [2, 0, 0]\nrepeat = 2\nrepeat_offset = [0, 1, 0]"), "repeat");
  test::expect_scene_refused(blur_scene("", "rotate_end = [0, 0, inf]"), "rotate_end");
  test::expect_scene_refused(blur_scene("", "scale_end = 0"), "scale_end");
  // A moving emitter, and motion keys on a light.
  std::string glow = moving;
  glow.replace(glow.find("albedo = [0.5, 0.5, 0.5]"), 24, "emission = [1, 1, 1]");
  test::expect_scene_refused(glow, "translate_end");
  test::expect_scene_refused(blur_scene("", "") +
                     "[[lights]]\ntype = \"quad\"\nsize = [1, 1]\nemission = [1, 1, 1]\ntranslate_end = [1, 0, 0]\n",
                 "translate_end");
  // Cut-outs: an unknown texture; an image of three channels (which one is coverage?).
  std::string unknown = cutout_scene();
  unknown.replace(unknown.find("opacity = \"mask\""), 16, "opacity = \"mask2\"");
  test::expect_scene_refused(unknown, "opacity");
  test::TempDir dir;
  test::write_exr(dir.file("rgb.exr"), 2, 2, {{"R", {1, 0, 1, 0}}, {"G", {1, 0, 1, 0}}, {"B", {1, 0, 1, 0}}});
  std::string rgb = cutout_scene();
  rgb.replace(rgb.find("[textures.mask]\ntype = \"checker\""), 32,
              "[textures.mask]\ntype = \"image\"\nfile = \"" + dir.file("rgb.exr") + "\"\n[textures.unused]\ntype = \"checker\"");
  test::expect_scene_refused(rgb, "3 channels");
}

TEST(Cutout, AGreyOrAlphaImageIsACoverageMask) {
  // One channel (grey) and four (RGBA: the alpha, never the colour) are accepted as masks; the
  // left half of the 2 x 1 mask is opaque.
  test::TempDir dir;
  test::write_exr(dir.file("grey.exr"), 2, 1, {{"Y", {1, 0}}});
  test::write_exr(dir.file("rgba.exr"), 2, 1, {{"R", {0, 1}}, {"G", {0, 1}}, {"B", {0, 1}}, {"A", {1, 0}}});
  for (const char* file : {"grey.exr", "rgba.exr"}) {
    std::string text = cutout_scene();
    text.replace(text.find("[textures.mask]\ntype = \"checker\""), 32,
                 "[textures.mask]\ntype = \"image\"\nfile = \"" + dir.file(file) + "\"\n[textures.unused]\ntype = \"checker\"");
    auto scene = load_scene(test::write_text(dir.file("m.toml"), text));
    // u = (X + 2) / 4: the texels' centres are at u = 0.25 (opaque) and 0.75 (a hole).
    rt::SurfaceHit hit;
    EXPECT_TRUE(scene->intersect(rt::Ray{Vec3(-1.0f, 0.3f, 5), Vec3(0, 0, -1)}, hit)) << file;
    EXPECT_FALSE(scene->intersect(rt::Ray{Vec3(1.0f, 0.3f, 5), Vec3(0, 0, -1)}, hit)) << file;
  }
}

}  // namespace
}  // namespace dnb
