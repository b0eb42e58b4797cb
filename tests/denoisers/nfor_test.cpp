// nfor: first-order regression on the features. A colour that is exactly an affine function of
// the features is in the span of every window's regression, so it must come back unchanged;
// noise on such a colour is what the regression averages away.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "denoisers/method.h"
#include "denoisers/synthetic_frame.h"

namespace dnb {
namespace {

MethodResult run_nfor(const AovFrame& f, const std::map<std::string, std::string>& settings = {}) {
  auto m = MethodRegistry::global().create("nfor", settings);
  return run_method(*m, {.frame = &f});
}

// The planes scene's geometry (two planes, a crease, a depth ramp) with an albedo that varies
// everywhere (a checkerboard times a smooth ramp, different per channel), and a colour that is
// an affine function of albedo and normal per channel: F_c = 0.05 + (0.6 + 0.1 c) T_c + 0.2 n_x
// + 0.1 n_z. F and its half buffers carry noise of relative standard deviation `noise` (the
// halves sqrt(2) times that, independent; 0: all equal), and `variance` says F's noise has
// relative standard deviation `claimed_noise`.
AovFrame affine_frame(int w, int h, float noise, float claimed_noise) {
  AovFrame f = test::planes_frame(w, h, 0.0f);
  Image& albedo = f.layer(layer::kAlbedo);
  const Image& normal = f.layer(layer::kNormal);
  Image& color = f.layer(layer::kColor);
  Image sd(w, h, 3);
  Image& var = f.layer(layer::kVariance);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) {
        const float t = (((x / 6 + y / 6) % 2) ? 0.7f : 0.3f) * (0.6f + 0.4f * float(x + c * y) / float(w + 2 * h));
        albedo.at(x, y, c) = t;
        const float v = 0.05f + (0.6f + 0.1f * c) * t + 0.2f * normal.at(x, y, 0) + 0.1f * normal.at(x, y, 2);
        color.at(x, y, c) = v;
        sd.at(x, y, c) = noise * v;
        var.at(x, y, c) = (claimed_noise * v) * (claimed_noise * v);  // of the halves' mean
      }
  // The halves: features copied from the full layers; the colour's halves independent, each
  // the truth plus noise of sd sqrt(2) (so their mean has sd), and F their mean.
  test::set_halves(f);
  if (noise > 0) {
    std::mt19937_64 rng(17);
    std::normal_distribution<float> gauss(0.0f, 1.0f);
    Image h0 = color, h1 = color;
    for (std::size_t k = 0; k < color.size(); ++k) {
      h0.data()[k] += std::sqrt(2.0f) * sd.data()[k] * gauss(rng);
      h1.data()[k] += std::sqrt(2.0f) * sd.data()[k] * gauss(rng);
      color.data()[k] = 0.5f * (h0.data()[k] + h1.data()[k]);
    }
    f.set(layer::at_half(0, layer::kColor), std::move(h0));
    f.set(layer::at_half(1, layer::kColor), std::move(h1));
  }
  return f;
}

// Noise-free halves, but a variance layer that claims 20% noise, so that the NL-means weights
// take in the whole window (with a variance of 0 every other pixel's weight would be ~0 and
// each pixel would be fitted by itself alone: no test of the regression). Every window's
// weighted least squares fits the affine colour exactly, so the output is the input to float
// rounding (the sums of the 8x8 normal matrix and of the collaborative averages; the ridge of
// 1e-7 of the diagonal): 1e-4 relative, measured 4.9e-6. The same frame with a colour that is
// not affine (a sine of x added) is changed: the test can fail.
TEST(Nfor, AnAffineFunctionOfTheFeaturesComesBackUnchanged) {
  AovFrame f = affine_frame(64, 48, 0.0f, 0.2f);
  const Image& in = f.layer(layer::kColor);
  const Image out = run_nfor(f).image;
  double worst = 0;
  for (std::size_t k = 0; k < in.size(); ++k)
    worst = std::max(worst, std::abs(double(out.data()[k]) - in.data()[k]) / std::abs(double(in.data()[k])));
  std::printf("nfor on an affine colour: worst relative change %.3g\n", worst);
  EXPECT_LT(worst, 1e-4);

  for (const char* n : {layer::kColor, "half0.color", "half1.color"}) {
    Image& c = f.layer(n);
    for (int y = 0; y < 48; ++y)
      for (int x = 0; x < 64; ++x)
        for (int ch = 0; ch < 3; ++ch) c.at(x, y, ch) += 0.1f * std::sin(0.7f * x);
  }
  const Image& in2 = f.layer(layer::kColor);
  const Image out2 = run_nfor(f).image;
  double worst2 = 0;
  for (std::size_t k = 0; k < in2.size(); ++k)
    worst2 = std::max(worst2, std::abs(double(out2.data()[k]) - in2.data()[k]) / std::abs(double(in2.data()[k])));
  std::printf("nfor on a non-affine colour: worst relative change %.3g\n", worst2);
  EXPECT_GT(worst2, 0.01);
}

// 20% relative noise on F (28% per half): the regression lowers the MSE by more than
// 10x (the bar set for it; measured 88x).
TEST(Nfor, LowersTheErrorOfANoisyAffineFrameTenfold) {
  const AovFrame clean = affine_frame(64, 48, 0.0f, 0.0f);
  const AovFrame noisy = affine_frame(64, 48, 0.2f, 0.2f);
  const Image& truth = clean.layer(layer::kColor);
  const double before = test::mse(noisy.layer(layer::kColor), truth);
  const double after = test::mse(run_nfor(noisy).image, truth);
  std::printf("nfor on a noisy affine colour: mse %.3g -> %.3g (%.1fx)\n", before, after, before / after);
  EXPECT_LT(after, before / 10);
}

// Fireflies (a sun reached by one diffuse bounce: single samples thousands of times brighter
// than the rest) in the noisy affine frame's halves: the regression on a window holding one
// extrapolated it into negative and saturated blotches (McGuire's Sponza at 16 spp: 22% of the
// output negative, mse 7475 against the input's 941). With the harness's firefly cut on each
// half (firefly_ratio 3) and the clamp at 0, the output is never negative and the error stays
// below the input's; without the cut the fireflies' blotches hold most of the error.
TEST(Nfor, FirefliesInTheHalvesMakeNoBlotches) {
  const AovFrame clean = affine_frame(64, 48, 0.0f, 0.0f);
  AovFrame noisy = affine_frame(64, 48, 0.2f, 0.2f);
  std::mt19937_64 rng(5);
  for (int n = 0; n < 12; ++n) {
    const int x = 4 + int(rng() % 56), y = 4 + int(rng() % 40), h = int(rng() % 2);
    Image& half = noisy.layer(layer::at_half(h, layer::kColor));
    for (int c = 0; c < 3; ++c) {
      half.at(x, y, c) += 2000.0f;
      noisy.layer(layer::kColor).at(x, y, c) += 1000.0f;
      noisy.layer(layer::kVariance).at(x, y, c) = 1000.0f * 1000.0f;
    }
  }
  const Image& truth = clean.layer(layer::kColor);
  const Image cut = run_nfor(noisy).image;
  const Image kept = run_nfor(noisy, {{"firefly_ratio", "0"}}).image;
  float lowest = 0;
  for (std::size_t k = 0; k < cut.size(); ++k) lowest = std::min(lowest, cut.data()[k]);
  const double before = test::mse(noisy.layer(layer::kColor), truth);
  const double e_cut = test::mse(cut, truth), e_kept = test::mse(kept, truth);
  std::printf("nfor with fireflies: input mse %.3g, cut %.3g, kept %.3g\n", before, e_cut, e_kept);
  EXPECT_GE(lowest, 0.0f);
  EXPECT_LT(e_cut, 0.01 * before);
  EXPECT_LT(e_cut, 0.1 * e_kept) << "the cut made no difference: the frame does not show the effect";
}

}  // namespace
}  // namespace dnb
