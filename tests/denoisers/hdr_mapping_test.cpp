// The range maps of denoisers/hdr_mapping.h: inverse pairs, monotonic, bounded where documented.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

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

// Each name means the formula the header documents for it, written out again here in double:
// a parse_range_map that swapped two names, or a map whose formula changed, fails. (Tests that
// build their expectation with parse_range_map, as a method's would, cannot see a swap.)
// Tolerance 1e-6 relative: a few float roundings through log1p, pow and a division.
TEST(RangeMap, EachNameIsItsDocumentedFormula) {
  auto srgb = [](double v) { return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055; };
  struct Case {
    const char* name;
    RangeMap map;
    double (*formula)(double);
  };
  const Case cases[] = {
      {"linear", RangeMap::Linear, [](double x) { return x; }},
      {"log", RangeMap::Log, [](double x) { return std::log(1 + x); }},
      {"reinhard", RangeMap::Reinhard, [](double x) { return std::pow(x / (1 + x), 1 / 2.2); }},
      {"srgb", RangeMap::Srgb, nullptr},
  };
  std::vector<std::string> names;
  for (const auto& c : cases) {
    names.push_back(c.name);
    EXPECT_EQ(parse_range_map(c.name), c.map) << c.name;
    for (float x : {0.002f, 0.25f, 0.5f, 0.9f, 3.0f, 40.0f}) {
      const double want = c.formula ? c.formula(x) : srgb(std::min(double(x), 1.0));
      EXPECT_NEAR(compress(parse_range_map(c.name), x), want, 1e-6 * want) << c.name << " x=" << x;
    }
  }
  EXPECT_EQ(range_map_names(), names);  // the documented choices, no more, no fewer
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
