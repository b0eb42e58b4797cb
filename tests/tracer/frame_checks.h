// Checks on rendered frames shared by the tracer's tests.
#pragma once

#include <gtest/gtest.h>

#include <cmath>

#include "core/aov_frame.h"

namespace dnb::test {

// Mean of channel c of a layer over all pixels, and the standard error of that mean from the
// per-pixel variance of the mean (pixels are independent).
inline void image_mean(const Image& value, const Image& var_of_mean, int c, double& mean, double& se) {
  double s = 0, v = 0;
  const double n = double(value.pixel_count());
  for (int y = 0; y < value.height(); ++y)
    for (int x = 0; x < value.width(); ++x) {
      s += value.at(x, y, c);
      v += var_of_mean.at(x, y, c);
    }
  mean = s / n;
  se = std::sqrt(v) / n;
}

// The paper's split F = (D + I) * T + R + E on every pixel and channel of frame f's level 0.
// Only float rounding separates the two, with u = 2^-24 (float's unit roundoff) and every term
// non-negative (no cancellation): F holds a sample's colour (d + i) * t + r + e in float (4
// roundings) and its double mean stored as float (1); the composed side holds d * t per sample in
// float (1) and D, T, R, E stored as floats (1 each, 2 for D * T). First order that is 5u + 3u =
// 8u relative; 10u leaves room for second-order terms (measured worst: 2.6u). The absolute 1e-9
// is demodulated()'s other branch (albedo mean under 1e-12, where D * T is off by at most
// 1e-12 * D) on pixels near black.
inline void expect_split_holds(const AovFrame& f) {
  const Image& F = f.layer(layer::kColor);
  const Image& D = f.layer(layer::kDirect);
  const Image& I = f.layer(layer::kIndirect);
  const Image& T = f.layer(layer::kAlbedo);
  const Image& R = f.layer(layer::kReflection);
  const Image& E = f.layer(layer::kEmission);
  const double u = 0x1p-24;
  for (int y = 0; y < F.height(); ++y)
    for (int x = 0; x < F.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        const double composed = (double(D.at(x, y, c)) + I.at(x, y, c)) * T.at(x, y, c) + R.at(x, y, c) + E.at(x, y, c);
        const double fv = F.at(x, y, c);
        ASSERT_TRUE(std::isfinite(fv)) << x << "," << y << " c" << c;
        EXPECT_LE(std::fabs(composed - fv), 10 * u * std::fabs(fv) + 1e-9) << x << "," << y << " c" << c;
      }
}

// R split as Cycles splits it, R = gc (gd + gi) + tc (td + ti), on every pixel and channel of
// frame f. Per sample a part is tint x (part of the next level's light) where R is tint x (all of
// it), or a lobe's weight x (first emission, rest) where R adds weight x (their sum): 2 roundings
// each side plus the additions of the four parts (3); the pixel means are sums in double stored
// as float (1 for R, 2 for each colour-weighted product). First order about 8u relative (every
// term non-negative), so 16u; the absolute 1e-9 covers pixels whose R is near 0.
inline void expect_specular_split_holds(const AovFrame& f) {
  const Image& R = f.layer(layer::kReflection);
  const Image& gd = f.layer(layer::kGlossDirect);
  const Image& gi = f.layer(layer::kGlossIndirect);
  const Image& gc = f.layer(layer::kGlossColor);
  const Image& td = f.layer(layer::kTransDirect);
  const Image& ti = f.layer(layer::kTransIndirect);
  const Image& tc = f.layer(layer::kTransColor);
  const double u = 0x1p-24;
  for (int y = 0; y < R.height(); ++y)
    for (int x = 0; x < R.width(); ++x)
      for (int c = 0; c < 3; ++c) {
        const double composed = double(gc.at(x, y, c)) * (double(gd.at(x, y, c)) + gi.at(x, y, c)) +
                                double(tc.at(x, y, c)) * (double(td.at(x, y, c)) + ti.at(x, y, c));
        const double r = R.at(x, y, c);
        EXPECT_LE(std::fabs(composed - r), 16 * u * std::fabs(r) + 1e-9) << x << "," << y << " c" << c;
      }
}

}  // namespace dnb::test
