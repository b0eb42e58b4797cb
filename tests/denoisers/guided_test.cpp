// guided: the multi-channel guided filter on the illumination, checked against what the model
// promises (an illumination that is linear in the guide is reproduced) and on edges.
#include <gtest/gtest.h>

#include <cmath>

#include "denoisers/illumination.h"
#include "denoisers/method.h"
#include "denoisers/synthetic_frame.h"

namespace dnb {
namespace {

MethodResult run_guided(const AovFrame& f, const std::map<std::string, std::string>& settings = {}) {
  auto m = MethodRegistry::global().create("guided", settings);
  return run_method(*m, {.frame = &f});
}

// He et al.'s local model L = a^T g + b holds exactly when the illumination is an affine
// function of the guide; the filter must then give it back (up to the eps shrinkage: with
// eps = 1e-6 and guide variances of order 1e-2, a relative error below 1e-3).
TEST(Guided, ReproducesIlluminationThatIsLinearInTheGuide) {
  AovFrame f = test::planes_frame(60, 40, 0.0f);
  Image& d = f.layer(layer::kDirect);
  Image& i = f.layer(layer::kIndirect);
  const Image& n = f.layer(layer::kNormal);
  const Image z = normalized_depth(f);
  const Image& t = f.layer(layer::kAlbedo);
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 60; ++x)
      for (int c = 0; c < 3; ++c) {
        d.at(x, y, c) = 1.0f + 0.5f * n.at(x, y, 0) + (0.3f + 0.1f * c) * z.at(x, y, 0) + 0.2f * t.at(x, y, c);
        i.at(x, y, c) = 0.0f;
      }
  MethodResult r = run_guided(f, {{"eps", "1e-6"}, {"radius", "3"}});
  const Image want = compose(illumination(f), f);
  double worst = 0;
  for (std::size_t k = 0; k < want.size(); ++k)
    worst = std::max(worst, std::abs(double(r.image.data()[k]) - want.data()[k]) / want.data()[k]);
  EXPECT_LT(worst, 1e-3);
}

// Noise is removed, and the crease between the two planes (a jump in normal, depth and
// illumination) is kept: the error on the two columns beside it is no larger than a few times
// the error elsewhere, while a guide-less filter (all weights 0, a box mean) smears it.
TEST(Guided, RemovesNoiseAndKeepsTheCrease) {
  AovFrame noisy = test::planes_frame(96, 64, 0.3f);
  const Image truth = test::planes_frame(96, 64, 0.0f).layer(layer::kColor);
  auto crease_mse = [&](const Image& img) {
    double s = 0;
    int n = 0;
    for (int y = 0; y < 64; ++y)
      for (int x = 47; x <= 48; ++x)
        for (int c = 0; c < 3; ++c, ++n) s += std::pow(double(img.at(x, y, c)) - truth.at(x, y, c), 2);
    return s / n;
  };
  const double before = test::mse(noisy.layer(layer::kColor), truth);
  const Image guided = run_guided(noisy).image;
  const Image box = run_guided(noisy, {{"albedo_weight", "0"}, {"normal_weight", "0"}, {"depth_weight", "0"}}).image;
  EXPECT_LT(test::mse(guided, truth), before / 4);
  EXPECT_LT(crease_mse(guided), crease_mse(box) / 4) << crease_mse(guided) << " vs " << crease_mse(box);
}

TEST(Guided, ReportsItsGuideChannels) {
  AovFrame f = test::planes_frame(16, 16, 0.1f);
  EXPECT_EQ(run_guided(f).stats.counters.at("guide_channels"), 7.0);
  EXPECT_EQ(run_guided(f, {{"albedo_weight", "0"}}).stats.counters.at("guide_channels"), 4.0);
}

}  // namespace
}  // namespace dnb
