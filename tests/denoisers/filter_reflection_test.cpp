// filter_reflection of the illumination filters (guided, atrous): R, what mirrors show, is
// passed through by default and filtered with the first reflection level's guides when asked.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "denoisers/illumination.h"
#include "denoisers/method.h"
#include "denoisers/synthetic_frame.h"

namespace dnb {
namespace {

// The planes frame with smooth reflection of 0.2 plus 30% relative noise, and level-1 guides
// that are two planes of their own.
AovFrame noisy_reflection_frame() {
  static AovFrame clean = test::planes_frame(96, 64, 0.0f);
  AovFrame f = clean;
  std::mt19937 rng(3);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  Image& r = f.layer(layer::kReflection);
  Image& c = f.layer(layer::kColor);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 96; ++x)
      for (int k = 0; k < 3; ++k) {
        const float noisy = std::max(0.0f, 0.2f * (1.0f + 0.3f * gauss(rng)));
        c.at(x, y, k) += noisy - r.at(x, y, k);
        r.at(x, y, k) = noisy;
      }
  f.layer(layer::at_level(1, layer::kNormal)) = clean.layer(layer::kNormal);
  f.layer(layer::at_level(1, layer::kDepth)) = clean.layer(layer::kDepth);
  return f;
}

class FilterReflection : public ::testing::TestWithParam<std::string> {
 protected:
  MethodResult run(const AovFrame& f, const char* on) const {
    auto m = MethodRegistry::global().create(GetParam(), {{"filter_reflection", on}});
    return run_method(*m, {.frame = &f});
  }
};

TEST_P(FilterReflection, AsksForTheLevelOneGuidesOnlyWhenOn) {
  auto off = MethodRegistry::global().create(GetParam(), {{"filter_reflection", "false"}})->required_layers();
  auto on = MethodRegistry::global().create(GetParam(), {{"filter_reflection", "true"}})->required_layers();
  EXPECT_EQ(std::count(off.begin(), off.end(), "refl1.normal"), 0);
  EXPECT_EQ(std::count(on.begin(), on.end(), "refl1.normal"), 1);
  EXPECT_EQ(std::count(on.begin(), on.end(), "refl1.depth"), 1);
}

// The R a method used is its output minus its output for the same frame with R = 0. Off: that
// is the noisy R itself (to float rounding of the sum, hence 1e-3 relative on the MSE). On: R's
// noise is mostly removed (at least 5x lower MSE against the noise-free R).
TEST_P(FilterReflection, PassesThroughOrFiltersR) {
  const AovFrame f = noisy_reflection_frame();
  Image clean_r(96, 64, 3, 0.2f);
  auto r_error = [&](const Image& out) {
    Image r = out;  // out - (out without R) recovers the R the method used
    AovFrame g = f;
    g.layer(layer::kReflection) = Image(96, 64, 3, 0.0f);
    const Image without = run(g, "false").image;
    for (std::size_t k = 0; k < r.size(); ++k) r.data()[k] -= without.data()[k];
    return test::mse(r, clean_r);
  };
  const double input = test::mse(f.layer(layer::kReflection), clean_r);
  EXPECT_NEAR(r_error(run(f, "false").image), input, 1e-3 * input);
  EXPECT_LT(r_error(run(f, "true").image), input / 5);
}

TEST_P(FilterReflection, ConstantStaysConstantWhenOn) {
  const AovFrame f = test::constant_frame(30, 20);
  const Image out = run(f, "true").image;
  for (std::size_t k = 0; k < out.size(); ++k) ASSERT_NEAR(out.data()[k], test::kConstantColor, 1e-5f);
}

INSTANTIATE_TEST_SUITE_P(IlluminationFilters, FilterReflection, ::testing::Values("guided", "atrous"));

}  // namespace
}  // namespace dnb
