// The range maps of denoisers/hdr_mapping.h: inverse pairs, monotonic, bounded where documented.
#include <gtest/gtest.h>

#include <cmath>

#include "core/errors.h"
#include "denoisers/hdr_mapping.h"

namespace dnb {
namespace {

// expand(compress(x)) == x to float precision over the range each map keeps. Tolerance: 1e-5
// relative (a few ulps through log1p/expm1 or pow and a division); reinhard's t/(1-t) loses
// relative precision as t -> 1, so its range is checked to x = 100.
TEST(RangeMap, ExpandInvertsCompress) {
  struct Case {
    RangeMap map;
    float hi;
  } cases[] = {{RangeMap::Linear, 1e4f}, {RangeMap::Log, 1e4f}, {RangeMap::Reinhard, 100.0f}, {RangeMap::Srgb, 1.0f}};
  for (const auto& c : cases)
    for (float x = 1e-4f; x <= c.hi; x *= 1.37f) {
      const float back = expand(c.map, compress(c.map, x));
      EXPECT_NEAR(back, x, 1e-5f * x + 1e-7f) << int(c.map) << " x=" << x;
    }
}

TEST(RangeMap, MonotonicAndBounded) {
  for (RangeMap m : {RangeMap::Log, RangeMap::Reinhard, RangeMap::Srgb}) {
    float prev = compress(m, 0.0f);
    EXPECT_EQ(prev, 0.0f);
    for (float x = 1e-3f; x < 1e3f; x *= 1.5f) {
      const float y = compress(m, x);
      EXPECT_GE(y, prev);
      prev = y;
    }
    EXPECT_EQ(compress(m, -1.0f), 0.0f);  // negative radiance clamps to 0
  }
  EXPECT_LT(compress(RangeMap::Reinhard, 1e6f), 1.0f + 1e-6f);
  EXPECT_EQ(compress(RangeMap::Srgb, 7.0f), 1.0f);
  EXPECT_TRUE(std::isfinite(expand(RangeMap::Reinhard, 1.0f)));  // the top 8-bit code stays finite
}

TEST(RangeMap, NamesParseAndUnknownIsRefused) {
  for (const auto& n : range_map_names()) EXPECT_NO_THROW(parse_range_map(n));
  EXPECT_THROW(parse_range_map("gamma"), InputError);
}

TEST(RangeMap, To8BitRoundsTheCompressedValue) {
  Image img(2, 1, 1);
  img.at(0, 0, 0) = 0.5f;
  img.at(1, 0, 0) = 3.0f;
  cv::Mat m = to_8bit(RangeMap::Srgb, img);
  EXPECT_EQ(m.at<std::uint8_t>(0, 0), std::uint8_t(std::lround(255 * compress(RangeMap::Srgb, 0.5f))));
  EXPECT_EQ(m.at<std::uint8_t>(0, 1), 255);
}

}  // namespace
}  // namespace dnb
