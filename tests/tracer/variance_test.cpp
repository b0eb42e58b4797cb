// The variance layers mean what they say: over many seeds, the variance a render
// predicts for a pixel's mean agrees with the measured seed-to-seed variance of that mean. The
// tracer stratifies film positions, so its samples are not independent and the sample variance
// of a pixel's samples / n overstates the variance of its mean (by 2.8x in RMSE on McGuire's
// Cornell box at 1024 spp, with the older stratified sampler); the layers come from the spread
// of the eight independent sample groups' means instead (render.cpp's top).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "tracer/reference.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"

namespace dnb {
namespace {

// Per pixel and channel, over seeds: the mean of the predicted variance and the sample variance
// of the value.
struct SeedStats {
  std::vector<double> sum, sum_sq, predicted;
  int seeds = 0;
  void add(const Image& value, const Image& var) {
    if (sum.empty()) sum.assign(value.size(), 0), sum_sq.assign(value.size(), 0), predicted.assign(value.size(), 0);
    for (std::size_t k = 0; k < value.size(); ++k) {
      sum[k] += value.data()[k];
      sum_sq[k] += double(value.data()[k]) * value.data()[k];
      predicted[k] += var.data()[k];
    }
    ++seeds;
  }
  double measured(std::size_t k) const {
    const double m = sum[k] / seeds;
    return std::max(0.0, (sum_sq[k] - m * sum[k]) / (seeds - 1));
  }
  // Pooled over the pixels `use` selects: mean predicted variance / measured variance.
  template <typename Use>
  double ratio(Use use, int channels, int* count = nullptr) const {
    double p = 0, m = 0;
    int n = 0;
    for (std::size_t k = 0; k < sum.size(); ++k) {
      if (!use(k / channels)) continue;
      p += predicted[k] / seeds;
      m += measured(k);
      ++n;
    }
    if (count) *count = n;
    return p / m;
  }
};

// How close the ratio must be to 1, and why: the pooled measured variance over M seeds of P
// pixel-channels has a relative standard error of about sqrt(2 / (M - 1)) / sqrt(P_eff), which
// the caustics' heavy tails raise, most on the 25 pixels off the edge set (the mirror sphere's
// caustic on the floor carries their indirect light). Measured over the seeds 1..M with a variant
// of this sampler (every vertex from the sequences): 0.997 / 0.997 / 0.996 for all pixels at
// M = 800 / 4000 / 40000, the subset's colour 0.79 / 0.95 / 0.995 and its indirect 0.79 / 0.94 /
// 0.999: no bias, and M = 4000 (10 s) keeps the subset's noise inside the 10% tolerance. This
// tracer reads 0.996 (all), 1.018 and 1.016 (the subset) at M = 4000. What the tolerance catches:
// the sample variance of a pixel's samples / n, which ignores the stratification, read 2.94 (frame
// colour; 2.95 on edge pixels, 0.98 off them) and 1.83 (reference) here at 400 seeds, with a
// sampler of one sample per stratum.
constexpr double kTolerance = 0.10;
constexpr int kSeeds = 4000;
constexpr int kReferenceSeeds = 800;  // all pixels only: 1.016 at 800

// The test frames: cornell-box at 16x12 (most pixels hold an edge there, where a plain
// sample variance is furthest off).
RenderSettings small_render(int spp) {
  RenderSettings s;
  s.width = 16;
  s.height = 12;
  s.spp = spp;
  return s;
}

TEST(VarianceOfTheMean, FrameLayersPredictTheSeedToSeedVariance) {
  auto scene = load_scene("cornell-box");
  RenderSettings s = small_render(16);
  s.reflection_levels = 0;
  s.edge_subpixels = false;
  SeedStats color, direct, indirect, half[2];
  std::vector<int> edge_count(std::size_t(s.width) * s.height, 0);
  for (int seed = 1; seed <= kSeeds; ++seed) {
    s.seed = std::uint64_t(seed);
    AovFrame f = render_frame(*scene, s);
    color.add(f.layer(layer::kColor), f.layer(layer::kVariance));
    direct.add(f.layer(layer::kDirect), f.layer(layer::kDirectVariance));
    indirect.add(f.layer(layer::kIndirect), f.layer(layer::kIndirectVariance));
    // A half buffer holds four of the eight groups: the variance of its mean is twice the
    // frame's, and twice is what holds only when the two halves are uncorrelated
    // (Var F = (Var h0 + Var h1 + 2 Cov) / 4).
    Image twice = f.layer(layer::kVariance);
    for (std::size_t k = 0; k < twice.size(); ++k) twice.data()[k] *= 2;
    for (int h = 0; h < 2; ++h) half[h].add(f.layer(layer::at_half(h, layer::kColor)), twice);
    const Image& g = f.layer(layer::kEdge);
    for (std::size_t p = 0; p < edge_count.size(); ++p) edge_count[p] += g.data()[p] > 0;
  }
  auto all = [](std::size_t) { return true; };
  auto edge = [&](std::size_t p) { return edge_count[p] > kSeeds / 2; };
  auto flat = [&](std::size_t p) { return edge_count[p] == 0; };
  int n_edge = 0, n_flat = 0;
  const double r_all = color.ratio(all, 3), r_edge = color.ratio(edge, 3, &n_edge), r_flat = color.ratio(flat, 3, &n_flat);
  const double r_direct = direct.ratio(flat, 3), r_indirect = indirect.ratio(flat, 3);
  const double r_half0 = half[0].ratio(all, 3), r_half1 = half[1].ratio(all, 3);
  std::printf("predicted / measured variance of the mean over %d seeds: colour %.3f (edge %.3f over %d, flat %.3f over %d), "
              "direct %.3f, indirect %.3f (flat)\n",
              kSeeds, r_all, r_edge, n_edge / 3, r_flat, n_flat / 3, r_direct, r_indirect);
  std::printf("half buffers: 2 x predicted / measured: half0 %.3f, half1 %.3f\n", r_half0, r_half1);
  ASSERT_GT(n_edge, 3 * 10);  // the test needs both kinds of pixel
  ASSERT_GT(n_flat, 3 * 10);
  EXPECT_NEAR(r_all, 1.0, kTolerance);
  EXPECT_NEAR(r_edge, 1.0, kTolerance);
  EXPECT_NEAR(r_flat, 1.0, kTolerance);
  EXPECT_NEAR(r_direct, 1.0, kTolerance);
  EXPECT_NEAR(r_indirect, 1.0, kTolerance);
  EXPECT_NEAR(r_half0, 1.0, kTolerance);
  EXPECT_NEAR(r_half1, 1.0, kTolerance);
}

TEST(VarianceOfTheMean, ReferenceVariancePredictsTheSeedToSeedVariance) {
  // The reference's blocks, as tracer/reference_image.cpp renders and adds them.
  auto scene = load_scene("cornell-box");
  RenderSettings s = small_render(32);
  BlockJob job;
  job.width = s.width;
  job.height = s.height;
  job.spp = s.spp;
  job.block_spp = 7;  // ranges that cut across the sample groups
  job.progress = false;
  SeedStats color;
  for (int seed = 1; seed <= kReferenceSeeds; ++seed) {
    s.seed = std::uint64_t(seed);
    const BlockResult b = accumulate_blocks(job, [&](int begin, int end, const std::function<void(std::int64_t)>&) {
      return render_color_sums(*scene, s, begin, end);
    });
    color.add(b.sums.mean(), b.sums.variance_of_mean());
  }
  const double r = color.ratio([](std::size_t) { return true; }, 3);
  std::printf("reference: predicted / measured variance of the mean over %d seeds: %.3f\n", kReferenceSeeds, r);
  EXPECT_NEAR(r, 1.0, kTolerance);
}

}  // namespace
}  // namespace dnb
