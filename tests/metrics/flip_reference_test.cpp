// LDR-FLIP, HDR-FLIP, FLIP's pooled statistics and SSIM against the implementations people compare
// with: NVIDIA's FLIP tool (flip-evaluator 1.7) and scikit-image 0.26's structural_similarity.
// The pairs are formulas of (x, y, c) on integers, written the same way in
// tests/metrics/data/flip_ssim_reference.py, which produced the pinned values (its header says
// how); every pixel is an 8-bit code or a dyadic rational, so both sides read the same numbers.
// A wrong filter, window, constant, exposure range or pooling rule moves a value well past its
// tolerance; each tolerance says what it allows for.
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "metrics/metrics.h"

namespace dnb::metrics {
namespace {

constexpr int kW = 32, kH = 24;    // the FLIP pairs
constexpr int kSW = 48, kSH = 40;  // the SSIM pair

double hdr_reference(int x, int y, int c) {
  // The second term breaks ties, so that the two middle luminances differ (the median's definition shows).
  const double base = ((x * 5 + y * 3 + c * 7) % 16 + 1) / 16.0 + ((x * 11 + y * 29 + c * 5) % 97) / 2048.0;
  return base * std::exp2(x / 8 + 2 * (y / 12));  // 1/16 .. 32 and a bit
}
double hdr_test(int x, int y, int c) {
  if (x == 5 && y == 5) return 64.0;  // a firefly
  const int d = (x * 7 + y * 11 + c * 3) % 5 - 2;
  return hdr_reference(x, y, c) * (1.0 + d / 8.0);
}
int ldr_reference_code(int x, int y, int c) { return 40 + 160 * ((x / 4 + y / 4) % 2) + (x * 3 + y * 5 + c * 17) % 32; }
int ldr_test_code(int x, int y, int c) {
  return std::min(255, std::max(0, ldr_reference_code(x, y, c) + (x * 13 + y * 7 + c * 5) % 21 - 10));
}
int ssim_reference_code(int x, int y, int c) { return (x * 9 + y * 14 + c * 50 + 80 * ((x / 6 + y / 5) % 2)) % 256; }
int ssim_test_code(int x, int y, int c) {
  return std::min(255, std::max(0, ssim_reference_code(x, y, c) + (x * 29 + y * 31 + c * 7) % 41 - 20));
}

template <typename F>
Image linear(int w, int h, F f) {
  Image im(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) im.at(x, y, c) = float(f(x, y, c));
  return im;
}
// An 8-bit sRGB code as the linear value whose 8-bit encoding (to_srgb8) is that code again.
template <typename F>
Image from_codes(int w, int h, F code) {
  return linear(w, h, [&](int x, int y, int c) { return srgb_decode(code(x, y, c) / 255.0); });
}

// Tolerances. NVIDIA's FLIP computes in float, with the exact sRGB-primaries RGB <-> XYZ matrices;
// ours computes in double with Lindbloom's 7-digit ones, and its CSV rounds to 6 decimals.
// Observed here: means 1.3e-6 apart, single-pixel values (percentiles, min, max) up to 1.1e-5.
// A mean averages those differences out, a percentile is one pixel's value and does not.
constexpr double kMeanTol = 1e-5;
constexpr double kPixelTol = 5e-5;
// Exposures: FLIP takes log2 of float luminances (under 6e-7 stops apart here).
constexpr double kExposureTol = 1e-5;

void expect_pooled(const FlipPooled& p, const FlipPooled& nvidia) {
  EXPECT_NEAR(p.mean, nvidia.mean, kMeanTol);
  EXPECT_NEAR(p.weighted_median, nvidia.weighted_median, kPixelTol);
  EXPECT_NEAR(p.weighted_first_quartile, nvidia.weighted_first_quartile, kPixelTol);
  EXPECT_NEAR(p.weighted_third_quartile, nvidia.weighted_third_quartile, kPixelTol);
  EXPECT_NEAR(p.min, nvidia.min, kPixelTol);
  EXPECT_NEAR(p.max, nvidia.max, kPixelTol);
}

TEST(FlipReference, HdrFlipMatchesNvidiasTool) {
  const Image ref = linear(kW, kH, hdr_reference), test = linear(kW, kH, hdr_test);
  // `flip -r hdr_ref.exr -t hdr_test.exr -ppd 67`: "Start exposure: -3.7525, Stop exposure: -0.5079,
  // Number of exposures: 4"; to full precision from flip_evaluator.evaluate(..., "HDR")'s parameters.
  // The stop exposure takes the upper middle luminance (the two middle ones' mean would give -0.5013,
  // the lower one -0.4947).
  const HdrFlipExposures ex = hdrflip_exposures(ref);
  EXPECT_NEAR(ex.start, -3.752464532852173, kExposureTol);
  EXPECT_NEAR(ex.stop, -0.5078828930854797, kExposureTol);
  EXPECT_EQ(ex.count, 4);
  const MetricResult r = hdrflip(test, ref);
  EXPECT_NEAR(r.value, 0.08986684679985046, kMeanTol);  // evaluate()'s mean
  // The tool's CSV: Mean, Weighted median, 1st and 3rd weighted quartile, Min, Max.
  expect_pooled(pool_flip(r.map), {0.089867, 0.090703, 0.073239, 0.124410, 0.029076, 0.681069});
}

TEST(FlipReference, LdrFlipMatchesNvidiasTool) {
  // `flip -r ldr_ref.png -t ldr_test.png -ppd 67`: the tool decodes the 8-bit sRGB codes, as
  // from_codes does here.
  const Image ref = from_codes(kW, kH, ldr_reference_code), test = from_codes(kW, kH, ldr_test_code);
  const MetricResult r = flip(test, ref);
  EXPECT_NEAR(r.value, 0.052058327943086624, kMeanTol);  // evaluate(..., "LDR", inputsRGB=True)'s mean
  expect_pooled(pool_flip(r.map), {0.052058, 0.059816, 0.044748, 0.073814, 0.009401, 0.197427});
}

TEST(FlipReference, SsimMatchesScikitImage) {
  // Checked against skimage.metrics.structural_similarity(test, ref, gaussian_weights=True,
  // sigma=1.5, use_sample_covariance=False, data_range=255, channel_axis=2) on the 8-bit codes:
  // the same 11-tap Gaussian (scipy truncates at 3.5 sigma: radius 5), the same constants and the
  // same crop of 5 pixels per side, all in double: they agree to 1e-16, so 1e-12 leaves room for
  // summation order only. A wrong sigma, window or constant moves the value by far more.
  const Image ref = from_codes(kSW, kSH, ssim_reference_code), test = from_codes(kSW, kSH, ssim_test_code);
  EXPECT_NEAR(ssim(test, ref).value, 0.9751123177562916, 1e-12);
}

}  // namespace
}  // namespace dnb::metrics
