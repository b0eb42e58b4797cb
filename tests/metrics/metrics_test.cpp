// The metrics of docs/design.md, "Metric conventions": identities, small cases computed by hand, and
// the refusals (NaN, unequal sizes) that every registered metric must share.
#include <cmath>
#include <limits>
#include <random>

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
  EXPECT_EQ(metric_names(),
            (std::vector<std::string>{"mse", "mse_hdr", "relmse", "psnr", "ssim", "flip", "hdrflip", "mse_hdr_nc",
                                      "relmse_nc", "mse_converged"}));
  EXPECT_THROW(metric("nope"), InputError);
  EXPECT_FALSE(metric("ssim").lower_is_better);
}

TEST(Metrics, IdenticalImagesScorePerfectly) {
  const Image a = pattern(24, 20);
  const Image no_noise(24, 20, 3, 0.0f);  // a reference without variance: every pixel converged
  for (const auto& m : all_metrics()) {
    MetricResult r = m.compute(a, a, &no_noise);
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
  const Image var(8, 8, 3, 0.0f);
  for (const auto& m : all_metrics()) {
    EXPECT_THROW(m.compute(a, b, &var), InputError) << m.name;
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

// The variance of the mean of n independent samples: their unbiased sample variance over n.
std::pair<double, double> mean_and_variance(const std::vector<double>& samples) {
  double sum = 0, sum_sq = 0;
  for (double v : samples) { sum += v; sum_sq += v * v; }
  const double n = double(samples.size()), mean = sum / n;
  return {mean, std::max(0.0, (sum_sq - sum * mean) / (n - 1)) / n};
}

TEST(Metrics, UnconvergedMaskFlagsPixelsCarriedByFewSamples) {
  // Pixel x of a 4096-sample reference: background radiance 0.1 in every sample, plus k firefly
  // samples of 500. When k equal samples carry a value its relative standard error is about
  // 1/sqrt(k) (here 0.99, 0.70, 0.50, 0.35, 0.25 for k = 1, 2, 4, 8, 16): the mask's bound of 1/2
  // flags k = 1 and 2, keeps k = 8 and 16. (k = 4 sits on the bound and is not asserted.)
  const std::vector<int> ks = {1, 2, 8, 16, 0};
  Image ref(int(ks.size()), 1, 3), var(int(ks.size()), 1, 3);
  for (std::size_t x = 0; x < ks.size(); ++x) {
    std::vector<double> s(4096, 0.1);
    for (int i = 0; i < ks[x]; ++i) s[std::size_t(i) * 97] = 500.0;
    auto [m, v] = mean_and_variance(s);
    for (int c = 0; c < 3; ++c) { ref.at(int(x), 0, c) = float(m); var.at(int(x), 0, c) = float(v); }
  }
  const Image mask = unconverged_mask(ref, var);
  EXPECT_EQ(mask.at(0, 0, 0), 1.0f);  // k = 1
  EXPECT_EQ(mask.at(1, 0, 0), 1.0f);  // k = 2
  EXPECT_EQ(mask.at(2, 0, 0), 0.0f);  // k = 8
  EXPECT_EQ(mask.at(3, 0, 0), 0.0f);  // k = 16
  EXPECT_EQ(mask.at(4, 0, 0), 0.0f);  // no firefly: variance 0
  EXPECT_DOUBLE_EQ(unconverged_share(ref, var), 2.0 / 5.0);

  // A dark channel's noise does not flag a pixel: the bound is on the brightest channel's mean.
  Image r2(2, 1, 3, 1.0f), v2(2, 1, 3, 0.0f);
  r2.at(0, 0, 2) = 0.001f;
  v2.at(0, 0, 2) = 0.01f * 0.01f;  // blue: sd 0.01 on a mean of 0.001, the brightest mean is 1
  v2.at(1, 0, 0) = 0.6f * 0.6f;    // red: sd 0.6 on a mean of 1: unconverged
  const Image m2 = unconverged_mask(r2, v2);
  EXPECT_EQ(m2.at(0, 0, 0), 0.0f);
  EXPECT_EQ(m2.at(1, 0, 0), 1.0f);
  // Black with variance (cannot come from non-negative samples, but a file may say so): unconverged.
  Image r3(1, 1, 3, 0.0f), v3(1, 1, 3, 1e-6f);
  EXPECT_EQ(unconverged_mask(r3, v3).at(0, 0, 0), 1.0f);
}

TEST(Metrics, MseConvergedLeavesOutTheUnconvergedPixelsOnly) {
  // 4x1 reference, pixel 3 a firefly (sd 2 on a mean of 3). The image is one 8-bit step off
  // on pixels 0..2 (100 against 101) and dark where the firefly is.
  const float v100 = float(srgb_decode(100.0 / 255)), v101 = float(srgb_decode(101.0 / 255));
  Image ref(4, 1, 3, v100), var(4, 1, 3, 1e-8f), img(4, 1, 3, v101);
  for (int c = 0; c < 3; ++c) { ref.at(3, 0, c) = 3.0f; var.at(3, 0, c) = 4.0f; img.at(3, 0, c) = v100; }
  ASSERT_EQ(to_srgb8(ref).at(0, 0, 0) + 1, to_srgb8(img).at(0, 0, 0));
  const double full = mse(img, ref).value;
  const MetricResult conv = mse_converged(img, ref, &var);
  EXPECT_DOUBLE_EQ(conv.value, 1.0);  // three pixels, each off by exactly 1 in every channel
  const double firefly = std::pow(255.0 - to_srgb8(img).at(3, 0, 0), 2);
  EXPECT_DOUBLE_EQ(full, (3 * 1.0 + firefly) / 4);
  EXPECT_EQ(conv.map.at(3, 0, 0), 0.0f);
  EXPECT_EQ(conv.map.at(0, 0, 0), 1.0f);
  // Without the variance it cannot be computed: NaN (n/a), never the plain mse in disguise.
  EXPECT_TRUE(std::isnan(mse_converged(img, ref, nullptr).value));
  EXPECT_TRUE(std::isnan(metric("mse_converged").compute(img, ref).value));
  // Every pixel unconverged: nothing to average, NaN.
  Image all_noisy(4, 1, 3, 100.0f);
  EXPECT_TRUE(std::isnan(mse_converged(img, ref, &all_noisy).value));
}

// A reference r = mu + e with known per-sample variance v (Gaussian e, fixed seed) and images
// x = mu + b: against r, mse_hdr expects b^2 + v; mse_hdr_nc takes the reference's v out.
struct NoisyReference {
  Image truth, reference, variance;
};
NoisyReference noisy_reference(int w, int h, double sd) {
  NoisyReference n{pattern(w, h), pattern(w, h), Image(w, h, 3, float(sd * sd))};
  std::mt19937_64 rng(7);
  std::normal_distribution<double> e(0.0, sd);
  for (std::size_t i = 0; i < n.reference.size(); ++i) n.reference.data()[i] = float(n.truth.data()[i] + e(rng));
  return n;
}

TEST(Metrics, NoiseCorrectedHdrMetricsTakeOutTheReferencesVariance) {
  const double sd = 0.05, v = sd * sd;
  const NoisyReference n = noisy_reference(64, 64, sd);
  const double samples = double(n.truth.size());
  // The mean of (x - r)^2 over P samples of N(b, v) differences has a standard deviation of
  // sqrt((2 v^2 + 4 b^2 v) / P): 5 of them (plus float rounding of the images) is the tolerance.
  for (double b : {0.0, 0.02, 0.1}) {
    Image x = n.truth;
    for (std::size_t i = 0; i < x.size(); ++i) x.data()[i] += float(b);
    const double tol = 5 * std::sqrt((2 * v * v + 4 * b * b * v) / samples) + 1e-6;
    EXPECT_NEAR(mse_hdr(x, n.reference), b * b + v, tol) << b;  // the raw metric carries the reference's v
    EXPECT_NEAR(metric("mse_hdr_nc").compute(x, n.reference, &n.variance).value, b * b, tol) << b;
    // relmse_nc: the same per sample over y^2 + 0.01 (y in [0, 1.5] here, so the weights stay
    // within 1/2.26 .. 100); to first order in v / (y^2 + 0.01) its expectation is the mean of
    // b^2 / (mu^2 + 0.01). The tolerance scales the one above by the largest weight, 100, and
    // adds the first-order term's size, v^2 / (y^2 + 0.01)^2 at most.
    double expected = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double mu = n.truth.data()[i];
      expected += b * b / (mu * mu + 0.01);
    }
    expected /= samples;
    const double rel = metric("relmse_nc").compute(x, n.reference, &n.variance).value;
    EXPECT_NEAR(rel, expected, 100 * tol + 0.03 * expected + v * v * 1e4) << b;
  }
  // Without the reference's variance there is nothing to take out: n/a.
  EXPECT_TRUE(std::isnan(metric("mse_hdr_nc").compute(n.truth, n.reference).value));
  EXPECT_TRUE(std::isnan(metric("relmse_nc").compute(n.truth, n.reference).value));
  Image bad = n.variance;
  bad.at(1, 2, 0) = -1;
  EXPECT_THROW(metric("mse_hdr_nc").compute(n.truth, n.reference, &bad), InputError);
}

TEST(Metrics, ReferenceErrorIsWhatAPerfectImageScores) {
  const double sd = 0.01;
  Image ref(4, 2, 3, 0.5f), var(4, 2, 3, float(sd * sd));
  ref.at(3, 1, 0) = 1.5f;  // clamped for the 8-bit display: its noise does not show there
  ref.at(2, 1, 1) = 0.0f;
  const ReferenceError e = reference_error(ref, var);
  const double v = var.data()[0];  // sd^2 as the float layer holds it
  EXPECT_NEAR(e.mse_hdr, v, 1e-15);
  double relmse = 0, mse = 0;
  auto slope = [](double y) {  // a numerical derivative of the 8-bit display value, one-sided at 0
    const double h = 1e-6;
    return y <= 0 ? 255 * (srgb_encode(h) - srgb_encode(0)) / h : 255 * (srgb_encode(y + h) - srgb_encode(y - h)) / (2 * h);
  };
  for (std::size_t i = 0; i < ref.size(); ++i) {
    const double y = ref.data()[i];
    relmse += v / (y * y + 0.01);
    mse += y >= 1 ? 0.0 : slope(y) * slope(y) * v;
  }
  EXPECT_NEAR(e.relmse, relmse / double(ref.size()), 1e-15);
  EXPECT_NEAR(e.mse, mse / double(ref.size()), 1e-6 * e.mse);
  // Against the real thing: the 8-bit mse of a grey truth (0.4) against a reference with noise of
  // sd 0.03 (about 5 display steps, so the first order holds; rounding adds about 1/12 of a step
  // squared, 0.3% here): within 5%, about 5 standard errors of the measured mean over 12288
  // samples (sqrt(2 / 12288) = 1.3%).
  Image grey(64, 64, 3, 0.4f), noisy = grey;
  Image grey_var(64, 64, 3, float(0.03 * 0.03));
  std::mt19937_64 rng(11);
  std::normal_distribution<double> noise(0.0, 0.03);
  for (std::size_t i = 0; i < noisy.size(); ++i) noisy.data()[i] = float(0.4 + noise(rng));
  const double measured = metric("mse").compute(grey, noisy).value;
  const double predicted = reference_error(noisy, grey_var).mse;
  EXPECT_NEAR(measured / predicted, 1.0, 0.05) << measured << " vs " << predicted;
}

TEST(Metrics, MseConvergedRefusesABadVariance) {
  const Image ref = pattern(6, 4), img = pattern(6, 4);
  Image neg(6, 4, 3, 0.0f), nan(6, 4, 3, 0.0f), small(6, 3, 3, 0.0f), one(6, 4, 1, 0.0f);
  neg.at(2, 1, 1) = -1.0f;
  nan.at(5, 3, 0) = std::numeric_limits<float>::quiet_NaN();
  for (const Image* v : {&neg, &nan, &small, &one}) EXPECT_THROW(mse_converged(img, ref, v), InputError);
  try {
    mse_converged(img, ref, &neg);
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("(2, 1)"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("channel G"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dnb::metrics

namespace dnb::metrics {
namespace {

// worse_blocks on a hand-made case: a 32x16 image of 2x1 tiles of 16x16; the input is off by 0.1
// everywhere; the image is exact on the left tile and off by 0.2 on the right one (four times
// the input's squared error there).
TEST(WorseBlocks, CountsTilesAboveTheInputsErrorAndAboveTwiceIt) {
  const Image ref(32, 16, 3, 0.5f);
  Image input(32, 16, 3, 0.6f), image(32, 16, 3, 0.5f);
  for (int y = 0; y < 16; ++y)
    for (int x = 16; x < 32; ++x)
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = 0.7f;
  WorseBlocks b = worse_blocks(image, input, ref);
  EXPECT_EQ(b.count, 2);
  EXPECT_DOUBLE_EQ(b.worse, 0.5);
  EXPECT_DOUBLE_EQ(b.worse_twice, 0.5);
  // Off by 0.12 on the right instead: worse than the input there, but not twice (in 8-bit sRGB:
  // 0.5 -> 188, 0.6 -> 203, 0.62 -> 206: 18^2 = 324 against 15^2 = 225, less than 450).
  for (int y = 0; y < 16; ++y)
    for (int x = 16; x < 32; ++x)
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = 0.62f;
  b = worse_blocks(image, input, ref);
  EXPECT_DOUBLE_EQ(b.worse, 0.5);
  EXPECT_DOUBLE_EQ(b.worse_twice, 0.0);
  // The worse tile is listed for the viewer, with its ratio 324 / 225.
  auto tile_is = [](const WorseBlocks::Tile& t, int x, int w, double ratio) {
    EXPECT_EQ(t.x, x);
    EXPECT_EQ(t.y, 0);
    EXPECT_EQ(t.w, w);
    EXPECT_EQ(t.h, 16);
    if (ratio > 0) {
      EXPECT_NEAR(t.ratio, ratio, 1e-9);
    }
  };
  ASSERT_EQ(b.tiles.size(), 1u);
  tile_is(b.tiles[0], 16, 16, 324.0 / 225.0);
  // Worst first: a third tile off by 0.2 (4x the input's error and more) comes before it; a
  // partial tile (48 + 5 wide) has its own width; tiles no worse than the input are not listed.
  const Image ref3(53, 16, 3, 0.5f);
  Image input3(53, 16, 3, 0.6f), image3(53, 16, 3, 0.5f);
  for (int y = 0; y < 16; ++y)
    for (int c = 0; c < 3; ++c) {
      for (int x = 0; x < 16; ++x) image3.at(x, y, c) = 0.62f;
      for (int x = 48; x < 53; ++x) image3.at(x, y, c) = 0.7f;
    }
  b = worse_blocks(image3, input3, ref3);
  ASSERT_EQ(b.tiles.size(), 2u);
  tile_is(b.tiles[0], 48, 5, 0);
  EXPECT_GT(b.tiles[0].ratio, 2.0);
  tile_is(b.tiles[1], 0, 16, 324.0 / 225.0);
  // Partial tiles at the borders count as tiles: 33x17 is 3x2 of them.
  EXPECT_EQ(worse_blocks(Image(33, 17, 3, 0.5f), Image(33, 17, 3, 0.5f), Image(33, 17, 3, 0.5f)).count, 6);
  EXPECT_THROW(worse_blocks(image, Image(8, 8, 3), ref), InputError);
}

}  // namespace
}  // namespace dnb::metrics
