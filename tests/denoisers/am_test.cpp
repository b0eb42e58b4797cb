// The adaptive-manifold core (denoisers/am/adaptive_manifold.h) and the methods `am`, `am_opencv`.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include <opencv2/ximgproc/edge_filter.hpp>

#include "core/errors.h"
#include "denoisers/am/adaptive_manifold.h"
#include "denoisers/am_opencv.h"
#include "denoisers/hdr_mapping.h"
#include "denoisers/method.h"
#include "denoisers/synthetic_frame.h"
#include "thread_count.h"

namespace dnb {
namespace {

// Measured figures for the test report, in scientific notation.
std::string sci(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}


// A smooth 3-channel image with a step and noise, and an 8-channel guide built from it
// (the image itself, its square, and two smooth ramps), the benchmark's kind of input.
struct Input {
  Image src, guide;
};
Input make_input(int w, int h, std::uint64_t seed) {
  Input in{Image(w, h, 3), Image(w, h, 8)};
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float u = float(x) / w, v = float(y) / h;
      for (int c = 0; c < 3; ++c) {
        const float clean = (x < w / 2 ? 0.25f : 0.7f) + 0.1f * v + 0.05f * c;
        in.src.at(x, y, c) = clean + 0.05f * g(rng);
      }
      float* q = in.guide.pixel(x, y);
      for (int c = 0; c < 3; ++c) q[c] = in.src.at(x, y, c);
      for (int c = 0; c < 3; ++c) q[3 + c] = in.src.at(x, y, c) * in.src.at(x, y, c);
      q[6] = 0.3f * u;
      q[7] = 0.3f * v;
    }
  return in;
}

Image opencv_am(const Image& src, const Image& guide, const AmSettings& s) {
  auto amf = opencv_am_filter(s);
  std::vector<cv::Mat> planes;
  cv::split(as_mat(guide), planes);  // OpenCV takes more than 4 guide channels as a vector of planes
  cv::Mat out;
  amf->filter(as_mat(src), out, planes);
  return from_mat(out);
}

// Ours and OpenCV's agree closely on the same parameters. Measured (160x120, 8-channel guide;
// 128x96 planes frame for the methods): with sigma_s = 8 the reduced grid is 2x coarser, where
// OpenCV's bilinear 1/2 resize is exactly our 2x2 box average, and one manifold agrees to about
// 2e-7 relative RMS (float summation order); the full tree agrees to about 1e-3 (the split's
// random start vector differs: a guide hash here, cv::RNG seeded by the centre pixel there, so
// the clusters differ at the margin). With sigma_s = 16 the grid is 4x coarser and OpenCV's
// bilinear resize samples only the middle 2x2 of each 4x4 block (aliasing noise) while we
// average the block: about 1.5-2e-2. Bounds leave a factor 3-5 of room.
double compare(const Image& src, const Image& guide, double sigma_s, int tree_height) {
  AmSettings s;
  s.sigma_s = sigma_s;
  s.tree_height = tree_height;
  return relative_rms(am_filter(src.cview(), guide.cview(), s), opencv_am(src, guide, s));
}

TEST(AdaptiveManifold, AgreesWithOpenCv) {
  Input in = make_input(160, 120, 3);
  const double one = compare(in.src, in.guide, 8, 1);
  const double tree = compare(in.src, in.guide, 8, 0);
  const double coarse = compare(in.src, in.guide, 16, 0);
  RecordProperty("rel_rms_one_manifold", sci(one));
  RecordProperty("rel_rms_tree", sci(tree));
  RecordProperty("rel_rms_sigma_s_16", sci(coarse));
  EXPECT_LT(one, 1e-5);
  EXPECT_LT(tree, 5e-3);
  EXPECT_LT(coarse, 5e-2);
  // And both actually filtered: far from the noisy input.
  AmSettings s;
  EXPECT_GT(relative_rms(am_filter(in.src.cview(), in.guide.cview(), s), in.src), 2 * coarse);
}

TEST(AdaptiveManifold, MethodsAgreeOnAFrame) {
  AovFrame f = test::planes_frame(128, 96, 0.3f);
  for (const char* sigma_s : {"8", "16"}) {
    auto am = MethodRegistry::global().create("am", {{"sigma_s", sigma_s}});
    auto amcv = MethodRegistry::global().create("am_opencv", {{"sigma_s", sigma_s}});
    const double d = relative_rms(run_method(*am, {.frame = &f}).image, run_method(*amcv, {.frame = &f}).image);
    RecordProperty(std::string("rel_rms_color_sigma_s_") + sigma_s, sci(d));
    EXPECT_LT(d, sigma_s[0] == '8' ? 5e-3 : 5e-2) << "sigma_s " << sigma_s;
  }
}

// A slice query with the pixel's own guide value (and the image's outlier adjustment) gives the
// filtered pixel (the same sums in
// double instead of float: 1e-4 relative); another guide value gives another answer.
TEST(AdaptiveManifold, SliceQueryReproducesThePixel) {
  Input in = make_input(96, 64, 5);
  std::vector<AmQuery> q;
  for (auto [x, y] : {std::pair{3, 4}, std::pair{47, 30}, std::pair{48, 30}, std::pair{95, 63}})
    q.push_back({x, y, in.guide.pixel(x, y), nullptr});
  std::vector<float> other(8);
  for (int c = 0; c < 8; ++c) other[c] = in.guide.at(80, 10, c);  // a pixel of the other side
  // Asked at a dark pixel 4 px from the edge (where an edge sub-pixel is), not far inside the dark
  // half: 38 px away (> 2 sigma_s) the bright manifolds' weight there is a ratio of underflowing
  // sums, and the answer moved from 0.63 (-O3) to 0.37 (-O1) while within 18 px of the edge
  // both builds answer 0.72 +- 0.01.
  q.push_back({44, 10, other.data(), nullptr});
  std::vector<float> out;
  for (bool adjust : {false, true}) {
    AmSettings s;
    s.adjust_outliers = adjust;
    for (auto& query : q) query.adjust_outliers = adjust;  // a query's own switch: as the image's
    const Image img = am_filter(in.src.cview(), in.guide.cview(), s, q, &out);
    for (std::size_t k = 0; k + 1 < q.size(); ++k)
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(out[k * 3 + c], img.at(q[k].x, q[k].y, c), 1e-4f * img.at(q[k].x, q[k].y, c));
    // Pixel (44, 10) on the dark side asked with a bright-side guide: answered near the bright side.
    EXPECT_GT(out[4 * 3], img.at(44, 10, 0) + 0.2f);
  }
}

// A slice query outside the image is refused with the query and the image size named (both
// paths index buffers by the queries' pixels: on the CPU path it used to read out of range).
TEST(AdaptiveManifold, SliceQueryOutsideTheImageIsRefused) {
  Input in = make_input(32, 24, 5);
  for (auto [x, y] : {std::pair{32, 3}, std::pair{-1, 3}, std::pair{3, 24}, std::pair{3, -1}}) {
    const std::vector<AmQuery> q{{0, 0, in.guide.pixel(0, 0), nullptr}, {x, y, in.guide.pixel(0, 0), nullptr}};
    std::vector<float> out;
    try {
      am_filter(in.src.cview(), in.guide.cview(), AmSettings{}, q, &out);
      ADD_FAILURE() << "no error for a query at (" << x << ", " << y << ")";
    } catch (const WorkError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("slice query 1 at pixel (" + std::to_string(x) + ", " + std::to_string(y) + ")"), std::string::npos) << what;
      EXPECT_NE(what.find("32x24"), std::string::npos) << what;
    }
  }
}

// Eq. 11's strength (AmSettings::outlier_scale): 0 is no adjustment at all (alpha = 1), the
// default 1 is Gastal and Oliveira's, and a weaker adjustment leaves the output between the
// two: per pixel it only moves alpha within [alpha(1), 1].
TEST(AdaptiveManifold, OutlierScaleSpansNoAdjustmentToFull) {
  Input in = make_input(96, 64, 9);
  AmSettings s;
  s.sigma_r = 0.15;  // small, so that many pixels are outliers and the adjustment matters
  s.adjust_outliers = false;
  const Image none = am_filter(in.src.cview(), in.guide.cview(), s);
  s.adjust_outliers = true;
  const Image full = am_filter(in.src.cview(), in.guide.cview(), s);
  s.outlier_scale = 0.0;
  EXPECT_EQ(test::mse(none, am_filter(in.src.cview(), in.guide.cview(), s)), 0.0);
  s.outlier_scale = 0.25;
  const Image weak = am_filter(in.src.cview(), in.guide.cview(), s);
  ASSERT_GT(test::mse(none, full), 1e-8) << "the adjustment does nothing on this input";
  int outside = 0;
  for (std::size_t k = 0; k < weak.size(); ++k) {
    const float lo = std::min(none.data()[k], full.data()[k]), hi = std::max(none.data()[k], full.data()[k]);
    const float slack = 1e-5f * (1.0f + std::abs(hi));  // float rounding of f + alpha (g - f)
    outside += weak.data()[k] < lo - slack || weak.data()[k] > hi + slack;
  }
  EXPECT_EQ(outside, 0);
  EXPECT_GT(test::mse(weak, full), 0.0);
  EXPECT_GT(test::mse(weak, none), 0.0);
}

// Dividing a guide group by its sigma is what make_guide does: scaling the data and the sigma
// together changes nothing; a smaller sigma for a group makes its edges count more.
TEST(AdaptiveManifold, GuideGroupsScaleBySigma) {
  Input in = make_input(64, 48, 9);
  Image twice = in.guide;
  for (std::size_t k = 0; k < twice.size(); ++k) twice.data()[k] *= 2;
  const float sr = 0.2f;
  Image g1 = make_guide({{in.guide.cview(), 0.5f}}, sr);
  Image g2 = make_guide({{twice.cview(), 1.0f}}, sr);
  for (std::size_t k = 0; k < g1.size(); ++k) ASSERT_FLOAT_EQ(g1.data()[k], g2.data()[k]);
  EXPECT_FLOAT_EQ(g1.at(3, 3, 0), in.guide.at(3, 3, 0) * sr / 0.5f);
}

// The power iteration is real: with more steps the split direction, hence the output, changes,
// and it converges (20 and 40 steps agree far better than 1 and 20).
TEST(AdaptiveManifold, PowerIterationConverges) {
  Input in = make_input(96, 72, 11);
  AmSettings s;
  s.pca_iterations = 1;
  const Image a = am_filter(in.src.cview(), in.guide.cview(), s);
  s.pca_iterations = 20;
  const Image b = am_filter(in.src.cview(), in.guide.cview(), s);
  s.pca_iterations = 40;
  const Image c = am_filter(in.src.cview(), in.guide.cview(), s);
  EXPECT_GT(relative_rms(a, b), 0.0);
  EXPECT_LT(relative_rms(b, c), 0.1 * relative_rms(a, b) + 1e-7);
}

// Same input, same output, bit for bit, whatever the thread count: one thread against four
// (an explicit count, since the default is one thread on a one-core runner).
TEST(AdaptiveManifold, DeterministicAcrossThreadCounts) {
  Input in = make_input(131, 77, 13);
  AmSettings s;
  s.adjust_outliers = true;
  Image one, many;
  EXPECT_EQ(test::run_on_threads(1, [&] { one = am_filter(in.src.cview(), in.guide.cview(), s); }), 1);
  const int threads = test::run_on_threads(4, [&] { many = am_filter(in.src.cview(), in.guide.cview(), s); });
  ASSERT_GT(threads, 1) << "the many-thread run had one thread: the comparison would be 1 against 1";
  EXPECT_TRUE(one == many);
}

// Small sizes and a sigma_s larger than the image do not break the reduced grid.
TEST(AdaptiveManifold, TinyImages) {
  for (auto [w, h] : {std::pair{1, 1}, std::pair{3, 1}, std::pair{1, 9}, std::pair{5, 7}}) {
    Input in = make_input(w, h, 1);
    AmSettings s;
    s.sigma_s = 64;
    const Image out = am_filter(in.src.cview(), in.guide.cview(), s);
    for (std::size_t k = 0; k < out.size(); ++k) ASSERT_TRUE(std::isfinite(out.data()[k]));
  }
}

}  // namespace
}  // namespace dnb
