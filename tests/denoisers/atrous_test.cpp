// atrous: the edge-avoiding a-trous wavelet filter. Checked against properties of its kernel
// (a linear ramp survives the symmetric B3 cascade) and of its edge-stopping functions.
#include <gtest/gtest.h>

#include <cmath>

#include "denoisers/illumination.h"
#include "denoisers/method.h"
#include "denoisers/synthetic_frame.h"

namespace dnb {
namespace {

MethodResult run_atrous(const AovFrame& f, const std::map<std::string, std::string>& settings = {}) {
  auto m = MethodRegistry::global().create("atrous", settings);
  return run_method(*m, {.frame = &f});
}

std::map<std::string, std::string> no_stopping(const char* iterations = "5") {
  return {{"sigma_color", "1e4"}, {"sigma_normal", "1e4"}, {"sigma_depth", "1e4"}, {"halve_color_sigma", "false"},
          {"iterations", iterations}};
}

// With the edge-stopping functions switched off, each pass is a normalised symmetric kernel, so
// an illumination that is linear in x and y comes back unchanged wherever no tap leaves the
// image (3 passes reach 2 * (1 + 2 + 4) = 14 pixels). Tolerance: 1e-5 relative, float sums of
// 25 taps over 3 passes (exp(-tiny) is 1 - 1e-8, not exactly 1).
TEST(Atrous, KeepsALinearRampWithoutEdgeStopping) {
  AovFrame f = test::constant_frame(48, 40);
  Image& d = f.layer(layer::kDirect);
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 48; ++x)
      for (int c = 0; c < 3; ++c) d.at(x, y, c) = 0.1f + 0.01f * x + 0.02f * y + 0.1f * c;
  const Image out = run_atrous(f, no_stopping("3")).image;
  const Image want = compose(illumination(f), f);
  for (int y = 14; y < 40 - 14; ++y)
    for (int x = 14; x < 48 - 14; ++x)
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(out.at(x, y, c), want.at(x, y, c), 1e-5f * want.at(x, y, c)) << x << "," << y;
}

// The crease between the two planes (normals 90 degrees apart, depths 7% apart), each plane
// lit by a constant: with the defaults no light leaks across (pixels beside it within 0.5% of
// the truth); with the stopping functions off, the same filter visibly blurs across it (more
// than 5%). Constant lighting per plane, because a one-sided kernel next to an edge shifts a
// lighting *gradient* (inherent to any filter that stops at edges).
TEST(Atrous, NormalAndDepthStopAtTheCrease) {
  AovFrame f = test::planes_frame(96, 64, 0.0f);
  Image& d = f.layer(layer::kDirect);
  Image& i = f.layer(layer::kIndirect);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 96; ++x)
      for (int c = 0; c < 3; ++c) d.at(x, y, c) = x < 48 ? 1.0f : 0.25f, i.at(x, y, c) = 0.0f;
  const Image truth = compose(illumination(f), f);
  auto worst_beside_crease = [&](const Image& img) {
    double worst = 0;
    for (int y = 0; y < 64; ++y)
      for (int x = 46; x <= 49; ++x)
        for (int c = 0; c < 3; ++c)
          worst = std::max(worst, std::abs(double(img.at(x, y, c)) - truth.at(x, y, c)) / truth.at(x, y, c));
    return worst;
  };
  EXPECT_LT(worst_beside_crease(run_atrous(f).image), 0.005);
  EXPECT_GT(worst_beside_crease(run_atrous(f, no_stopping()).image), 0.05);
}

// On the smooth scene with heavy noise (30% relative) the defaults remove nearly all of it:
// measured 45x lower MSE; the bound of 20x leaves room for a retuned default.
TEST(Atrous, RemovesNoiseOnASmoothScene) {
  AovFrame noisy = test::planes_frame(96, 64, 0.3f);
  const Image truth = test::planes_frame(96, 64, 0.0f).layer(layer::kColor);
  const double before = test::mse(noisy.layer(layer::kColor), truth);
  const double after = test::mse(run_atrous(noisy).image, truth);
  EXPECT_LT(after, before / 20) << before << " -> " << after;
}

}  // namespace
}  // namespace dnb
