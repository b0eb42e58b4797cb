// The path tracer against analytic answers (white and mirror furnaces, a mirror floor and a
// coated plane under a sky, a plane under a square light), the paper's decomposition per sample
// and per pixel, and determinism over thread counts.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>

#include "core/errors.h"
#include "frame_checks.h"
#include "test_util.h"
#include "thread_count.h"
#include "tracer/integrator.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

using rt::Vec3;

using test::image_mean;

TEST(WhiteFurnace, ClosedSphereRadianceIsAnalytic) {
  // Inside a closed surface of uniform albedo a and uniform emission Le, every path of k
  // bounces brings Le * a^k: with paths of at most D segments the radiance is
  // Le * (1 - a^D) / (1 - a), whatever the shape. Russian roulette keeps it unbiased.
  test::TempDir dir;
  const double a = 0.6, le = 0.7;
  auto scene = load_scene(test::write_text(dir.file("furnace.toml"), test::furnace_scene(a, le)));
  for (int depth : {1, 3, 8}) {
    RenderSettings s;
    s.width = 24;
    s.height = 16;
    s.spp = 32;
    s.max_depth = depth;
    AovFrame f = render_frame(*scene, s);
    const double expected = le * (1 - std::pow(a, depth)) / (1 - a);
    double mean, se;
    image_mean(f.layer(layer::kColor), f.layer(layer::kVariance), 0, mean, se);
    // 5 standard errors: a false failure has probability < 1e-6 (the mean of 12288 samples is
    // close to normal); the flat-shaded sphere makes the furnace identity exact, and 1e-5
    // covers float accumulation.
    EXPECT_NEAR(mean, expected, 5 * se + 1e-5 * expected) << "max depth " << depth;
    EXPECT_EQ(f.meta.dropped_samples, 0);
  }
}

TEST(MirrorFurnace, ClosedMirrorSphereRadianceIsAnalytic) {
  // A closed mirror sphere (flat-shaded) of tint t emitting Le inwards, the camera at its
  // centre: every mirror bounce lands on the sphere again and multiplies by t, so a path of at
  // most D segments brings Le * (1 + t + ... + t^(D-1)) = Le * (1 - t^D) / (1 - t) per channel,
  // the white furnace's identity with the mirror's tint for the albedo. A mirror draws no random
  // number, and Russian roulette starts only after rr_depth = 3 vertices: up to D = 4 every
  // sample has exactly that value (noise zero), so every pixel is compared, up to float rounding
  // of a sum of at most 4 terms (1e-5 relative is ~100 units of float's 2^-24). D = 8 has
  // roulette: its image mean is compared within 5 standard errors (as the white furnace).
  // The tint differs per channel, so a channel mix-up or a dropped tint shows.
  test::TempDir dir;
  const double t[3] = {0.9, 0.6, 0.3}, le = 0.7;
  std::string text =
      "[camera]\neye = [0, 0, 0]\nlook_at = [0, 0, -1]\nvfov = 70\n"
      "[materials.wall]\ntype = \"mirror\"\ntint = [0.9, 0.6, 0.3]\nemission = [0.7, 0.7, 0.7]\n"
      "[[objects]]\ntype = \"sphere\"\nmaterial = \"wall\"\nradius = 1.0\ninward = true\nsmooth = false\n"
      "segments = 24\n";
  auto scene = load_scene(test::write_text(dir.file("mirror_furnace.toml"), text));
  for (int depth : {1, 2, 4, 8}) {
    RenderSettings s;
    s.width = 16;
    s.height = 12;
    s.spp = depth < 8 ? 4 : 64;
    s.max_depth = depth;
    AovFrame f = render_frame(*scene, s);
    const Image& F = f.layer(layer::kColor);
    for (int c = 0; c < 3; ++c) {
      const double expected = le * (1 - std::pow(t[c], depth)) / (1 - t[c]);
      if (depth <= 4) {
        for (int y = 0; y < s.height; ++y)
          for (int x = 0; x < s.width; ++x)
            ASSERT_NEAR(F.at(x, y, c), expected, 1e-5 * expected) << "max depth " << depth << " pixel " << x << ","
                                                                 << y << " channel " << c;
      } else {
        double mean, se;
        image_mean(F, f.layer(layer::kVariance), c, mean, se);
        EXPECT_NEAR(mean, expected, 5 * se + 1e-5 * expected) << "max depth " << depth << " channel " << c;
      }
    }
    EXPECT_EQ(f.meta.dropped_samples, 0);
  }
}

// Renders `scene` and compares each row's mean colour with `radiance(camera ray, channel)`
// averaged over each pixel (the film samples are uniform in it) by the midpoint rule on a
// 16 x 16 sub-grid, whose error (~1e-5 relative) is far below the tolerance: 5 of the row mean's
// standard errors from the renderer's per-pixel variance (12 rows x 3 channels: a false failure
// below 2e-5), plus 1e-5 relative for that rule. Every camera ray must point downwards (at the
// plane below the camera both tests look at).
void expect_rows_match(const Scene& scene, const RenderSettings& s, const std::function<double(const rt::Ray&, int)>& radiance) {
  AovFrame f = render_frame(scene, s);
  const Image& F = f.layer(layer::kColor);
  const Image& var = f.layer(layer::kVariance);
  const int sub = 16;
  for (int y = 0; y < s.height; ++y)
    for (int c = 0; c < 3; ++c) {
      double sum = 0, v = 0, expected = 0;
      for (int x = 0; x < s.width; ++x) {
        sum += F.at(x, y, c);
        v += var.at(x, y, c);
        for (int j = 0; j < sub; ++j)
          for (int i = 0; i < sub; ++i) {
            const rt::Ray r = scene.camera.generate_ray(x + (i + 0.5f) / sub, y + (j + 0.5f) / sub, s.width, s.height);
            ASSERT_LT(r.dir.y, 0.0f);  // every ray hits the plane
            expected += radiance(r, c) / (sub * sub);
          }
      }
      ASSERT_GT(v, 0.0);  // the tolerance below is not vacuous: the variance is reported
      EXPECT_NEAR(sum / s.width, expected / s.width, 5 * std::sqrt(v) / s.width + 1e-5 * expected / s.width)
          << "row " << y << " channel " << c;
    }
  EXPECT_EQ(f.meta.dropped_samples, 0);
}

TEST(Mirror, FloorReflectsTheGradientSkyAboveIt) {
  // A mirror floor (tint t, facing +y) under a gradient sky of zenith Z and horizon H (ground
  // black), seen from above at 6 to 46 degrees below the horizon. A camera ray d is reflected to
  // d' = (d.x, -d.y, d.z), which escapes upwards with c = dot(d', up) = -d.y, so the pixel is
  //   t * (H (1 - sqrt(c)) + Z sqrt(c))            (Sky::radiance's blend above the horizon)
  // averaged over the pixel (the film samples are uniform in it): here by the midpoint rule on
  // a 16 x 16 sub-grid, whose error (~1e-5 relative) is far below the tolerance. A ray reflected
  // downwards, or not at all, would see the black ground. Only the film position is random, so
  // each row mean is compared within 5 of its standard errors (from the renderer's per-pixel
  // variance): 12 rows, a false failure below 1e-5.
  test::TempDir dir;
  const double tint[3] = {0.9, 0.7, 0.5}, Z[3] = {0.2, 0.4, 1.0}, H[3] = {1.0, 0.8, 0.6};
  std::string text =
      "[camera]\neye = [0.0, 1.0, 0.0]\nlook_at = [0.0, 0.0, -2.0]\nvfov = 40\n"
      "[sky]\ntype = \"gradient\"\nzenith = [0.2, 0.4, 1.0]\nhorizon = [1.0, 0.8, 0.6]\nground = [0, 0, 0]\n"
      "[materials.floor]\ntype = \"mirror\"\ntint = [0.9, 0.7, 0.5]\n"
      "[[objects]]\ntype = \"quad\"\nmaterial = \"floor\"\nsize = [1000.0, 1000.0]\n";
  auto scene = load_scene(test::write_text(dir.file("mirror_floor.toml"), text));
  RenderSettings s;
  s.width = 12;
  s.height = 12;
  s.spp = 64;
  expect_rows_match(*scene, s, [&](const rt::Ray& r, int c) {
    const double w = std::sqrt(-double(r.dir.y));
    return tint[c] * (H[c] * (1 - w) + Z[c] * w);
  });
}

// Schlick's approximation of the dielectric Fresnel reflectance, written out again here (the
// coat's Fr, tracer/scene.h), so that a change of the tracer's formula shows.
double schlick(double cos_theta, double ior) {
  const double r0 = (ior - 1) * (ior - 1) / ((ior + 1) * (ior + 1));
  return r0 + (1 - r0) * std::pow(1 - cos_theta, 5);
}

TEST(CoatedPlane, UnderUniformSkyMatchesFresnelBlend) {
  // A coated plane (base albedo A, coat tint t, index n) under a constant sky L, seen at an angle
  // theta from its normal. The coat reflects Fr(cos theta) of the sky as a mirror, times t; the
  // base receives 1 - Fr and, being Lambertian under a sky that fills its whole hemisphere,
  // returns A L of it (as the SunAndSky test's D = L); nothing else is in the scene, so
  //   F = L * (t Fr(cos theta) + (1 - Fr(cos theta)) A),   Fr = Schlick's, as the tracer's coat.
  // The rows span cos theta = 0.11 .. 0.73 (6 to 47 degrees below the horizon), so Fr runs from
  // 0.60 to 0.08 (n = 1.8, r0 = 0.08). The expectation is averaged over each pixel on a 16 x 16
  // sub-grid (as above). The noise is the lobe choice (coat with probability clamp(Fr, 0.2,
  // 0.8)) and the base's light and BSDF samples; each row mean is compared within 5 of its
  // standard errors from the per-pixel variance (12 rows x 3 channels: a false failure below
  // 2e-5). Rows compare each angle on its own: a wrong Fresnel curve that is too high at some
  // angles and too low at others (exact Fresnel against Schlick) would cancel in an image mean.
  test::TempDir dir;
  const double L = 1.5, ior = 1.8, A[3] = {0.1, 0.2, 0.3}, tint[3] = {1.0, 0.9, 0.8};
  std::string text =
      "[camera]\neye = [0.0, 1.0, 0.0]\nlook_at = [0.0, 0.0, -2.0]\nvfov = 40\n"
      "[sky]\ntype = \"constant\"\ncolor = [1.5, 1.5, 1.5]\n"
      "[materials.plane]\ntype = \"coated\"\nalbedo = [0.1, 0.2, 0.3]\ntint = [1.0, 0.9, 0.8]\nior = 1.8\n"
      "[[objects]]\ntype = \"quad\"\nmaterial = \"plane\"\nsize = [1000.0, 1000.0]\n";
  auto scene = load_scene(test::write_text(dir.file("coated.toml"), text));
  RenderSettings s;
  s.width = 12;
  s.height = 12;
  // Enough samples that Fresnel's exact formula, 0.02 off Schlick's at these angles, is ~10
  // standard errors off in the rows where they differ most.
  s.spp = 4096;
  expect_rows_match(*scene, s, [&](const rt::Ray& r, int c) {
    const double fr = schlick(-double(r.dir.y), ior);
    return L * (tint[c] * fr + (1 - fr) * A[c]);
  });
}

// Irradiance at the origin from a Lambertian rectangle [x1, x2] x [z1, z2] of radiance L at
// height h, parallel to the receiving plane: pi L times the signed corner view factors.
double rect_irradiance(double L, double h, double x1, double x2, double z1, double z2) {
  auto f = [h](double x, double z) {
    double ax = std::sqrt(x * x + h * h), az = std::sqrt(z * z + h * h);
    return (x / ax * std::atan(z / ax) + z / az * std::atan(x / az)) / (2 * M_PI);
  };
  return M_PI * L * (f(x2, z2) - f(x1, z2) - f(x2, z1) + f(x1, z1));
}

TEST(LitPlane, DirectLightMatchesClosedFormIrradiance) {
  test::TempDir dir;
  const double side = 0.2, h = 0.3, le = 2.0;
  auto scene = load_scene(test::write_text(dir.file("plane.toml"), test::lit_plane_scene(side, h, le)));
  RenderSettings s;
  s.width = 16;
  s.height = 16;
  s.spp = 64;
  AovFrame f = render_frame(*scene, s);
  const Image& depth = f.layer(layer::kDepth);
  const Image& direct = f.layer(layer::kDirect);
  const Image& indirect = f.layer(layer::kIndirect);
  double sum = 0, expected = 0;
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x) {
      // The point seen through the pixel centre (the irradiance varies by < 1e-4 over a pixel).
      rt::Ray r = scene->camera.generate_ray(x + 0.5f, y + 0.5f, s.width, s.height);
      Vec3 p = r.origin + r.dir * depth.at(x, y, 0);
      ASSERT_NEAR(p.y, 0.0, 1e-4);
      // D is the light a white Lambertian reflects: E / pi.
      expected += rect_irradiance(le, h, -side / 2 - p.x, side / 2 - p.x, -side / 2 - p.z, side / 2 - p.z) / M_PI;
      sum += direct.at(x, y, 1);
      // Nothing but the black back of the light is above the plane: no indirect light.
      EXPECT_EQ(indirect.at(x, y, 1), 0.0f);
    }
  double mean, se;
  image_mean(direct, f.layer(layer::kDirectVariance), 1, mean, se);
  // 5 standard errors plus 2e-4 relative for the pixel-footprint curvature of E.
  EXPECT_NEAR(sum / 256, expected / 256, 5 * se + 2e-4 * expected / 256);
  // F = D * albedo.
  EXPECT_NEAR(f.layer(layer::kColor).at(3, 3, 0), 0.5f * direct.at(3, 3, 0), 1e-6);
}

TEST(LitPlane, SphereLightMatchesClosedFormIrradiance) {
  // A sphere of radiance L and radius r whose centre is at distance d from a point, fully above
  // its horizon, gives irradiance pi L (r / d)^2 cos(theta) (theta: angle of the centre from
  // the normal). Sphere lights are sampled by their cone, so this checks that sampling and its
  // density; the 96-segment tessellation lies inside the sphere and subtends ~0.1% less.
  test::TempDir dir;
  const double r = 0.1, h = 0.5, le = 3.0;
  std::string text =
      "[camera]\neye = [0.6, 0.25, 0.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 2.0\n"
      "[materials.plane]\nalbedo = [0.5, 0.5, 0.5]\n"
      "[[objects]]\ntype = \"quad\"\nmaterial = \"plane\"\nsize = [20.0, 20.0]\n"
      "[[lights]]\ntype = \"sphere\"\ncenter = [0.0, 0.5, 0.0]\nradius = 0.1\nsegments = 96\n"
      "emission = [3.0, 3.0, 3.0]\n";
  auto scene = load_scene(test::write_text(dir.file("sphere.toml"), text));
  ASSERT_EQ(scene->sphere_lights.size(), 1u);
  RenderSettings s;
  s.width = 16;
  s.height = 16;
  s.spp = 64;
  AovFrame f = render_frame(*scene, s);
  const Image& depth = f.layer(layer::kDepth);
  double expected = 0;
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x) {
      rt::Ray ray = scene->camera.generate_ray(x + 0.5f, y + 0.5f, s.width, s.height);
      Vec3 p = ray.origin + ray.dir * depth.at(x, y, 0);
      double dx = -p.x, dy = h - p.y, dz = -p.z;
      double d2 = dx * dx + dy * dy + dz * dz;
      expected += M_PI * le * r * r / d2 * (dy / std::sqrt(d2)) / M_PI;
    }
  expected /= s.width * s.height;
  double mean, se;
  image_mean(f.layer(layer::kDirect), f.layer(layer::kDirectVariance), 0, mean, se);
  // 5 standard errors plus 0.3% for the tessellation (inscribed polygon of 96 sides: -0.07%)
  // and the pixel footprint.
  EXPECT_NEAR(mean, expected, 5 * se + 3e-3 * expected);
}

TEST(SunAndSky, PlaneUnderOpenSkyMatchesClosedForm) {
  // A white-equivalent plane (D is untextured) under a constant sky L and a sun of irradiance E
  // at 45 degrees: every direction of the upper hemisphere escapes, so D = L + E cos(45) / pi
  // (the cosine's variation over the 0.27-degree disc is below 1e-5), and nothing is indirect.
  // Sun, sky and BSDF samples are combined by MIS: a wrong density in any would show here.
  test::TempDir dir;
  const double L = 0.8, E = 3.0;
  std::string text =
      "[camera]\neye = [0.0, 1.0, 1.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 10.0\n"
      "[sky]\ntype = \"constant\"\ncolor = [0.8, 0.8, 0.8]\n"
      "[sun]\ndirection = [0.0, 1.0, 1.0]\nirradiance = [3.0, 3.0, 3.0]\n"
      "[materials.plane]\nalbedo = [0.5, 0.5, 0.5]\n"
      "[[objects]]\ntype = \"quad\"\nmaterial = \"plane\"\nsize = [1000.0, 1000.0]\n";
  auto scene = load_scene(test::write_text(dir.file("sky.toml"), text));
  RenderSettings s;
  s.width = 16;
  s.height = 16;
  s.spp = 64;
  AovFrame f = render_frame(*scene, s);
  double mean, se;
  image_mean(f.layer(layer::kDirect), f.layer(layer::kDirectVariance), 0, mean, se);
  const double expected = L + E * std::sqrt(0.5) / M_PI;
  EXPECT_NEAR(mean, expected, 5 * se + 1e-5 * expected);  // 5 standard errors, as above
  double imean, ise;
  image_mean(f.layer(layer::kIndirect), f.layer(layer::kIndirectVariance), 0, imean, ise);
  EXPECT_EQ(imean, 0.0);
}

// A light sample towards the sun and a BSDF sample along the same direction must agree on
// whether the direction is in the sun's disc: the sample's radiance and density are then the
// escaped radiance and density of its direction. Near the disc's rim, a cone sample turned into
// world space can round to just outside it; the sample used to carry the sun's radiance with a
// density that left the sun out (the sky's alone, ~1e5 times smaller), a firefly of ~1e5 with
// weight 1. Under -O1 (the sanitizer build) this made SunAndSky above read 31 against 1.48.
TEST(SunAndSky, ALightSampleAgreesWithItsDirectionAtTheDiscsRim) {
  test::TempDir dir;
  const std::string text =
      "[camera]\neye = [0.0, 1.0, 1.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 10.0\n"
      "[sky]\ntype = \"constant\"\ncolor = [0.8, 0.8, 0.8]\n"
      "[sun]\ndirection = [0.3, 1.0, 0.7]\nirradiance = [3.0, 3.0, 3.0]\n"
      "[materials.plane]\nalbedo = [0.5, 0.5, 0.5]\n"
      "[[objects]]\ntype = \"quad\"\nmaterial = \"plane\"\nsize = [1000.0, 1000.0]\n";
  auto scene = load_scene(test::write_text(dir.file("sun.toml"), text));
  const Vec3 p(0.0f), n(0, 1, 0);
  int sun_samples = 0, outside = 0, mismatches = 0;
  // u1 near 1 puts the sample on the rim; every u0 of the grid picks the sun or the sky.
  for (int i = 0; i < 64; ++i)
    for (int j = 0; j < 512; ++j)
      for (int k = 0; k < 8; ++k) {
        const float u0 = (i + 0.5f) / 64, u1 = 1.0f - std::ldexp(float(j + 1), -20), u2 = (k + 0.5f) / 8;
        rt::LightSample ls;
        if (!scene->sample_light(p, n, u0, u1, u2, ls)) continue;
        const Vec3 L = scene->escaped_radiance(ls.wi);
        const float pdf = scene->escaped_light_pdf(ls.wi, n);
        const bool in_sun = ls.radiance.x > 10.0f;  // the sun's radiance is ~1e5, the sky's 0.8
        sun_samples += in_sun || ls.pdf > 100.0f;
        outside += scene->sun.enabled && rt::dot(ls.wi, scene->sun.direction) < scene->sun.cos_max;
        mismatches += L.x != ls.radiance.x || pdf != ls.pdf;
      }
  ASSERT_GT(sun_samples, 1000) << "the grid must reach the sun";
  EXPECT_EQ(mismatches, 0) << outside << " samples rounded to outside the disc";
}

TEST(Decomposition, HoldsPerSamplePath) {
  auto scene = load_scene("cornell-box");
  rt::PathTracer::Options o;
  o.reflection_levels = 2;
  rt::PathTracer tracer(*scene, o);
  int specular = 0, deep = 0;
  for (int i = 0; i < 4000; ++i) {
    rt::Sampler rng(7, std::uint64_t(i), 0);
    rt::PathContext ctx{rng};
    // Rays over the whole image, denser on the mirror sphere's region to reach level 2.
    float fx = rng.next() * 64, fy = rng.next() * 48;
    if (i % 2) {
      fx = 14 + rng.next() * 10;
      fy = 34 + rng.next() * 10;
    }
    rt::SampleResult r;
    tracer.sample_layers(scene->camera.generate_ray(fx, fy, 64, 48), ctx, r);
    ASSERT_GE(r.levels, 1);
    for (int k = 0; k < r.levels; ++k) {
      const rt::LevelSample& L = r.level[k];
      Vec3 F = L.color();
      ASSERT_TRUE(rt::is_finite(F));
      if (k + 1 < r.levels) {
        // A specular bounce into level k+1: R_k = tint_k * F_{k+1}, bit for bit, and the
        // mirror (or coat) sample carries no diffuse light.
        Vec3 expect = L.tint * r.level[k + 1].color();
        EXPECT_EQ(L.reflection.x, expect.x);
        EXPECT_EQ(L.reflection.y, expect.y);
        EXPECT_EQ(L.reflection.z, expect.z);
        EXPECT_TRUE(rt::is_black(L.direct) && rt::is_black(L.indirect));
        ++specular;
        if (k == 1) ++deep;
      } else if (!rt::is_black(L.direct) || !rt::is_black(L.indirect)) {
        // A diffuse base sample: no reflection term.
        EXPECT_TRUE(rt::is_black(L.reflection));
      }
      if (L.depth == 0) {
        // A miss: only emission.
        EXPECT_TRUE(rt::is_black(L.direct) && rt::is_black(L.indirect) && rt::is_black(L.albedo));
      }
    }
  }
  EXPECT_GT(specular, 100);  // the mirror sphere and coated block were reached
  EXPECT_GT(deep, 0);        // and level 2 (mirror seen in the coat or the sphere)
}

TEST(Decomposition, PixelMeansHoldOnEveryPixel) {
  // D and I are albedo-weighted pixel means (render.cpp), so F = (D + I) * T + R + E holds for
  // the means of every pixel, off the edge set G and on it (silhouettes, the checker floor's
  // texture edges), where plain means would differ by the product-of-means error.
  auto scene = load_scene("cornell-box");
  RenderSettings s;
  s.width = 64;
  s.height = 48;
  s.spp = 16;
  AovFrame f = render_frame(*scene, s);
  test::expect_split_holds(f);
  test::expect_specular_split_holds(f);  // the mirror sphere and the coated block: all gloss
  const Image& G = f.layer(layer::kEdge);
  int edges = 0;
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x)
      if (G.at(x, y, 0) > 0) ++edges;
  EXPECT_GT(edges, 0);
  EXPECT_LT(edges, s.width * s.height / 2);
  ASSERT_TRUE(f.edges.has_value());
  EXPECT_EQ(int(f.edges->size()), edges);
  // Edge sub-pixels: finite, normals of unit length or zero (a sub-pixel on one surface).
  for (const auto& e : f.edges->samples) {
    float n = std::sqrt(e.normal[0] * e.normal[0] + e.normal[1] * e.normal[1] + e.normal[2] * e.normal[2]);
    EXPECT_LE(n, 1.0f + 1e-5f);
    EXPECT_TRUE(std::isfinite(e.direct[0] + e.indirect[0] + e.albedo[0] + e.depth));
  }
}

TEST(Decomposition, ReflectionLevelComposesTheMirrorPixels) {
  // Inside the mirror sphere (not on G) every sample bounces once off the mirror with the same
  // tint, so reflection = refl1.tint * ((D1 + I1) * T1 + R1 + E1) for the pixel means, with the
  // level-1 means taken over those samples (and D1, I1 albedo-weighted like level 0).
  auto scene = load_scene("cornell-box");
  RenderSettings s;
  s.width = 64;
  s.height = 48;
  s.spp = 16;
  AovFrame f = render_frame(*scene, s);
  const Image& R = f.layer(layer::kReflection);
  const Image& tint = f.layer("refl1.tint");
  const Image& D1 = f.layer("refl1.direct");
  const Image& I1 = f.layer("refl1.indirect");
  const Image& T1 = f.layer("refl1.albedo");
  const Image& R1 = f.layer("refl1.reflection");
  const Image& E1 = f.layer("refl1.emission");
  const Image& G = f.layer(layer::kEdge);
  int mirror_pixels = 0;
  for (int y = 0; y < s.height; ++y)
    for (int x = 0; x < s.width; ++x) {
      if (G.at(x, y, 0) > 0 || std::fabs(tint.at(x, y, 0) - 0.95f) > 1e-6f) continue;  // the sphere's tint
      ++mirror_pixels;
      for (int c = 0; c < 3; ++c) {
        double composed = tint.at(x, y, c) * ((double(D1.at(x, y, c)) + I1.at(x, y, c)) * T1.at(x, y, c) +
                                              R1.at(x, y, c) + E1.at(x, y, c));
        // Float rounding only, with u = 2^-24, counted as for level 0: R holds per sample
        // tint * ((d + i) * t + r + e) in float (5 roundings) and its double mean stored as float
        // (1); the composed side holds level 0's 3 (d * t per sample, D1 and T1 stored, D1 * T1)
        // and the stored tint is exact (one float value, 0.95f, on every sample). First order 9u;
        // 12u leaves room for second-order terms (measured worst: 1.9u). The absolute 1e-9 is
        // demodulated()'s other branch, as for level 0.
        const double u = 0x1p-24;
        EXPECT_LE(std::fabs(composed - R.at(x, y, c)), 12 * u * std::fabs(R.at(x, y, c)) + 1e-9) << x << "," << y;
      }
    }
  EXPECT_GT(mirror_pixels, 20);
}

TEST(Determinism, BitIdenticalForOneAndTwoThreads) {
  auto scene = load_scene("cornell-box");
  RenderSettings s;
  s.width = 40;
  s.height = 30;
  s.spp = 9;
  s.threads = 1;
  AovFrame a = render_frame(*scene, s);
  // The tracer's task_arena(2) alone gets one thread on a one-core runner (TBB's worker limit,
  // tests/thread_count.h); run_on_threads lifts that limit and checks two threads really ran.
  s.threads = 2;
  AovFrame b;
  ASSERT_GT(test::run_on_threads(2, [&] { b = render_frame(*scene, s); }), 1)
      << "the two-thread render had one thread: the comparison would be 1 against 1";
  ASSERT_EQ(a.layers().size(), b.layers().size());
  for (const auto& [name, img] : a.layers()) EXPECT_TRUE(img == b.layer(name)) << name;
  EXPECT_TRUE(a.edges == b.edges);
  // The colour sums used by references give the same colour as the frame.
  s.threads = 2;
  ColorSums lo = render_color_sums(*scene, s, 0, 3);  // ends inside a pair: the next range redoes it
  ColorSums hi = render_color_sums(*scene, s, 3, 9);
  lo.add(hi);
  Image m = lo.mean();
  const Image& F = a.layer(layer::kColor);
  for (std::size_t i = 0; i < m.size(); ++i)
    EXPECT_NEAR(m.data()[i], F.data()[i], 1e-6 * std::fabs(F.data()[i]) + 1e-9);
}

// Another seed gives another image of the same scene: the pixels differ (a tracer that ignored
// the seed would repeat the image) but the image means agree (the seed picks samples, not the
// estimate's expectation).
TEST(Determinism, AnotherSeedGivesAnotherImageWithTheSameMean) {
  auto scene = load_scene("cornell-box");
  RenderSettings s;
  s.width = 48;
  s.height = 36;
  s.spp = 64;  // then the standard error of the means' difference is about 1% of the mean
  s.seed = 1;
  const Image a = render_frame(*scene, s).layer(layer::kColor);
  s.seed = 2;
  const Image b = render_frame(*scene, s).layer(layer::kColor);
  const double n = double(a.pixel_count());
  for (int c = 0; c < 3; ++c) {
    // The per-pixel differences d = a - b of two independent renders: their mean is the
    // difference of the image means, and their spread (pixels are independent) gives its
    // standard error sd(d) / sqrt(n). 5 standard errors: a false failure about once in 1.7 million.
    double sum = 0, sq = 0;
    int differ = 0;
    for (int y = 0; y < a.height(); ++y)
      for (int x = 0; x < a.width(); ++x) {
        const double d = double(a.at(x, y, c)) - b.at(x, y, c);
        sum += d;
        sq += d * d;
        if (d != 0) ++differ;
      }
    const double mean = sum / n, sd = std::sqrt(std::max(0.0, (sq - sum * mean) / (n - 1)));
    // Pixels that see only the light or only the background may agree; most must not.
    EXPECT_GT(differ, int(n / 2)) << "channel " << c << ": seeds 1 and 2 gave the same pixels";
    EXPECT_GT(sd, 0.0) << "channel " << c;
    EXPECT_LE(std::fabs(mean), 5 * sd / std::sqrt(n)) << "channel " << c << ": image means differ by " << mean;
  }
}

TEST(Frame, HasEveryChannelOfTheDesign) {
  auto scene = load_scene("cornell-box");
  RenderSettings s;
  s.width = 32;
  s.height = 24;
  s.spp = 4;
  s.reflection_levels = 2;
  AovFrame f = render_frame(*scene, s);
  std::vector<std::string> names = {layer::kColor,    layer::kDirect,   layer::kIndirect,       layer::kAlbedo,
                                    layer::kReflection, layer::kEmission, layer::kNormal,        layer::kDepth,
                                    layer::kVariance, layer::kDirectVariance, layer::kIndirectVariance,
                                    layer::kEdge,     layer::kSamples};
  for (int k = 1; k <= 2; ++k)
    for (const char* b : {layer::kDirect, layer::kIndirect, layer::kAlbedo, layer::kNormal, layer::kDepth,
                          layer::kReflection, layer::kEmission, layer::kTint})
      names.push_back(layer::at_level(k, b));
  for (int h = 0; h < 2; ++h)
    for (const char* b : {layer::kColor, layer::kDirect, layer::kIndirect, layer::kAlbedo, layer::kNormal, layer::kDepth})
      names.push_back(layer::at_half(h, b));
  EXPECT_TRUE(f.missing_channels(names).empty());
  EXPECT_EQ(f.meta.tracer_version, kTracerVersion);
  EXPECT_EQ(f.meta.spp, 4);
  EXPECT_EQ(f.meta.scene, "cornell-box");
  EXPECT_FALSE(f.meta.build_version.empty());
  // The light is seen directly, the mirror sphere reflects something.
  double e = 0, r = 0;
  for (std::size_t i = 0; i < f.layer(layer::kEmission).size(); ++i) e += f.layer(layer::kEmission).data()[i];
  for (std::size_t i = 0; i < f.layer(layer::kReflection).size(); ++i) r += f.layer(layer::kReflection).data()[i];
  EXPECT_GT(e, 0);
  EXPECT_GT(r, 0);
  for (const auto& [name, img] : f.layers()) EXPECT_EQ(count_non_finite(img.view()), 0u) << name;
}

// The half buffers (core/aov_frame.h): half 0 holds the even samples, half 1 the odd ones. At
// 2 spp each is one sample, which render_color_sums traces on its own: the colours must agree
// bit for bit. At 16 spp the two halves' mean is the frame's layer, to float rounding (8
// samples per half; the full sums add the same values in another order: 1e-6 relative).
TEST(HalfBuffers, EachHalfIsTheMeanOfItsOwnSamples) {
  auto scene = load_scene("cornell-box");
  RenderSettings s{.width = 24, .height = 18, .spp = 2, .seed = 1, .threads = 0, .max_depth = 8, .reflection_levels = 0,
                   .edge_subpixels = true, .on_progress = {}};
  AovFrame f = render_frame(*scene, s);
  ASSERT_EQ(f.meta.dropped_samples, 0);
  EXPECT_TRUE(render_color_sums(*scene, s, 0, 1).mean() == f.layer(layer::at_half(0, layer::kColor)));
  EXPECT_TRUE(render_color_sums(*scene, s, 1, 2).mean() == f.layer(layer::at_half(1, layer::kColor)));
  EXPECT_FALSE(f.layer(layer::at_half(0, layer::kColor)) == f.layer(layer::at_half(1, layer::kColor)));

  s.spp = 16;
  f = render_frame(*scene, s);
  ASSERT_EQ(f.meta.dropped_samples, 0);
  for (const char* b : {layer::kColor, layer::kAlbedo, layer::kNormal, layer::kDepth}) {
    const Image &h0 = f.layer(layer::at_half(0, b)), &h1 = f.layer(layer::at_half(1, b)), &full = f.layer(b);
    for (std::size_t k = 0; k < full.size(); ++k)
      ASSERT_NEAR(0.5 * (double(h0.data()[k]) + h1.data()[k]), full.data()[k], 1e-6 * std::fabs(full.data()[k]) + 1e-9)
          << b << " value " << k;
  }
  // D and I are albedo-weighted per half (sum of D T over the half's samples / sum of T), so the
  // halves' D_h T_h add up to the frame's D T: D_0 T_0 + D_1 T_1 = 2 D T for every pixel and
  // channel (8 samples per half; float rounding of the means, 1e-5 relative).
  for (const char* b : {layer::kDirect, layer::kIndirect}) {
    const Image &l0 = f.layer(layer::at_half(0, b)), &l1 = f.layer(layer::at_half(1, b)), &l = f.layer(b);
    const Image &t0 = f.layer(layer::at_half(0, layer::kAlbedo)), &t1 = f.layer(layer::at_half(1, layer::kAlbedo)),
                &t = f.layer(layer::kAlbedo);
    int checked = 0;
    for (std::size_t k = 0; k < l.size(); ++k) {
      const double want = 2.0 * l.data()[k] * t.data()[k];
      const double got = double(l0.data()[k]) * t0.data()[k] + double(l1.data()[k]) * t1.data()[k];
      ASSERT_NEAR(got, want, 1e-5 * std::fabs(want) + 1e-9) << b << " value " << k;
      checked += want > 0;
    }
    EXPECT_GT(checked, int(l.size() / 2)) << b;
  }
}

TEST(Render, BadSettingsAreInputErrors) {
  auto scene = load_scene("cornell-box");
  RenderSettings s;
  s.width = 8;
  s.height = 8;
  s.spp = 0;
  EXPECT_THROW(render_frame(*scene, s), InputError);
  s.spp = 1;
  s.reflection_levels = 99;
  EXPECT_THROW(render_frame(*scene, s), InputError);
}

// The batched direct light (shadow rays traced as Embree packets) equals the one-by-one sum
// bit for bit, on scenes with an area light (cornell-box) and with a sphere lamp, the sun and
// the sky through a window (bedroom); and it sees shadows: some sums are partial.
TEST(DirectLight, BatchedShadowRaysEqualOneByOne) {
  for (const char* name : {"cornell-box", "bedroom"}) {
    auto scene = load_scene(name);
    rt::PathTracer tracer(*scene, {});
    int compared = 0, partial = 0;
    for (int i = 0; i < 400; ++i) {
      rt::Sampler rng(3, std::uint64_t(i), 0);
      rt::SurfaceHit hit;
      if (!scene->intersect(scene->camera.generate_ray(rng.next() * 64, rng.next() * 48, 64, 48), hit)) continue;
      std::vector<std::array<float, 3>> u(21);  // more than one packet of 16
      for (auto& v : u) v = {rng.next(), rng.next(), rng.next()};
      rt::Sampler a(1, 1, 1), b(1, 1, 1);
      rt::PathContext ca{a}, cb{b};
      Vec3 one(0.0f);
      int lit = 0;
      for (const auto& v : u) {
        const Vec3 c = tracer.direct_white(hit, ca, v[0], v[1], v[2]);
        lit += rt::is_black(c) ? 0 : 1;
        one += c;
      }
      const Vec3 batch = tracer.direct_white_sum(hit, cb, u.data(), int(u.size()));
      ASSERT_EQ(one.x, batch.x) << name << " sample " << i;
      ASSERT_EQ(one.y, batch.y);
      ASSERT_EQ(one.z, batch.z);
      EXPECT_EQ(ca.rays, cb.rays);
      ++compared;
      partial += lit > 0 && lit < int(u.size());
    }
    EXPECT_GT(compared, 250) << name;  // camera rays that hit something (286 and more)
    EXPECT_GT(partial, 10) << name;  // penumbrae and partly hidden lights were exercised
  }
}

// Scene::intersect over packets of 16 gives intersect()'s hits one by one, bit for bit, on the
// camera rays of 24 samples per pixel (one packet and a partial one) and on cosine bounce rays
// from their hits; on a scene of diffuse boxes, coated and mirror surfaces (cornell-box), one
// with alpha cut-out leaves (plant: the filter function runs on packets) and one with moving
// geometry and a shutter (motion-room: each lane at its own time). Plant's rays also miss.
TEST(Intersect, PacketsOfSixteenGiveTheHitsOfSingleRays) {
  for (const char* name : {"cornell-box", "plant", "motion-room"}) {
    auto scene = load_scene(name);
    const rt::Camera& cam = scene->camera;
    std::vector<rt::Ray> rays;
    rt::Sampler rng(11, 0, 0);
    for (int px = 0; px < 48; ++px) {
      const float x = rng.next() * 64, y = rng.next() * 48;
      std::vector<rt::Ray> camera;
      for (int s = 0; s < 24; ++s) {
        const float time = cam.has_shutter() ? cam.time_at(rng.next()) : cam.shutter_open;
        camera.push_back(cam.generate_ray_at(x + rng.next(), y + rng.next(), 64, 48, 0, 0, time));
      }
      rays.insert(rays.end(), camera.begin(), camera.end());
      for (const rt::Ray& r : camera) {  // the bounce rays of the same samples
        rt::SurfaceHit h;
        if (!scene->intersect(r, h)) continue;
        const rt::Frame f(h.ns);
        rays.push_back(h.spawn_ray(f.to_world(rt::sample_cosine_hemisphere(rng.next(), rng.next()))));
      }
    }
    std::vector<rt::SurfaceHit> hits(rays.size());
    std::vector<std::uint8_t> found(rays.size(), 7);
    scene->intersect(rays.data(), int(rays.size()), hits.data(), found.data());
    int hit = 0, missed = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
      rt::SurfaceHit one;
      const bool f = scene->intersect(rays[i], one);
      ASSERT_EQ(int(found[i]), f ? 1 : 0) << name << " ray " << i;
      if (!f) {
        ++missed;
        continue;
      }
      ++hit;
      const rt::SurfaceHit& b = hits[i];
      ASSERT_EQ(one.t, b.t) << name << " ray " << i;
      ASSERT_EQ(one.geom, b.geom);
      ASSERT_EQ(one.prim, b.prim);
      ASSERT_EQ(one.front, b.front);
      ASSERT_EQ(one.material, b.material);
      ASSERT_EQ(one.time, b.time);
      ASSERT_EQ(one.u, b.u);
      ASSERT_EQ(one.v, b.v);
      ASSERT_EQ(one.offset, b.offset);
      for (auto [p, q] : {std::pair{one.p, b.p}, {one.ng, b.ng}, {one.ns, b.ns}, {one.albedo, b.albedo}}) {
        ASSERT_EQ(p.x, q.x) << name << " ray " << i;
        ASSERT_EQ(p.y, q.y);
        ASSERT_EQ(p.z, q.z);
      }
    }
    EXPECT_GT(hit, 500) << name;  // 48 pixels x 24 samples, most of them hit, and their bounces
    if (std::string(name) == "plant") {
      EXPECT_GT(missed, 10) << name;  // under an open sky: rays escape
    }
  }
}

}  // namespace
}  // namespace dnb
