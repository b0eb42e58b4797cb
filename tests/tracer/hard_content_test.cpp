// The hard materials and the thin lens in whole renders: white furnaces (a sphere of each
// material under a uniform sky), the decomposition F = (D + I) * T + R + E on every pixel of a
// frame that has all of them, depth of field against the pinhole, and the loader's refusals.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "core/errors.h"
#include "frame_checks.h"
#include "test_util.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

// A sphere of `material` (the lines of a [materials.ball] table) under a constant sky of
// radiance 1, filling the middle of a 24 x 24 image seen from outside; every pixel off the
// sphere sees the sky.
std::string ball_scene(const std::string& material, bool smooth_normals = true) {
  return "[camera]\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\nvfov = 45\n"
         "[sky]\ntype = \"constant\"\ncolor = [1, 1, 1]\n"
         "[materials.ball]\n" + material +
         "\n[[objects]]\ntype = \"sphere\"\nmaterial = \"ball\"\nradius = 1.0\nsegments = 48\nsmooth = " +
         (smooth_normals ? "true" : "false") + "\n";
}

struct Mean {
  double mean = 0, se = 0;
};
Mean mean_of(const AovFrame& f, int c) {
  Mean m;
  test::image_mean(f.layer(layer::kColor), f.layer(layer::kVariance), c, m.mean, m.se);
  return m;
}

AovFrame render_ball(const std::string& material, int spp, int max_depth = 64, bool smooth_normals = true) {
  test::TempDir dir;
  auto scene = load_scene(test::write_text(dir.file("ball.toml"), ball_scene(material, smooth_normals)));
  RenderSettings s;
  s.width = 24;
  s.height = 24;
  s.spp = spp;
  s.max_depth = max_depth;
  return render_frame(*scene, s);
}

TEST(HardFurnace, SmoothWhiteConductorReturnsTheSkyExactly) {
  // F = 1 (Schlick tint 1): one mirror bounce on a convex sphere, then the sky. No random number
  // changes any sample's value, so every pixel is 1 to float rounding (flat facets: the shading
  // normal is the facet's, no ray is sent below the surface).
  const AovFrame f = render_ball("type = \"conductor\"\nschlick = true\ntint = [1, 1, 1]", 4, 8, false);
  const Image& F = f.layer(layer::kColor);
  for (int y = 0; y < 24; ++y)
    for (int x = 0; x < 24; ++x)
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(F.at(x, y, c), 1.0f, 1e-5f) << x << "," << y;
}

TEST(HardFurnace, SmoothGlassAndPlasticOfAlbedoOneReturnTheSky) {
  // Clear glass: reflection and refraction are chosen with their Fresnel probabilities, so every
  // escaping path has weight 1 (the 1 / eta^2 of entering is undone on leaving); plastic of
  // albedo 1: the coat's F and the base's 1 - F (tests/tracer/bsdf_test.cpp) add to 1. The mean
  // over the image is 1 within 5 standard errors (Russian roulette makes the samples differ), plus
  // 2e-3 for the paths cut at 64 segments (glass traps some rays by total internal reflection).
  for (const char* m : {"type = \"dielectric\"\nior = 1.5", "type = \"plastic\"\nalbedo = [1, 1, 1]\nior = 1.5"}) {
    const AovFrame f = render_ball(m, 64);
    const Mean r = mean_of(f, 1);
    EXPECT_NEAR(r.mean, 1.0, 5 * r.se + 2e-3) << m;
    EXPECT_GT(r.se, 0) << m;
    EXPECT_EQ(f.meta.dropped_samples, 0) << m;
  }
}

TEST(HardFurnace, RoughLobesLoseTheirSingleScatteringShareAndNoMore) {
  // Rough GGX lobes drop the light their microfacets shadow (single scattering): the ball is
  // darker than the sky, more so when rougher, never brighter than it. The pixels off the
  // sphere are exactly 1, so the image mean lies between the sphere's share of the image times
  // the lobe's lowest albedo and 1.
  double previous = 1.0 + 1e-9;
  for (const char* rough : {"0.1", "0.4", "0.9"}) {
    const AovFrame f = render_ball(std::string("type = \"conductor\"\nschlick = true\ntint = [1, 1, 1]\nroughness = ") + rough, 64);
    const Mean r = mean_of(f, 0);
    EXPECT_LT(r.mean, previous + 5 * r.se) << rough;
    EXPECT_GT(r.mean, 0.6) << rough;
    previous = r.mean;
  }
  EXPECT_LT(previous, 0.97);  // alpha 0.9 loses a visible share
  for (const char* m : {"type = \"dielectric\"\nior = 1.5\nroughness = 0.3",
                        "type = \"plastic\"\nalbedo = [1, 1, 1]\nroughness = 0.3"}) {
    const Mean r = mean_of(render_ball(m, 64), 1);
    EXPECT_LT(r.mean, 1.0 + 5 * r.se) << m;
    // Rough glass loses at every interface a ray crosses or is reflected inside by (a sphere
    // alone, filling the view: 1.000 smooth, 0.996 at alpha 0.05, 0.983 at 0.1, 0.851 at 0.3).
    EXPECT_GT(r.mean, 0.75) << m;
  }
}

TEST(HardDecomposition, PixelMeansHoldWithEveryHardMaterialAndALens) {
  // Spheres of rough gold, clear and rough glass (one absorbing) and rough plastic on a
  // diffuse checker floor, under a sky and a sun, through a thin lens: the identity of the
  // paper's split holds on every pixel as on the old scenes (frame_checks.h gives the tolerance).
  test::TempDir dir;
  const std::string text =
      "[camera]\neye = [0, 1.2, 4]\nlook_at = [0, 0.4, 0]\nvfov = 45\naperture_radius = 0.05\nfocus_distance = 4\n"
      "[sky]\ntype = \"constant\"\ncolor = [0.6, 0.7, 0.9]\n"
      "[sun]\ndirection = [0.3, 1, 0.2]\nirradiance = [4, 3.8, 3.5]\nangular_radius = 2\n"
      "[textures.check]\ntype = \"checker\"\nscale = 8\n"
      "[materials.floor]\nalbedo = [0.8, 0.8, 0.8]\ntexture = \"check\"\n"
      "[materials.gold]\ntype = \"conductor\"\nmetal = \"Au\"\nroughness = 0.2\n"
      "[materials.brushed]\ntype = \"conductor\"\nmetal = \"Al\"\nroughness_x = 0.05\nroughness_y = 0.4\n"
      "[materials.glass]\ntype = \"dielectric\"\nior = 1.5\nabsorption = [0.5, 0.1, 0.05]\n"
      "[materials.frosted]\ntype = \"dielectric\"\nior = 1.45\nroughness = 0.25\n"
      "[materials.red]\ntype = \"plastic\"\nalbedo = [0.7, 0.1, 0.1]\nroughness = 0.15\n"
      "[[objects]]\ntype = \"quad\"\nmaterial = \"floor\"\nsize = [8, 8]\n"
      "[[objects]]\ntype = \"sphere\"\nmaterial = \"gold\"\nradius = 0.4\ntranslate = [-1.2, 0.4, 0]\n"
      "[[objects]]\ntype = \"sphere\"\nmaterial = \"glass\"\nradius = 0.4\ntranslate = [-0.4, 0.4, 0]\n"
      "[[objects]]\ntype = \"sphere\"\nmaterial = \"frosted\"\nradius = 0.4\ntranslate = [0.4, 0.4, 0]\n"
      "[[objects]]\ntype = \"sphere\"\nmaterial = \"red\"\nradius = 0.4\ntranslate = [1.2, 0.4, 0]\n"
      "[[objects]]\ntype = \"box\"\nmaterial = \"brushed\"\nsize = [0.5, 0.3, 0.5]\ntranslate = [0, 0.15, -1.2]\n";
  auto scene = load_scene(test::write_text(dir.file("hard.toml"), text));
  RenderSettings s;
  s.width = 64;
  s.height = 40;
  s.spp = 16;
  const AovFrame f = render_frame(*scene, s);
  test::expect_split_holds(f);
  test::expect_specular_split_holds(f);
  const Image& T = f.layer(layer::kAlbedo);
  const Image& R = f.layer(layer::kReflection);
  int glossy_pixels = 0, refracting = 0, reflecting = 0;
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x) {
      if (R.at(x, y, 0) > 0 && T.at(x, y, 1) < 0.5f) ++glossy_pixels;
      if (f.layer(layer::kTransIndirect).at(x, y, 1) > 0) ++refracting;  // the glass balls
      if (f.layer(layer::kGlossDirect).at(x, y, 1) > 0) ++reflecting;     // the sun in gold and plastic
    }
  EXPECT_GT(glossy_pixels, 100);  // the spheres are there and reflect
  EXPECT_GT(refracting, 30);
  EXPECT_GT(reflecting, 30);
  EXPECT_EQ(f.meta.dropped_samples, 0);
}

TEST(ThinLens, TheFocusPlaneStaysSharpAndTheRestBlurs) {
  // A checker plane facing the camera at distance 4. Focused on it, the lens's rays through one
  // pixel meet the plane at one point: the image is the pinhole's, within noise (the plane is
  // diffuse, lit by a uniform sky: its radiance does not depend on the direction it is seen
  // from). Focused at 1, each pixel averages a disc of the plane, so the checker's contrast
  // (the spread of pixel values) falls far below the pinhole's.
  auto render = [](const std::string& lens) {
    test::TempDir dir;
    const std::string text = "[camera]\neye = [0, 0, 4]\nlook_at = [0, 0, 0]\nvfov = 30\n" + lens +
                             "\n[sky]\ntype = \"constant\"\ncolor = [1, 1, 1]\n"
                             "[textures.check]\ntype = \"checker\"\nscale = 6\n"
                             "[materials.plane]\nalbedo = [0.9, 0.9, 0.9]\ntexture = \"check\"\n"
                             "[[objects]]\ntype = \"quad\"\nmaterial = \"plane\"\nsize = [6, 6]\nrotate = [90, 0, 0]\n";
    auto scene = load_scene(test::write_text(dir.file("lens.toml"), text));
    RenderSettings s;
    s.width = 32;
    s.height = 32;
    s.spp = 64;
    s.max_depth = 2;
    return render_frame(*scene, s);
  };
  auto spread = [](const AovFrame& f) {
    const Image& F = f.layer(layer::kColor);
    double s = 0, q = 0;
    const double n = double(F.pixel_count());
    for (int y = 0; y < F.height(); ++y)
      for (int x = 0; x < F.width(); ++x) {
        s += F.at(x, y, 1);
        q += double(F.at(x, y, 1)) * F.at(x, y, 1);
      }
    return std::sqrt(q / n - (s / n) * (s / n));
  };
  const AovFrame pinhole = render("");
  const AovFrame focused = render("aperture_radius = 0.2\nfocus_distance = 4");
  const AovFrame blurred = render("aperture_radius = 0.2\nfocus_distance = 1");
  // Per pixel, focused against pinhole: 5 standard errors of the difference, from both frames'
  // variances of the mean.
  const Image& a = pinhole.layer(layer::kColor);
  const Image& b = focused.layer(layer::kColor);
  const Image& va = pinhole.layer(layer::kVariance);
  const Image& vb = focused.layer(layer::kVariance);
  int far = 0;
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x)
      if (std::fabs(a.at(x, y, 1) - b.at(x, y, 1)) > 5 * std::sqrt(va.at(x, y, 1) + vb.at(x, y, 1)) + 1e-6) ++far;
  EXPECT_LE(far, 3);  // 1024 pixels at 5 sigma: expect none; allow a checker-edge pixel or three
  EXPECT_GT(spread(pinhole), 0.2);  // the checker (0.9 x 0.8 against 0.9 x 0.2) is resolved
  EXPECT_LT(spread(blurred), 0.5 * spread(pinhole));
  EXPECT_GT(spread(focused), 0.9 * spread(pinhole));
}

void expect_refused(const std::string& material_or_camera, const std::string& key, bool camera = false) {
  test::TempDir dir;
  const std::string text =
      std::string("[camera]\neye = [0, 0, 3]\nlook_at = [0, 0, 0]\n") + (camera ? material_or_camera : "") +
      "\n[materials.m]\n" + (camera ? "" : material_or_camera) +
      "\n[[objects]]\ntype = \"sphere\"\nmaterial = \"m\"\nradius = 1.0\n";
  const std::string path = test::write_text(dir.file("bad.toml"), text);
  try {
    load_scene(path);
    ADD_FAILURE() << "accepted: " << material_or_camera;
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("bad.toml:"), std::string::npos) << msg;
    EXPECT_NE(msg.find(key), std::string::npos) << msg;
  }
}

TEST(HardMaterials, BadValuesAreRefusedNamingFileLineAndKey) {
  expect_refused("type = \"conductor\"\nroughness = 1.5", "roughness");
  expect_refused("type = \"conductor\"\nroughness = nan", "roughness");
  expect_refused("type = \"conductor\"\nroughness = -0.1", "roughness");
  expect_refused("type = \"conductor\"\nroughness_x = 0.3", "roughness_x");  // one smooth axis, one rough
  expect_refused("type = \"conductor\"\nmetal = \"Pt\"", "metal");
  expect_refused("type = \"conductor\"\nmetal = \"Au\"\neta = [1, 1, 1]\nk = [1, 1, 1]", "metal");
  expect_refused("type = \"conductor\"\neta = [0, 1, 1]\nk = [1, 1, 1]", "eta");
  expect_refused("type = \"conductor\"\neta = [1, 1, 1]", "k");
  expect_refused("type = \"dielectric\"\nior = 0.9", "ior");
  expect_refused("type = \"dielectric\"\nabsorption = [-1, 0, 0]", "absorption");
  expect_refused("type = \"dielectric\"\nthin = true\nroughness = 0.2", "thin");
  expect_refused("type = \"dielectric\"\ntransmittance = [1.5, 1, 1]", "transmittance");
  expect_refused("type = \"diffuse\"\nroughness = 0.2", "roughness");  // not a key of a diffuse material
  expect_refused("type = \"glass\"", "type");
  expect_refused("aperture_radius = -1", "aperture_radius", true);
  expect_refused("aperture_radius = 0.1", "focus_distance", true);  // a lens needs its focus
  expect_refused("aperture_radius = 0.1\nfocus_distance = 0", "focus_distance", true);
}

}  // namespace
}  // namespace dnb
