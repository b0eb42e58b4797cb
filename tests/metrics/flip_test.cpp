// HDR-FLIP and FLIP's pooled statistics (metrics.h): what their definitions guarantee, on small
// images, and hand-computed cases. NVIDIA's own numbers are pinned in flip_reference_test.cpp.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"
#include "metrics/metrics.h"

namespace dnb::metrics {
namespace {

// A deterministic HDR image: texture over a brightness ramp from about 0.02 to 20 (10 stops).
Image hdr_pattern(int w, int h) {
  Image im(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c)
        im.at(x, y, c) = float((0.6 + 0.4 * std::sin(0.37 * x + 0.23 * y + c)) * 0.02 * std::exp2(10.0 * x / (w - 1)));
  return im;
}

// Uniform noise in [-1/2, 1/2) from an integer hash of (sample, seed): the same on every platform.
float noise(std::uint32_t i, std::uint32_t seed) {
  std::uint32_t h = (i + 1) * 2654435761u ^ (seed + 1) * 2246822519u;
  h ^= h >> 15; h *= 2246822519u; h ^= h >> 13;
  return float(h % 100000) / 100000.0f - 0.5f;
}

// The reference with relative noise of amplitude a: x (1 + a e).
Image noisy(const Image& ref, float a, std::uint32_t seed) {
  Image out = ref;
  for (std::size_t i = 0; i < out.size(); ++i) out.data()[i] *= 1.0f + a * noise(std::uint32_t(i), seed);
  return out;
}

Image grey(std::initializer_list<float> values) {
  Image im(int(values.size()), 1, 3);
  int x = 0;
  for (float v : values) { for (int c = 0; c < 3; ++c) im.at(x, 0, c) = v; ++x; }
  return im;
}

TEST(HdrFlip, IdenticalImagesScoreZero) {
  // Every exposure then scores two identical LDR images: HyAB 0 and no feature difference.
  for (const Image& im : {hdr_pattern(24, 16), Image(8, 8, 3, 0.0f), Image(8, 8, 3, 1e4f)}) {
    const MetricResult r = hdrflip(im, im);
    EXPECT_EQ(r.value, 0.0);
    for (std::size_t p = 0; p < r.map.size(); ++p) ASSERT_EQ(r.map.data()[p], 0.0f);
  }
}

TEST(HdrFlip, RisesWithNoise) {
  // Not a theorem (FLIP's terms are nonlinear in the pixels), but what a metric of noise must do:
  // the same noise pattern at growing amplitudes, three seeds. The means here grow by a factor
  // 1.6 to 2 from one amplitude to the next (0.0089, 0.017, 0.029, 0.048, 0.082 for seed 1), far
  // from a tie.
  const Image ref = hdr_pattern(48, 32);
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    double previous = 0;
    for (float a : {0.02f, 0.05f, 0.1f, 0.2f, 0.4f}) {
      const double v = hdrflip(noisy(ref, a, seed), ref).value;
      EXPECT_GT(v, previous) << "seed " << seed << ", amplitude " << a;
      EXPECT_LE(v, 1.0);
      previous = v;
    }
  }
}

TEST(HdrFlip, IsTheLargestLdrFlipOverItsExposures) {
  // The definition, pixel by pixel: HDR-FLIP = max over its exposures c of LDR-FLIP of the pair
  // tone-mapped at c. That is the only ordering it promises: it is not bounded below by LDR-FLIP
  // of the images as they are, not even of an LDR image, since no exposure's tone curve is the
  // identity on [0, 1]; so no test compares it with `flip` on the untone-mapped pair.
  // flip() applies its display transform (clamp, sRGB encode and decode) to the already linear
  // tone-mapped pixels: a round trip in double that moves a value by about 1e-16 and, through the
  // square roots of the feature term, an error by far less than the 1e-6 allowed (it is exact here).
  const Image ref = hdr_pattern(48, 32), test = noisy(ref, 0.1f, 7);
  const MetricResult h = hdrflip(test, ref);
  const HdrFlipExposures ex = hdrflip_exposures(ref);
  ASSERT_GE(ex.count, 5);  // ten stops of brightness, over a range from the brightest pixel to the median
  std::vector<float> largest(h.map.size(), 0.0f);
  for (int i = 0; i < ex.count; ++i) {
    const MetricResult l = flip(hdrflip_tone_map(test, ex.exposure(i)), hdrflip_tone_map(ref, ex.exposure(i)));
    for (std::size_t p = 0; p < largest.size(); ++p) largest[p] = std::max(largest[p], l.map.data()[p]);
  }
  for (std::size_t p = 0; p < largest.size(); ++p) ASSERT_NEAR(h.map.data()[p], largest[p], 1e-6) << "pixel " << p;
}

TEST(HdrFlip, DoesNotDependOnTheUnitsOfRadiance) {
  // Scaling both images by 2^k moves the exposure range by -k stops (it comes from the reference's
  // luminance) and so every exposed image stays the same: HDR-FLIP reads no absolute brightness.
  // Powers of two keep the scaled samples exact; the 1e-12 allow for log2's and exp2's rounding
  // (they are exact here).
  const Image ref = hdr_pattern(32, 24), test = noisy(ref, 0.1f, 5);
  const MetricResult base = hdrflip(test, ref);
  const HdrFlipExposures ex = hdrflip_exposures(ref);
  for (int k : {-3, 5}) {
    Image a = ref, b = test;
    for (std::size_t i = 0; i < a.size(); ++i) { a.data()[i] = std::ldexp(a.data()[i], k); b.data()[i] = std::ldexp(b.data()[i], k); }
    const HdrFlipExposures scaled = hdrflip_exposures(a);
    EXPECT_NEAR(scaled.start, ex.start - k, 1e-12);
    EXPECT_NEAR(scaled.stop, ex.stop - k, 1e-12);
    EXPECT_EQ(scaled.count, ex.count);
    EXPECT_NEAR(hdrflip(b, a).value, base.value, 1e-12) << "k = " << k;
  }
}

TEST(HdrFlip, ExposureRangeAsThePaperDefinesIt) {
  // Grey pixels (Y = the value) 1, 2, 3, 20: Y_max = 20, Y_median = 3 (rank n/2 = 2 of the sorted
  // four). At the start exposure the brightest pixel, at the stop exposure the median one, tone-maps
  // to 0.85; stop - start = log2(20 / 3) = 2.74 stops, so ceil gives 3 exposures, evenly spaced.
  const Image ref = grey({2, 20, 1, 3});
  const HdrFlipExposures ex = hdrflip_exposures(ref);
  EXPECT_DOUBLE_EQ(ex.luminance_max, 20.0 * (0.2126 + 0.7152 + 0.0722));
  EXPECT_DOUBLE_EQ(ex.luminance_median, 3.0 * (0.2126 + 0.7152 + 0.0722));
  EXPECT_NEAR(ex.stop - ex.start, std::log2(20.0 / 3.0), 1e-12);
  EXPECT_EQ(ex.count, 3);
  EXPECT_DOUBLE_EQ(ex.exposure(0), ex.start);
  EXPECT_NEAR(ex.exposure(1), 0.5 * (ex.start + ex.stop), 1e-12);
  EXPECT_NEAR(ex.exposure(2), ex.stop, 1e-12);
  // 1e-6: the tone-mapped value is stored as a float.
  EXPECT_NEAR(hdrflip_tone_map(grey({20}), ex.start).at(0, 0, 0), 0.85, 1e-6);
  EXPECT_NEAR(hdrflip_tone_map(grey({3}), ex.stop).at(0, 0, 0), 0.85, 1e-6);
  // The ACES curve itself: T(0) = 0, T saturates at 1 (clamped from 2.51 / 2.43), x_max ~ 2.1189
  // (the root of 0.16002 x^2 - 0.2829 x - 0.119 = 0, by hand) maps to 0.85.
  EXPECT_EQ(hdrflip_tone_map(grey({0, 1e6f, -5}), 0).at(0, 0, 0), 0.0f);
  EXPECT_EQ(hdrflip_tone_map(grey({0, 1e6f, -5}), 0).at(1, 0, 0), 1.0f);
  EXPECT_EQ(hdrflip_tone_map(grey({0, 1e6f, -5}), 0).at(2, 0, 0), 0.0f);  // negative: black
  EXPECT_NEAR(std::exp2(ex.start) * 20.0, 2.1189, 1e-4);
  // An odd pixel count takes the middle luminance.
  EXPECT_DOUBLE_EQ(hdrflip_exposures(grey({5, 1, 4, 2, 3})).luminance_median, 3.0 * (0.2126 + 0.7152 + 0.0722));
}

TEST(HdrFlip, DarkReferencesHaveAFiniteRange) {
  // FLIP divides by a zero median (or maximum) here; these are the documented fallbacks.
  const HdrFlipExposures mostly_black = hdrflip_exposures(grey({0, 0, 0, 4, 1}));
  EXPECT_DOUBLE_EQ(mostly_black.luminance_median, 4.0 * (0.2126 + 0.7152 + 0.0722));  // of {1, 4}: rank 1
  EXPECT_TRUE(std::isfinite(mostly_black.start) && std::isfinite(mostly_black.stop));
  const HdrFlipExposures black = hdrflip_exposures(Image(4, 4, 3, 0.0f));
  EXPECT_EQ(black.start, 0.0);
  EXPECT_EQ(black.stop, 0.0);
  EXPECT_EQ(black.count, 2);
  const double v = hdrflip(Image(4, 4, 3, 1.0f), Image(4, 4, 3, 0.0f)).value;
  EXPECT_GT(v, 0.9);  // white against black at exposure 1 (T(1) = 0.67): a large colour error
  EXPECT_LE(v, 1.0);
  EXPECT_THROW(hdrflip_exposures(Image(4, 4, 1, 1.0f)), InputError);
}

Image map_of(std::initializer_list<float> values) {
  Image m(int(values.size()), 1, 1);
  std::copy(values.begin(), values.end(), m.data());
  return m;
}

// FLIP keeps the reference's prepared images between calls (flip.cpp's ReferenceMemo). A reference
// is recognised by its content: another reference, even one written in place over the last one's
// pixels (the same address), must be prepared again, and a reference seen before scores exactly as
// it did then.
TEST(FlipMemo, ScoresDoNotDependOnWhichReferenceCameBefore) {
  const Image a = hdr_pattern(40, 24);
  Image b = hdr_pattern(40, 24);
  const Image image = noisy(a, 0.3f, 5);
  Image other = a;
  for (int x = 0; x < 40; ++x) other.at(x, 12, 1) *= 3.0f;  // a bright line: the scores differ a lot
  const double ldr_a = flip(image, a).value, hdr_a = hdrflip(image, a).value;
  const double ldr_other = flip(image, other).value, hdr_other = hdrflip(image, other).value;
  ASSERT_NE(ldr_a, ldr_other);
  ASSERT_NE(hdr_a, hdr_other);
  // `b` is `a`'s pixels at another address: the same scores.
  EXPECT_EQ(flip(image, b).value, ldr_a);
  EXPECT_EQ(hdrflip(image, b).value, hdr_a);
  // `b` overwritten with `other`'s pixels, in place: scored as `other`, not as the `b` seen before.
  std::copy(other.data(), other.data() + other.size(), b.data());
  EXPECT_EQ(flip(image, b).value, ldr_other);
  EXPECT_EQ(hdrflip(image, b).value, hdr_other);
  EXPECT_EQ(hdrflip(image, a).value, hdr_a);
}

// Every pixel is computed alone and HDR-FLIP's maximum over exposures is exact, so the maps are
// the same bit for bit on one thread and on every core, and when several images are scored at
// once against one reference (the memo shared between threads).
TEST(FlipMemo, SameMapsOnOneThreadAndOnManyInParallel) {
  const Image ref = hdr_pattern(64, 48);
  std::vector<Image> images;
  for (std::uint32_t s = 0; s < 6; ++s) images.push_back(noisy(ref, 0.1f * float(s + 1), s));
  std::vector<MetricResult> one, many(images.size());
  {
    const tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    hdrflip(hdr_pattern(8, 8), hdr_pattern(8, 8));  // another reference first: nothing of `ref` kept
    for (const auto& im : images) one.push_back(hdrflip(im, ref));
  }
  hdrflip(hdr_pattern(8, 8), hdr_pattern(8, 8));
  tbb::parallel_for(std::size_t(0), images.size(), [&](std::size_t i) { many[i] = hdrflip(images[i], ref); });
  for (std::size_t i = 0; i < images.size(); ++i) {
    EXPECT_EQ(one[i].value, many[i].value) << "image " << i;
    ASSERT_EQ(one[i].map.size(), many[i].map.size());
    for (std::size_t p = 0; p < one[i].map.size(); ++p) ASSERT_EQ(one[i].map.data()[p], many[i].map.data()[p]) << i << " " << p;
  }
}

TEST(FlipPooling, HandComputedWeightedPercentiles) {
  // Sorted 0.1, 0.2, 0.3, 0.4, total 1.0; running sums 0.1, 0.3, 0.6, 1.0. The weighted
  // p-percentile is the first value whose running sum exceeds p: 0.25 -> 0.2, 0.5 -> 0.3, 0.75 -> 0.4.
  FlipPooled p = pool_flip(map_of({0.3f, 0.1f, 0.4f, 0.2f}));
  EXPECT_NEAR(p.mean, 0.25, 1e-7);  // float map values
  EXPECT_FLOAT_EQ(float(p.weighted_first_quartile), 0.2f);
  EXPECT_FLOAT_EQ(float(p.weighted_median), 0.3f);
  EXPECT_FLOAT_EQ(float(p.weighted_third_quartile), 0.4f);
  EXPECT_FLOAT_EQ(float(p.min), 0.1f);
  EXPECT_FLOAT_EQ(float(p.max), 0.4f);
  // "Exceeds", not "reaches": 1/8, 1/8, 1/4, 1/2 (exact) run 0.125, 0.25, 0.5, 1. The median's
  // running sum reaches 0.5 at 1/4 but first exceeds it at 1/2; the first quartile's at 1/4.
  p = pool_flip(map_of({0.5f, 0.125f, 0.25f, 0.125f}));
  EXPECT_EQ(p.weighted_median, 0.5);
  EXPECT_EQ(p.weighted_first_quartile, 0.25);
  EXPECT_EQ(p.weighted_third_quartile, 0.5);
  EXPECT_EQ(p.mean, 0.25);
}

TEST(FlipPooling, WeightingFollowsTheLargeErrors) {
  // Nine pixels of 0.01 and one of 0.9: the plain median is 0.01, but the large error carries
  // 0.9 / 0.99 of the total, so every weighted percentile up to 0.9 falls on it.
  Image m(10, 1, 1, 0.01f);
  m.at(6, 0, 0) = 0.9f;
  const FlipPooled p = pool_flip(m);
  EXPECT_NEAR(p.mean, 0.099, 1e-7);
  EXPECT_FLOAT_EQ(float(p.weighted_first_quartile), 0.9f);
  EXPECT_FLOAT_EQ(float(p.weighted_median), 0.9f);
  EXPECT_FLOAT_EQ(float(p.weighted_third_quartile), 0.9f);
  EXPECT_FLOAT_EQ(float(p.min), 0.01f);
}

TEST(FlipPooling, NoErrorPoolsToZeroAndBadMapsAreRefused) {
  const FlipPooled z = pool_flip(Image(3, 2, 1, 0.0f));
  for (double v : {z.mean, z.weighted_median, z.weighted_first_quartile, z.weighted_third_quartile, z.min, z.max})
    EXPECT_EQ(v, 0.0);
  EXPECT_THROW(pool_flip(Image(3, 2, 3, 0.5f)), InputError);
  EXPECT_THROW(pool_flip(Image()), InputError);
  Image nan(3, 2, 1, 0.5f);
  nan.at(2, 1, 0) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(pool_flip(nan), InputError);
  // The mean is the metric's value.
  const Image ref = hdr_pattern(16, 12), test = noisy(ref, 0.2f, 3);
  const MetricResult r = hdrflip(test, ref);
  EXPECT_NEAR(pool_flip(r.map).mean, r.value, 1e-7);  // the map holds floats
}

}  // namespace
}  // namespace dnb::metrics
