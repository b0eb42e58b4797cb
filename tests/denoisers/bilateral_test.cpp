// bilateral: it is OpenCV's bilateralFilter, run in the documented range-compressed domain.
#include <gtest/gtest.h>

#include <utility>

#include <opencv2/imgproc.hpp>

#include "denoisers/hdr_mapping.h"
#include "denoisers/method.h"
#include "denoisers/synthetic_frame.h"

namespace dnb {
namespace {

MethodResult run_bilateral(const AovFrame& f, const std::map<std::string, std::string>& settings) {
  auto m = MethodRegistry::global().create("bilateral", settings);
  return run_method(*m, {.frame = &f});
}

// The method is exactly compress -> cv::bilateralFilter -> expand, bit for bit.
TEST(Bilateral, IsOpenCvBilateralInTheCompressedDomain) {
  AovFrame f = test::planes_frame(50, 40, 0.3f);
  // The maps are named here, not parsed: parse_range_map is what is under test too (a swap of
  // two names would otherwise change both sides alike).
  const std::pair<const char*, RangeMap> maps[] = {
      {"linear", RangeMap::Linear}, {"log", RangeMap::Log}, {"reinhard", RangeMap::Reinhard}};
  for (const auto& [map, range_map] : maps) {
    Image y = f.layer(layer::kColor);
    compress(range_map, y);
    cv::Mat dst;
    cv::bilateralFilter(as_mat(y), dst, 7, 0.2, 2.5, cv::BORDER_REFLECT);
    Image expected = from_mat(dst);
    expand(range_map, expected);
    MethodResult r = run_bilateral(
        f, {{"range_map", map}, {"diameter", "7"}, {"sigma_color", "0.2"}, {"sigma_space", "2.5"}});
    EXPECT_TRUE(r.image == expected) << map;
  }
}

// A high-contrast edge (10x in radiance) survives: the range kernel in the log domain stops
// averaging across it, so pixels two columns from the edge stay within 2% of their side.
TEST(Bilateral, KeepsAHighContrastEdge) {
  AovFrame f = test::constant_frame(32, 16);
  Image& c = f.layer(layer::kColor);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 32; ++x)
      for (int k = 0; k < 3; ++k) c.at(x, y, k) = x < 16 ? 0.2f : 2.0f;
  MethodResult r = run_bilateral(f, {{"sigma_space", "4"}, {"sigma_color", "0.1"}});
  EXPECT_NEAR(r.image.at(13, 8, 0), 0.2f, 0.004f);
  EXPECT_NEAR(r.image.at(18, 8, 0), 2.0f, 0.04f);
}

}  // namespace
}  // namespace dnb
