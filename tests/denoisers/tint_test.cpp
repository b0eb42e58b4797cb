// smooth_tint (denoisers/illumination.h): the lobe-choice noise of a coated surface's tint is
// averaged away, and what is not noise (a mirror's edge on a coplanar wall, a depth step, edge
// pixels, pixels without reflection) is left alone.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "denoisers/illumination.h"

namespace dnb {
namespace {

constexpr int kW = 48, kH = 32, kSpp = 256;
// The band proposed uses: 3 standard deviations of the lobe choice at pc = 0.2.
const float kBand = 3.0f * 2.0f / std::sqrt(float(kSpp));

struct Plane {
  Image tint{kW, kH, 3}, normal{kW, kH, 3}, depth{kW, kH, 1};
  Plane() {
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        normal.at(x, y, 2) = 1.0f;
        depth.at(x, y, 0) = 1.0f;
      }
  }
};

// A pixel's tint as the tracer makes it: each of kSpp samples picks the specular lobe with
// probability pc and then records expected / pc, the others 0.
float coated_sample(float expected, float pc, std::mt19937_64& rng) {
  std::binomial_distribution<int> picks(kSpp, pc);
  return expected / pc * float(picks(rng)) / float(kSpp);
}

// A coated plane whose expected tint (the Fresnel term) runs from 0.04 to 0.08 across the
// frame, at pc 0.2 (relative noise 12.5%): the smoothed tint's RMS error against the expectation
// is at most 0.3x the raw one. Averaging 25 pixels would give 0.2x; the bound leaves room for the
// band's trimming and the frame's border, where windows hold fewer pixels (measured 0.22x; one
// pass of the filter, centred on the pixel's own tint, measured 0.28x).
TEST(SmoothTint, AveragesAwayTheLobeChoiceNoise) {
  Plane p;
  std::mt19937_64 rng(3);
  Image expected(kW, kH, 1);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const float e = 0.04f + 0.04f * float(x) / float(kW - 1);
      expected.at(x, y, 0) = e;
      const float t = coated_sample(e, 0.2f, rng);
      for (int c = 0; c < 3; ++c) p.tint.at(x, y, c) = t;
    }
  const Image s = smooth_tint(p.tint, p.normal, p.depth, 2, kBand, 0.1f, 0.01f);
  double raw = 0, smooth = 0;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      const double e = expected.at(x, y, 0);
      raw += std::pow(p.tint.at(x, y, 0) - e, 2);
      smooth += std::pow(s.at(x, y, 0) - e, 2);
    }
  RecordProperty("rms_ratio", std::to_string(std::sqrt(smooth / raw)));
  EXPECT_LT(std::sqrt(smooth / raw), 0.3) << "raw " << raw << " smoothed " << smooth;
}

// A mirror (tint 0.9) on a coplanar wall (tint 0): same normal, same depth, so no edge pixel
// marks its border. The border column is partly covered (tint 0.9 x coverage): those pixels
// hold no noise, only the step, and must keep their tint to the bit, as must the mirror's
// inside and the wall; a row of pixels in `keep` stays as it is whatever its neighbours.
TEST(SmoothTint, LeavesStepsWallsAndKeptPixelsAlone) {
  Plane p;
  for (int y = 0; y < kH; ++y)
    for (int x = 20; x < kW; ++x) {
      const float t = x == 20 ? (y % 2 ? 0.3f * 0.9f : 0.55f * 0.9f) : 0.9f;  // coverage 0.3 or 0.55
      for (int c = 0; c < 3; ++c) p.tint.at(x, y, c) = t;
    }
  std::vector<char> keep(std::size_t(kW) * kH, 0);
  for (int x = 0; x < kW; ++x) {
    keep[std::size_t(10) * kW + x] = 1;
    for (int c = 0; c < 3; ++c) p.tint.at(x, 10, c) = 0.5f + 0.01f * float(x % 3);  // not smooth
  }
  const Image s = smooth_tint(p.tint, p.normal, p.depth, 2, kBand, 0.1f, 0.01f, &keep);
  EXPECT_TRUE(s == p.tint) << "something that is not lobe-choice noise was smoothed";
}

// Two surfaces side by side with noise-free tints 0.05 and 0.06, within each other's noise
// band (20% apart): separated by a depth step or by a crease (normals 0.2 apart), neither
// borrows from the other and nothing changes; on one plane they do mix, which shows the two
// tests above are not vacuous.
TEST(SmoothTint, DoesNotMixAcrossADepthStepOrACrease) {
  auto frame = [](bool depth_step, bool crease) {
    Plane p;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const bool right = x >= 24;
        for (int c = 0; c < 3; ++c) p.tint.at(x, y, c) = right ? 0.06f : 0.05f;
        if (right && depth_step) p.depth.at(x, y, 0) = 1.2f;
        if (right && crease) p.normal.at(x, y, 0) = 0.2f;  // |n_p - n_q| = 0.2 > 0.1
      }
    return p;
  };
  for (auto [depth_step, crease] : {std::pair{true, false}, std::pair{false, true}}) {
    const Plane p = frame(depth_step, crease);
    EXPECT_TRUE(smooth_tint(p.tint, p.normal, p.depth, 2, kBand, 0.1f, 0.01f) == p.tint)
        << (depth_step ? "across the depth step" : "across the crease");
  }
  const Plane flat = frame(false, false);
  const Image mixed = smooth_tint(flat.tint, flat.normal, flat.depth, 2, kBand, 0.1f, 0.01f);
  EXPECT_GT(mixed.at(23, 5, 0), 0.05f);
  EXPECT_LT(mixed.at(24, 5, 0), 0.06f);
}

TEST(SmoothTint, OffWithoutARadiusOrABand) {
  Plane p;
  std::mt19937_64 rng(1);
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x)
      for (int c = 0; c < 3; ++c) p.tint.at(x, y, c) = coated_sample(0.05f, 0.2f, rng);
  EXPECT_TRUE(smooth_tint(p.tint, p.normal, p.depth, 0, kBand, 0.1f, 0.01f) == p.tint);
  EXPECT_TRUE(smooth_tint(p.tint, p.normal, p.depth, 2, 0.0f, 0.1f, 0.01f) == p.tint);
  EXPECT_FALSE(smooth_tint(p.tint, p.normal, p.depth, 2, kBand, 0.1f, 0.01f) == p.tint);
}

}  // namespace
}  // namespace dnb
