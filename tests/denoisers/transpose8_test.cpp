// The layout moves of the adaptive-manifold core (denoisers/am/transpose8.h): every element where
// the element loops put it, the padding channels zero, and nothing written outside the rows,
// for widths and channel counts that do and do not fill whole 8 x 8 blocks.
#include <gtest/gtest.h>

#include <vector>

#include "denoisers/am/transpose8.h"

namespace dnb::am_detail {
namespace {

// A distinct value per (channel, pixel), so that a misplaced element shows.
float value(int c, int x) { return float(1000 * (c + 1) + x) + 0.25f; }

constexpr float kGuard = -7.5f;  // around every row: a write outside it changes it

TEST(Transpose8, PlanarToInterleavedAndBack) {
  for (int w : {1, 7, 8, 9, 23, 64, 131})
    for (int n : {1, 3, 4, 7, 8, 9, 16, 17}) {
      SCOPED_TRACE("w " + std::to_string(w) + ", channels " + std::to_string(n));
      const int dp = 8 * ((n + 7) / 8);
      std::vector<std::vector<float>> planes(static_cast<std::size_t>(n));
      std::vector<const float*> in(static_cast<std::size_t>(n));
      for (int c = 0; c < n; ++c) {
        planes[std::size_t(c)].resize(std::size_t(w));
        for (int x = 0; x < w; ++x) planes[std::size_t(c)][std::size_t(x)] = value(c, x);
        in[std::size_t(c)] = planes[std::size_t(c)].data();
      }
      // The interleaved row between guards; stale values where the padding goes.
      std::vector<float> il(std::size_t(w) * dp + 16, 99.0f);
      for (int k = 0; k < 8; ++k) il[std::size_t(k)] = il[il.size() - 1 - std::size_t(k)] = kGuard;
      to_interleaved(in.data(), n, w, il.data() + 8, dp);
      for (int k = 0; k < 8; ++k) {
        EXPECT_EQ(il[std::size_t(k)], kGuard);
        EXPECT_EQ(il[il.size() - 1 - std::size_t(k)], kGuard);
      }
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < dp; ++c)
          ASSERT_EQ(il[8 + std::size_t(x) * dp + c], c < n ? value(c, x) : 0.0f) << "pixel " << x << " channel " << c;

      // And back, into fresh planes between guards.
      std::vector<std::vector<float>> back(std::size_t(n), std::vector<float>(std::size_t(w) + 16, kGuard));
      std::vector<float*> out(static_cast<std::size_t>(n));
      for (int c = 0; c < n; ++c) out[std::size_t(c)] = back[std::size_t(c)].data() + 8;
      from_interleaved(il.data() + 8, dp, w, out.data(), n);
      for (int c = 0; c < n; ++c)
        for (int x = -8; x < w + 8; ++x)
          ASSERT_EQ(back[std::size_t(c)][std::size_t(x + 8)], x >= 0 && x < w ? value(c, x) : kGuard)
              << "channel " << c << " pixel " << x;
    }
}

// An image's pixels (stride = its channel count, or more) to planes: the guide's and the
// source's copies read 8 floats from each pixel only where those stay inside the row.
TEST(Transpose8, PixelsOfAnyStrideToPlanar) {
  for (int w : {1, 5, 8, 9, 16, 33, 100})
    for (auto [n, stride] : {std::pair{1, 1}, {3, 3}, {4, 4}, {7, 7}, {3, 8}, {7, 8}, {10, 10}, {9, 16}}) {
      SCOPED_TRACE("w " + std::to_string(w) + ", channels " + std::to_string(n) + ", stride " + std::to_string(stride));
      // The row alone in its allocation, so that a read past its end is a sanitizer's error.
      std::vector<float> row(std::size_t(w) * stride);
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < stride; ++c) row[std::size_t(x) * stride + c] = c < n ? value(c, x) : -1.0f;
      std::vector<std::vector<float>> planes(std::size_t(n), std::vector<float>(std::size_t(w) + 16, kGuard));
      std::vector<float*> out(static_cast<std::size_t>(n));
      for (int c = 0; c < n; ++c) out[std::size_t(c)] = planes[std::size_t(c)].data() + 8;
      from_interleaved(row.data(), stride, w, out.data(), n);
      for (int c = 0; c < n; ++c)
        for (int x = -8; x < w + 8; ++x)
          ASSERT_EQ(planes[std::size_t(c)][std::size_t(x + 8)], x >= 0 && x < w ? value(c, x) : kGuard)
              << "channel " << c << " pixel " << x;
    }
}

}  // namespace
}  // namespace dnb::am_detail
