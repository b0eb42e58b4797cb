// The metrics of DESIGN.md "Metric conventions": identities, small cases computed by hand, and
// the refusals (NaN, unequal sizes) that every registered metric must share.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "core/errors.h"
#include "metrics/metrics.h"

namespace dnb::metrics {
namespace {

Image constant(int w, int h, float v) { return Image(w, h, 3, v); }

// A deterministic textured image in [0, 1.5] (values above 1 exercise the clamp).
Image pattern(int w, int h) {
  Image im(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) im.at(x, y, c) = float(0.75 + 0.75 * std::sin(0.37 * x + 0.23 * y + c));
  return im;
}

TEST(Metrics, RegistryListsTheContractMetrics) {
  EXPECT_EQ(metric_names(), (std::vector<std::string>{"mse", "mse_hdr", "relmse", "psnr", "ssim", "flip"}));
  EXPECT_THROW(metric("nope"), InputError);
  EXPECT_FALSE(metric("ssim").lower_is_better);
}

TEST(Metrics, IdenticalImagesScorePerfectly) {
  const Image a = pattern(24, 20);
  for (const auto& m : all_metrics()) {
    MetricResult r = m.compute(a, a);
    if (m.name == "ssim") EXPECT_DOUBLE_EQ(r.value, 1.0) << m.name;
    else if (m.name == "psnr") EXPECT_TRUE(std::isinf(r.value) && r.value > 0) << m.name;
    else EXPECT_EQ(r.value, 0.0) << m.name;
    ASSERT_EQ(r.map.width(), 24);
    ASSERT_EQ(r.map.height(), 20);
    ASSERT_EQ(r.map.channels(), 1);
    for (std::size_t i = 0; i < r.map.size(); ++i) EXPECT_NEAR(r.map.data()[i], 0.0, 1e-6) << m.name;
  }
}

TEST(Metrics, SrgbEncodingMatchesTheStandard) {
  // sRGB of linear 0.5 is 0.7353569 -> 187.5 -> 188; above 1 clamps to 255, below 0 to 0.
  Image lin(3, 1, 3);
  for (int c = 0; c < 3; ++c) { lin.at(0, 0, c) = 0.5f; lin.at(1, 0, c) = 7.0f; lin.at(2, 0, c) = -1.0f; }
  Image s = to_srgb8(lin);
  EXPECT_EQ(s.at(0, 0, 0), 188.0f);
  EXPECT_EQ(s.at(1, 0, 1), 255.0f);
  EXPECT_EQ(s.at(2, 0, 2), 0.0f);
}

TEST(Metrics, HandComputedCases) {
  // Black against white: every 8-bit sample differs by 255.
  EXPECT_DOUBLE_EQ(mse(constant(4, 4, 0), constant(4, 4, 1)).value, 255.0 * 255.0);
  EXPECT_NEAR(psnr(constant(4, 4, 0), constant(4, 4, 1)).value, 0.0, 1e-12);  // 10 log10(255^2/255^2)
  // Linear: one pixel of two off by 2 in one channel: 4 / 6 samples.
  Image a = constant(2, 1, 0.5f), b = constant(2, 1, 0.5f);
  a.at(1, 0, 2) = 2.5f;
  EXPECT_NEAR(mse_hdr(a, b), 4.0 / 6.0, 1e-12);
  // relmse: (2)^2 / (0.5^2 + 0.01) over 6 samples.
  EXPECT_NEAR(relmse(a, b).value, 4.0 / 0.26 / 6.0, 1e-9);
  // Its map holds the pixel's mean over channels.
  EXPECT_NEAR(relmse(a, b).map.at(1, 0, 0), 4.0 / 0.26 / 3.0, 1e-5);
  EXPECT_EQ(relmse(a, b).map.at(0, 0, 0), 0.0f);
  // 8-bit mse of one sample 0.5 (188) against 0 (0): 188^2 / 6 samples.
  Image c = constant(2, 1, 0.0f), d = constant(2, 1, 0.0f);
  c.at(0, 0, 0) = 0.5f;
  EXPECT_NEAR(mse(c, d).value, 188.0 * 188.0 / 6.0, 1e-9);
}

TEST(Metrics, SsimOfConstantImagesIsTheLuminanceTerm) {
  // No variance: SSIM = (2 mu_x mu_y + C1) / (mu_x^2 + mu_y^2 + C1), C1 = (0.01 * 255)^2.
  const double C1 = std::pow(0.01 * 255, 2);
  EXPECT_NEAR(ssim(constant(16, 16, 0), constant(16, 16, 1)).value, C1 / (255.0 * 255.0 + C1), 1e-12);
  EXPECT_NEAR(ssim(constant(16, 16, 1), constant(16, 16, 1)).value, 1.0, 1e-12);
  // Noise lowers it; more noise lowers it more.
  Image ref = pattern(32, 32), n1 = ref, n2 = ref;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    float e = ((i * 2654435761u) % 1000) / 1000.0f - 0.5f;
    n1.data()[i] += 0.05f * e;
    n2.data()[i] += 0.2f * e;
  }
  double s1 = ssim(n1, ref).value, s2 = ssim(n2, ref).value;
  EXPECT_LT(s1, 1.0);
  EXPECT_LT(s2, s1);
}

TEST(Metrics, FlipOfBlackAgainstWhiteIsTheHandComputedColourError) {
  // Uniform images have no edges or points, so FLIP is the colour term alone: HyAB(black,
  // white) = 100, ^0.7 = 25.119; cmax = HyAB(green, blue)^0.7 = 41.275 (Hunt-adjusted Lab);
  // 25.119 > pc * cmax, so FLIP = pt + (25.119 - 0.4 cmax) / (0.6 cmax) (1 - pt) = 0.96738.
  EXPECT_NEAR(flip(constant(20, 20, 0), constant(20, 20, 1)).value, 0.967381, 1e-4);
  // Bounded, and growing with the difference.
  Image ref = pattern(40, 30), small = ref, large = ref;
  for (std::size_t i = 0; i < ref.size(); i += 7) { small.data()[i] += 0.05f; large.data()[i] += 0.5f; }
  double fs = flip(small, ref).value, fl = flip(large, ref).value;
  EXPECT_GT(fs, 0.0);
  EXPECT_GT(fl, fs);
  EXPECT_LE(fl, 1.0);
}

TEST(Metrics, EveryMetricRefusesNanAndUnequalSizes) {
  Image a = pattern(8, 8), b = pattern(8, 8), small = pattern(8, 7);
  a.at(3, 2, 1) = std::numeric_limits<float>::quiet_NaN();
  Image inf_ref = pattern(8, 8);
  inf_ref.at(0, 0, 0) = std::numeric_limits<float>::infinity();
  for (const auto& m : all_metrics()) {
    EXPECT_THROW(m.compute(a, b), InputError) << m.name;
    EXPECT_THROW(m.compute(b, inf_ref), InputError) << m.name;
    EXPECT_THROW(m.compute(b, small), InputError) << m.name;
  }
  try {
    check_pair(a, b, "x.exr", "ref.exr");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("x.exr"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("(3, 2)"), std::string::npos);
  }
}

}  // namespace
}  // namespace dnb::metrics
