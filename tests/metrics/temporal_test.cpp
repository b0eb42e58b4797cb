// Reprojection and the temporal metrics (metrics/temporal.h, docs/temporal-metrics.md) on
// constructed sequences whose answers are known: static, flickering, shifted by whole and
// fractional pixels, with a depth jump that uncovers the background.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <vector>

#include "core/errors.h"
#include "metrics/metrics.h"
#include "metrics/temporal.h"

namespace dnb::metrics {
namespace {

constexpr int kW = 24, kH = 16;

Image filled(int w, int h, int channels, const std::function<float(int, int, int)>& f) {
  Image img(w, h, channels);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < channels; ++c) img.at(x, y, c) = f(x, y, c);
  return img;
}

Image constant(int channels, float v) { return Image(kW, kH, channels, v); }
Image motion_of(float mx, float my) {
  return filled(kW, kH, 2, [&](int, int, int c) { return c == 0 ? mx : my; });
}
Image facing_camera() { return filled(kW, kH, 3, [](int, int, int c) { return c == 2 ? 1.0f : 0.0f; }); }

// A static sequence (zero motion, one depth and normal) of outputs and references.
TemporalScores score_static(const std::vector<Image>& outputs, const std::vector<Image>& references) {
  const Image motion = motion_of(0, 0), depth = constant(1, 2.0f), normal = facing_camera();
  TemporalScorer scorer;
  for (std::size_t t = 0; t < outputs.size(); ++t)
    scorer.add({.output = &outputs[t], .reference = &references[t], .motion = &motion, .depth = &depth,
                .normal = &normal});
  return scorer.scores();
}

// An output equal to its reference, over a static camera, has no temporal error, however the
// reference itself changes from frame to frame (here it brightens): only the difference of the
// output's change from the reference's counts. Nothing is disoccluded, so disocclusion_mse has
// no frame (NaN).
TEST(TemporalMetrics, StaticSequenceEqualToTheReferenceHasNoTemporalError) {
  std::vector<Image> frames;
  for (int t = 0; t < 5; ++t)
    frames.push_back(filled(kW, kH, 3, [&](int x, int y, int c) { return 0.05f * t + 0.01f * (x + y + c); }));
  const TemporalScores s = score_static(frames, frames);
  EXPECT_EQ(s.tmse, 0.0);
  ASSERT_EQ(s.tmse_per_frame.size(), 5u);
  EXPECT_TRUE(std::isnan(s.tmse_per_frame[0]));  // no previous frame
  for (int t = 1; t < 5; ++t) EXPECT_EQ(s.tmse_per_frame[t], 0.0) << t;
  EXPECT_TRUE(std::isnan(s.disocclusion_mse));
  for (std::size_t n : s.disoccluded_pixels) EXPECT_EQ(n, 0u);
}

// Flicker around a constant: the reference is 0.2 in every frame, the output alternates
// 0.2, 0.25, 0.2, 0.25, ... (static camera). By hand, on the 8-bit scale of mse:
//   0.2  -> sRGB 1.055 * 0.2^(1/2.4) - 0.055 = 0.48453 -> x255 = 123.55 -> 124
//   0.25 -> sRGB 1.055 * 0.25^(1/2.4) - 0.055 = 0.53710 -> x255 = 136.96 -> 137
// so each frame t >= 1 has O_t - O_{t-1} = +-13 in every channel and R_t - R_{t-1} = 0:
// tmse = 13^2 = 169 per frame and pooled. The still metric sees only every other frame (mse 0 on
// the even frames, 169 on the odd: a mean of 84.5 over 6 frames); tmse sees every change.
TEST(TemporalMetrics, FlickeringConstantHasTheTemporalErrorComputedByHand) {
  std::vector<Image> outputs, references;
  for (int t = 0; t < 6; ++t) {
    outputs.push_back(constant(3, t % 2 ? 0.25f : 0.2f));
    references.push_back(constant(3, 0.2f));
  }
  EXPECT_EQ(mse(outputs[1], references[1]).value, 169.0);  // the hand arithmetic's 8-bit values
  const TemporalScores s = score_static(outputs, references);
  EXPECT_EQ(s.tmse, 169.0);
  for (int t = 1; t < 6; ++t) EXPECT_EQ(s.tmse_per_frame[t], 169.0) << t;
}

// True motion does not count: an output that is the reference darkened (a fixed bias that moves
// with the content) over a camera panning 3 px right per frame has tmse 0 over the pixels with
// history. Ignoring the motion (zero motion vectors) the same frames score well above 0: the
// warp is what removes the motion.
TEST(TemporalMetrics, TrueMotionDoesNotCountAndIgnoringItDoes) {
  const auto scene = [](int t) {  // content at world column x + 3t (the camera pans right)
    return filled(kW, kH, 3, [t](int x, int y, int c) { return 0.1f + 0.4f * float(((x + 3 * t) / 4 + y / 4 + c) % 2); });
  };
  const auto darker = [](Image img) {
    for (std::size_t k = 0; k < img.size(); ++k) img.data()[k] *= 0.5f;
    return img;
  };
  const Image depth = constant(1, 2.0f), normal = facing_camera();
  // Pixel x of frame t sees world column x + 3t, which frame t - 1 showed at x + 3.
  const Image motion = motion_of(3, 0), none = motion_of(0, 0);
  TemporalScorer with_motion, without;
  std::vector<Image> r, o;
  for (int t = 0; t < 4; ++t) {
    r.push_back(scene(t));
    o.push_back(darker(r.back()));
  }
  for (int t = 0; t < 4; ++t) {
    with_motion.add({.output = &o[t], .reference = &r[t], .motion = &motion, .depth = &depth, .normal = &normal});
    without.add({.output = &o[t], .reference = &r[t], .motion = &none, .depth = &depth, .normal = &normal});
  }
  const TemporalScores a = with_motion.scores(), b = without.scores();
  EXPECT_EQ(a.tmse, 0.0);
  // The pixels whose history would come from beyond the right border: the last 3 columns.
  EXPECT_EQ(a.disoccluded_pixels[1], std::size_t(3 * kH));
  // Without the warp the checker's cells seem to change: 0.1 <-> 0.5 is 89 <-> 188 in 8 bits (99
  // levels), the darkened 0.05 <-> 0.25 is 63 <-> 137 (74), so a pixel whose cell changed scores
  // (99 - 74)^2 = 625, and a shift of 3 changes 6 pixels of the checker's period of 8: about 470.
  EXPECT_GT(b.tmse, 100.0);
}

// An image shifted by a whole number of pixels is recovered exactly: frame t - 1 holds a
// pattern, the current frame is it moved 3 px left and 2 px down, so pixel (x, y) was at
// (x + 3, y - 2): motion (3, -2). Where that falls outside the previous frame (the last 3
// columns, the first 2 rows) the mask is 0, everywhere else 1 and the value exact (one tap of
// weight 1).
TEST(Reproject, IntegerShiftIsRecoveredAndPixelsFromOutsideAreFlagged) {
  const Image previous = filled(kW, kH, 3, [](int x, int y, int c) { return float(x * 100 + y * 3 + c); });
  const Reprojected r = reproject(previous, motion_of(3, -2));
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const bool inside = x + 3 < kW && y - 2 >= 0;
      EXPECT_EQ(r.valid.at(x, y, 0), inside ? 1.0f : 0.0f) << x << "," << y;
      if (inside) {
        for (int c = 0; c < 3; ++c) ASSERT_EQ(r.image.at(x, y, c), previous.at(x + 3, y - 2, c)) << x << "," << y;
      }
    }
}

// A sub-pixel motion on an image linear in x and y: bilinear interpolation reproduces a linear
// function exactly, so the warped value is the function at the shifted position,
// f(x + 0.25, y - 0.5) (pixel-centre coordinates), to float rounding (values up to about 50:
// 1e-4 is a few ulps). The half-pixel step in y is the average of two rows. Every position
// stays inside the image ([0.75, w - 0.25] x [0, h - 1]); those within half a pixel of the border
// read the border pixel (clamped), so the exact check is on the interior. A motion of one pixel
// to the left takes the first column's positions to x = -0.5: outside.
TEST(Reproject, SubPixelMotionOfALinearImageIsRecoveredInTheInterior) {
  const auto f = [](double x, double y) { return 1.0 + 2.0 * x + 0.5 * y; };
  const Image previous = filled(kW, kH, 1, [&](int x, int y, int) { return float(f(x, y)); });
  const Reprojected r = reproject(previous, motion_of(0.25f, -0.5f));
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      EXPECT_EQ(r.valid.at(x, y, 0), 1.0f) << x << "," << y;
      if (x < kW - 1 && y >= 1) {  // the interior: every tap inside, no clamping
        EXPECT_NEAR(r.image.at(x, y, 0), f(x + 0.25, y - 0.5), 1e-4) << x << "," << y;
      }
    }
  // One pixel further and the left column's positions fall outside.
  const Reprojected far = reproject(previous, motion_of(-1.0f, 0));
  for (int y = 0; y < kH; ++y) {
    EXPECT_EQ(far.valid.at(0, y, 0), 0.0f);
    EXPECT_EQ(far.valid.at(1, y, 0), 1.0f);
  }
}

// A disocclusion: a box at depth 1 in front of a wall at depth 5 moves 4 px right between the
// frames (static camera). Its pixels now at columns 10..19 were at 6..15 (motion -4) and keep
// their history; the wall's pixels at 6..9, covered by the box in the previous frame, now
// reproject (motion 0) onto the box's depth there: disoccluded. The rest of the wall is valid.
// And a miss (depth 0, the sky) matches only a miss: the top row shows sky now, and the wall in
// the previous frame above column 12 only.
TEST(DisocclusionMask, DepthJumpAndSkyAreMasked) {
  const auto box_at = [](int x0) {
    return filled(kW, kH, 1, [x0](int x, int, int) { return x >= x0 && x < x0 + 10 ? 1.0f : 5.0f; });
  };
  Image depth = box_at(10), previous_depth = box_at(6);
  for (int x = 0; x < kW; ++x) {
    depth.at(x, 0, 0) = 0;                              // sky now along the top row
    previous_depth.at(x, 0, 0) = x < 12 ? 0.0f : 5.0f;  // and before, left of column 12
  }
  const Image motion = filled(kW, kH, 2, [&](int x, int y, int c) {
    return c == 0 && depth.at(x, y, 0) == 1.0f ? -4.0f : 0.0f;
  });
  const Image normal = facing_camera();
  const Image mask = disocclusion_mask(motion, depth, normal, previous_depth, normal);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const bool expected = y == 0 ? x < 12 : !(x >= 6 && x < 10);
      EXPECT_EQ(mask.at(x, y, 0), expected ? 1.0f : 0.0f) << x << "," << y;
    }
  // Normals turned by more than the test's 25.8 degrees (here 45) also reject: a surface that
  // rotated, or another face at the same depth.
  const Image turned = filled(kW, kH, 3, [](int, int, int c) { return c == 0 ? 0.70710678f : c == 2 ? 0.70710678f : 0.0f; });
  const Image flat = constant(1, 5.0f);
  const Image rotated = disocclusion_mask(motion_of(0, 0), flat, normal, flat, turned);
  for (std::size_t k = 0; k < rotated.size(); ++k) EXPECT_EQ(rotated.data()[k], 0.0f);
  // And depths 5 and 5.4 (8% apart) match, 5 and 6 (17%) do not.
  EXPECT_EQ(disocclusion_mask(motion_of(0, 0), flat, normal, constant(1, 5.4f), normal).at(3, 3, 0), 1.0f);
  EXPECT_EQ(disocclusion_mask(motion_of(0, 0), flat, normal, constant(1, 6.0f), normal).at(3, 3, 0), 0.0f);
}

// disocclusion_mse scores the disoccluded pixels only, and averages over the frames that have
// any. Frame 1: the box of the test above uncovers 4 columns of wall (4 x 16 pixels). The output is exact except on those
// pixels, where it is 0.25 against the reference's 0.2 (13 levels: 169). Frame 2: nothing moves,
// nothing is disoccluded. So frame 1 scores 169, frame 2 NaN, and the sequence 169.
TEST(TemporalMetrics, DisocclusionMseScoresTheUncoveredPixelsOnly) {
  const auto box_at = [](int x0) {
    return filled(kW, kH, 1, [x0](int x, int, int) { return x >= x0 && x < x0 + 10 ? 1.0f : 5.0f; });
  };
  const Image d0 = box_at(6), d1 = box_at(10), normal = facing_camera();
  const Image m1 = filled(kW, kH, 2, [&](int x, int y, int c) { return c == 0 && d1.at(x, y, 0) == 1.0f ? -4.0f : 0.0f; });
  const Image still = motion_of(0, 0);
  const Image reference = constant(3, 0.2f);
  Image ghosted = reference;
  for (int y = 0; y < kH; ++y)
    for (int x = 6; x < 10; ++x)
      for (int c = 0; c < 3; ++c) ghosted.at(x, y, c) = 0.25f;
  TemporalScorer scorer;
  scorer.add({.output = &reference, .reference = &reference, .depth = &d0, .normal = &normal});
  scorer.add({.output = &ghosted, .reference = &reference, .motion = &m1, .depth = &d1, .normal = &normal});
  scorer.add({.output = &ghosted, .reference = &reference, .motion = &still, .depth = &d1, .normal = &normal});
  const TemporalScores s = scorer.scores();
  EXPECT_EQ(s.disoccluded_pixels[1], std::size_t(4 * kH));
  EXPECT_EQ(s.disocclusion_mse_per_frame[1], 169.0);
  EXPECT_EQ(s.disoccluded_pixels[2], 0u);
  EXPECT_TRUE(std::isnan(s.disocclusion_mse_per_frame[2]));
  EXPECT_EQ(s.disocclusion_mse, 169.0);
  // The still mse of frame 1 dilutes the same error over the whole image (64 of 384 pixels).
  EXPECT_NEAR(mse(ghosted, reference).value, 169.0 * 64 / 384, 1e-9);
}

TEST(TemporalMetrics, RefusesMismatchedLayers) {
  const Image a = constant(3, 0.2f), depth = constant(1, 2.0f), normal = facing_camera();
  const Image small(kW - 1, kH, 3, 0.2f), motion3 = constant(3, 0.0f);
  TemporalScorer scorer;
  scorer.add({.output = &a, .reference = &a, .depth = &depth, .normal = &normal});
  EXPECT_THROW(scorer.add({.output = &a, .reference = &a, .depth = &depth, .normal = &normal}), InputError);  // no motion
  EXPECT_THROW(scorer.add({.output = &a, .reference = &a, .motion = &motion3, .depth = &depth, .normal = &normal}),
               InputError);
  EXPECT_THROW(reproject(small, motion_of(0, 0)), InputError);
}

}  // namespace
}  // namespace dnb::metrics
