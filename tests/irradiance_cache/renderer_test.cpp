// The irradiance_cache method end to end with the shared tracer: analytic scenes, thread-count
// determinism, and its parameters' validation through the registry.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>


#include "core/errors.h"
#include "denoisers/method.h"
#include "test_util.h"
#include "thread_count.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace dnb {
namespace {

std::string write(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

MethodResult render(const Scene& scene, int w, int h, const std::map<std::string, std::string>& settings) {
  auto m = MethodRegistry::global().create("irradiance_cache", settings);
  return run_method(*m, MethodInput{.scene = &scene, .sample_budget = 16, .width = w, .height = h, .seed = 7});
}

double channel_mean(const Image& img, int c) {
  double s = 0;
  for (int y = 0; y < img.height(); ++y)
    for (int x = 0; x < img.width(); ++x) s += img.at(x, y, c);
  return s / double(img.pixel_count());
}

TEST(IrradianceCacheRenderer, PlaneUnderConstantSkyIsExact) {
  // Constant irradiance: a plane of albedo 0.5 under a constant sky L and nothing else. The sky
  // is sampled by a cosine about the normal, so every light sample estimates D = L exactly;
  // every gather ray escapes, so I = 0; F = 0.5 L to float rounding (1e-5).
  test::TempDir dir;
  auto scene = load_scene(write(dir.file("sky.toml"),
                                "[camera]\neye = [0.0, 1.0, 0.2]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 10.0\n"
                                "[sky]\ntype = \"constant\"\ncolor = [0.8, 0.6, 0.4]\n"
                                "[materials.plane]\nalbedo = [0.5, 0.5, 0.5]\n"
                                "[[objects]]\ntype = \"quad\"\nmaterial = \"plane\"\nsize = [1000.0, 1000.0]\n"));
  MethodResult r = render(*scene, 12, 8, {{"pixel_samples", "2"}, {"gather_theta_cells", "4"}, {"gather_phi_cells", "8"}});
  const float expected[3] = {0.4f, 0.3f, 0.2f};
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 12; ++x)
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(r.image.at(x, y, c), expected[c], 1e-5f) << x << "," << y;
  EXPECT_GT(r.stats.counters.at("records"), 0);
  EXPECT_EQ(r.stats.counters.at("records"), r.stats.counters.at("records_overture") + r.stats.counters.at("records_final"));
}

TEST(IrradianceCacheRenderer, WhiteFurnaceSphere) {
  // Inside a closed sphere of albedo a emitting Le, paths of at most D segments bring
  // Le (1 - a^D) / (1 - a) (tests/tracer's furnace). Here D comes from light samples and I from
  // cached gathers; the image mean is compared with 2%: the mean over 192 pixels of 4 samples
  // x 4 light samples, plus a few dozen records of 8 x 24 Russian-rouletted paths, has a
  // relative standard error below 0.5% (measured over seeds: 0.2-0.3%).
  test::TempDir dir;
  const double a = 0.6, le = 0.7;
  auto scene = load_scene(write(dir.file("furnace.toml"),
                                "[camera]\neye = [0, 0, 0]\nlook_at = [0, 0, -1]\nvfov = 70\n"
                                "[materials.wall]\nalbedo = [0.6, 0.6, 0.6]\nemission = [0.7, 0.7, 0.7]\n"
                                "[[objects]]\ntype = \"sphere\"\nmaterial = \"wall\"\nradius = 1.0\ninward = true\n"
                                "smooth = false\nsegments = 24\n"));
  MethodResult r = render(*scene, 16, 12,
                          {{"pixel_samples", "4"}, {"direct_samples", "4"}, {"gather_theta_cells", "8"},
                           {"gather_phi_cells", "24"}});
  const double expected = le * (1 - std::pow(a, 8)) / (1 - a);
  EXPECT_NEAR(channel_mean(r.image, 0), expected, 0.02 * expected);
}

TEST(IrradianceCacheRenderer, SameImageForAnyThreadCount) {
  auto scene = load_scene("cornell-box");
  const std::map<std::string, std::string> s = {
      {"pixel_samples", "1"}, {"direct_samples", "1"}, {"gather_theta_cells", "4"}, {"gather_phi_cells", "8"},
      {"overture_stride", "8"}, {"overture_min_stride", "2"}};
  MethodResult one, many;
  EXPECT_EQ(test::run_on_threads(1, [&] { one = render(*scene, 40, 30, s); }), 1);
  ASSERT_GT(test::run_on_threads(4, [&] { many = render(*scene, 40, 30, s); }), 1)
      << "the many-thread run had one thread: the comparison would be 1 against 1";
  ASSERT_EQ(one.image.size(), many.image.size());
  for (std::size_t i = 0; i < one.image.size(); ++i) ASSERT_EQ(one.image.data()[i], many.image.data()[i]) << i;
  EXPECT_EQ(one.stats.counters.at("records"), many.stats.counters.at("records"));
  EXPECT_GT(channel_mean(one.image, 1), 0.0);
}

TEST(IrradianceCacheRenderer, BadParametersNameTheParameter) {
  const auto& reg = MethodRegistry::global();
  auto refused = [&](const std::map<std::string, std::string>& s, const std::string& name) {
    try {
      reg.create("irradiance_cache", s);
      ADD_FAILURE() << "accepted " << name;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  };
  refused({{"min_pixel_spacing", "-1"}}, "min_pixel_spacing");
  refused({{"max_pixel_spacing", "-0.5"}}, "max_pixel_spacing");
  refused({{"gather_theta_cells", "0"}}, "gather_theta_cells");
  refused({{"gather_phi_cells", "0"}}, "gather_phi_cells");
  refused({{"kappa", "0"}}, "kappa");
  refused({{"min_pixel_spacing", "20"}, {"max_pixel_spacing", "10"}}, "min_pixel_spacing");
  refused({{"overture_stride", "4"}, {"overture_min_stride", "8"}}, "overture_min_stride");
  EXPECT_EQ(reg.info("irradiance_cache").kind, MethodKind::Renderer);
}

TEST(IrradianceCacheRenderer, RefusesToRunWithoutAScene) {
  auto m = MethodRegistry::global().create("irradiance_cache");
  EXPECT_THROW(run_method(*m, MethodInput{.width = 4, .height = 4}), InputError);
}

}  // namespace
}  // namespace dnb
