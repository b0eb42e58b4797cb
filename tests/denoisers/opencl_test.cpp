// The OpenCL path of the adaptive-manifold core (denoisers/am/opencl.h) against the
// CPU path, on PoCL here (POCL_CACHE_DIR inside the build tree, set by tests/CMakeLists.txt).
// Tolerance: relative RMS difference <= 1e-4. The two paths do the same operations
// in float; only summation order differs (per block here, per column then block on the CPU),
// plus the odd pixel whose split dot product sits at 0 and changes cluster. Measured on PoCL:
// about 8e-8 for the core (150x101, 7-channel guide), 1e-7 for the whole method and for the
// grouped tree of GroupsBlockSumsAndQueryRunsMatchCpuPath.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>

#include "denoisers/am/adaptive_manifold.h"
#include "denoisers/am/opencl.h"
#include "denoisers/method.h"
#include "opencl_test_util.h"

namespace dnb {
namespace {

// Measured figures for the test report, in scientific notation.
std::string sci(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}


// A w x h test input: a 3-channel source, `level`(x, y, c) plus Gaussian noise of 0.05, and a
// guide of `dims` channels, `wave`(x, y, c) plus Gaussian noise of 0.02.
struct AmCase {
  Image src, guide;
};
template <class Level, class Wave>
AmCase noisy_case(int w, int h, int dims, unsigned seed, Level level, Wave wave) {
  AmCase r{Image(w, h, 3), Image(w, h, dims)};
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) r.src.at(x, y, c) = level(x, y, c) + 0.05f * g(rng);
      for (int c = 0; c < dims; ++c) r.guide.at(x, y, c) = wave(x, y, c) + 0.02f * g(rng);
    }
  return r;
}


TEST(OpenCl, MatchesCpuPath) {
  if (!test::have_opencl()) GTEST_SKIP() << "no OpenCL in this build";
  const int w = 150, h = 101;  // not multiples of the reduced grid
  auto [src, guide] = noisy_case(
      w, h, 7, 4, [&](int x, int, int c) { return (x < w / 3 ? 0.3f : 0.8f) + 0.05f * c; },
      [](int x, int y, int c) { return 0.2f * std::sin(0.05f * x * (c + 1) + 0.03f * y); });
  // An outlier far from every manifold: its weights underflow to (near) 0 on both paths, which
  // must then agree that it keeps its own value, whatever the denormal mode (kAmMinWeight).
  for (int c = 0; c < 7; ++c) guide.at(5, 5, c) = 3.0f;
  std::vector<float> qv(7, 0.1f);
  std::vector<AmQuery> queries{{10, 10, qv.data(), nullptr}, {w - 1, h - 1, guide.pixel(w - 1, h - 1), nullptr}};
  // The recursive filters' two forms: 8 rows or columns per work-item (a CPU device's, PoCL's
  // default) and one column per work-item with the rows through transposes (a GPU's: rf_cols1,
  // transpose_planes), which CI can run only by asking for it.
  for (const char* lanes : {"8", "1"})
  for (bool adjust : {false, true})
    for (double sigma_s : {8.0, 16.0}) {
      ::setenv("DENOISEBENCH_OPENCL_LANES", lanes, 1);
      AmSettings s;
      s.sigma_s = sigma_s;
      s.adjust_outliers = adjust;
      s.outlier_scale = sigma_s == 16.0 ? 0.25 : 1.0;  // proposed's weaker eq. 11 at low spp
      s.pca_iterations = 3;
      std::vector<float> qc, qg;
      const Image cpu = am_filter(src.cview(), guide.cview(), s, queries, &qc);
      const Image gpu = am_filter_opencl(src.cview(), guide.cview(), s, queries, &qg);
      ::unsetenv("DENOISEBENCH_OPENCL_LANES");
      const double d = relative_rms(gpu.data(), cpu.data(), cpu.size());
      RecordProperty("rel_rms_sigma_s_" + std::to_string(int(sigma_s)) + (adjust ? "_adjust" : "") + "_lanes" + lanes, sci(d));
      EXPECT_LE(d, 1e-4) << "sigma_s " << sigma_s << " adjust " << adjust << " lanes " << lanes;
      ASSERT_EQ(qc.size(), qg.size());
      EXPECT_LE(relative_rms(qg.data(), qc.data(), qc.size()), 1e-4);
    }
}

// The OpenCL path runs a tree level's manifolds in groups of up to 4 and sums a reduced block in
// the work-item where df divides 8, through column sums otherwise; queries at one pixel share
// its upsampled values. A tree of height 5 (16 leaves: levels of 8 and 16 manifolds in 2 and 4
// groups), reduction factors on both routes (2, 8: in the work-item; 3, 16: column sums; 3 and
// 16 leave partial blocks at the 150 x 101 image's edges), and queries in runs at one pixel, a
// pixel visited twice, against the CPU path at the same 1e-4.
TEST(OpenCl, GroupsBlockSumsAndQueryRunsMatchCpuPath) {
  if (!test::have_opencl()) GTEST_SKIP() << "no OpenCL in this build";
  const int w = 150, h = 101;
  const auto [src, guide] = noisy_case(
      w, h, 5, 11, [&](int, int y, int c) { return (y < h / 2 ? 0.4f : 0.9f) + 0.05f * c; },
      [](int x, int y, int c) { return 0.3f * std::cos(0.04f * x * (c + 1) - 0.05f * y); });
  std::vector<std::vector<float>> qv;
  for (int k = 0; k < 7; ++k) qv.push_back(std::vector<float>(5, 0.05f * k - 0.1f));
  std::vector<AmQuery> queries;
  for (int k = 0; k < 3; ++k) queries.push_back({40, 30, qv[k].data(), nullptr});
  queries.push_back({w - 1, h - 1, qv[3].data(), nullptr});
  for (int k = 4; k < 7; ++k) queries.push_back({40, 30, qv[k].data(), nullptr});
  for (int df : {2, 3, 8, 16}) {
    AmSettings s;
    s.sigma_s = 12.0;
    s.tree_height = 5;
    s.downsample = df;
    s.pca_iterations = 3;
    std::vector<float> qc, qg;
    const Image cpu = am_filter(src.cview(), guide.cview(), s, queries, &qc);
    const Image gpu = am_filter_opencl(src.cview(), guide.cview(), s, queries, &qg);
    const double d = relative_rms(gpu.data(), cpu.data(), cpu.size());
    RecordProperty("rel_rms_height5_df" + std::to_string(df), sci(d));
    EXPECT_LE(d, 1e-4) << "df " << df;
    ASSERT_EQ(qc.size(), qg.size());
    EXPECT_LE(relative_rms(qg.data(), qc.data(), qc.size()), 1e-4) << "df " << df;
    // Queries at one pixel with different guides get answers of their own, not their run's.
    EXPECT_GT(relative_rms(qg.data(), qg.data() + 4 * 3, 3), 0.0) << "queries with different guides must differ";
  }
}

// Views whose rows are wider than their pixels (a crop, as proposed's reflection boxes pass): the
// OpenCL path uploads such rows through a copy and contiguous ones straight from the caller's
// memory, then makes planes on the device; both must read the same pixels as the CPU path.
TEST(OpenCl, CroppedViewsMatchCpuPath) {
  if (!test::have_opencl()) GTEST_SKIP() << "no OpenCL in this build";
  const int w = 120, h = 90;
  const auto [src, guide] = noisy_case(
      w, h, 6, 17, [&](int x, int y, int c) { return (x + y < w ? 0.3f : 0.75f) + 0.04f * c; },
      [](int x, int y, int c) { return 0.25f * std::sin(0.06f * x + 0.02f * y * (c + 1)); });
  const int x0 = 13, y0 = 7, cw = 77, ch = 61;
  const ConstImageView s_view = src.cview().crop(x0, y0, cw, ch), g_view = guide.cview().crop(x0, y0, cw, ch);
  const Image s_copy = to_image(s_view), g_copy = to_image(g_view);
  AmSettings s;
  s.sigma_s = 10.0;
  const Image cpu = am_filter(s_copy.cview(), g_copy.cview(), s);
  const Image from_crop = am_filter_opencl(s_view, g_view, s);
  const Image from_copy = am_filter_opencl(s_copy.cview(), g_copy.cview(), s);
  ASSERT_EQ(from_crop.size(), cpu.size());
  EXPECT_LE(relative_rms(from_crop.data(), cpu.data(), cpu.size()), 1e-4);
  EXPECT_LE(relative_rms(from_copy.data(), cpu.data(), cpu.size()), 1e-4);
  EXPECT_EQ(relative_rms(from_crop.data(), from_copy.data(), cpu.size()), 0.0) << "the same pixels, the same kernels";
}

// The whole method with device=opencl matches device=cpu (edge queries and a reflection level
// included, through the synthetic frames of the proposed tests' kind).
TEST(OpenCl, ProposedMatchesCpu) {
  if (!test::have_opencl()) GTEST_SKIP() << "no OpenCL in this build";
  AovFrame f(80, 60);
  for (int k = 0; k <= 1; ++k)
    for (const char* base : {layer::kDirect, layer::kIndirect, layer::kAlbedo, layer::kReflection, layer::kEmission, layer::kNormal})
      f.add(layer::at_level(k, base), 3);
  f.add(layer::kDepth, 1), f.add(layer::at_level(1, layer::kDepth), 1), f.add(layer::at_level(1, layer::kTint), 3);
  std::mt19937_64 rng(8);
  std::normal_distribution<float> g(0.0f, 1.0f);
  EdgeSubpixels edges;
  for (int y = 0; y < 60; ++y)
    for (int x = 0; x < 80; ++x) {
      const bool left = x < 40;
      for (int c = 0; c < 3; ++c) {
        f.layer(layer::kDirect).at(x, y, c) = std::max(0.0f, (left ? 1.0f : 0.3f) * (1 + 0.3f * g(rng)));
        f.layer(layer::kIndirect).at(x, y, c) = std::max(0.0f, 0.2f * (1 + 0.3f * g(rng)));
        f.layer(layer::kAlbedo).at(x, y, c) = ((x / 4 + y / 4) % 2) ? 0.8f : 0.3f;
        f.layer(layer::at_level(1, layer::kDirect)).at(x, y, c) = std::max(0.0f, 0.5f * (1 + 0.3f * g(rng)));
        f.layer(layer::at_level(1, layer::kAlbedo)).at(x, y, c) = 0.5f;
        f.layer(layer::at_level(1, layer::kTint)).at(x, y, c) = y > 30 ? 0.5f : 0.0f;
      }
      f.layer(layer::kNormal).at(x, y, left ? 2 : 0) = 1;
      f.layer(layer::at_level(1, layer::kNormal)).at(x, y, 1) = 1;
      f.layer(layer::kDepth).at(x, y, 0) = left ? 2.0f : 3.0f;
      f.layer(layer::at_level(1, layer::kDepth)).at(x, y, 0) = 4.0f;
      if (x == 40) {
        edges.pixels.push_back(y * 80 + x);
        for (int s = 0; s < 16; ++s) {
          EdgeSample e;
          const bool l = s % 4 < 2;
          e.normal[l ? 2 : 0] = 1, e.depth = l ? 2.0f : 3.0f;
          for (int c = 0; c < 3; ++c) e.albedo[c] = 0.5f, e.direct[c] = l ? 1.0f : 0.3f, e.indirect[c] = 0.2f;
          edges.samples.push_back(e);
        }
      }
    }
  f.edges = edges;
  // Without the NLM space (an ablation) only the adaptive-manifold core runs on the device, a call
  // per layer: the core's tolerance. (The whole filter on the device: proposed_opencl_test.cpp.)
  auto cpu = MethodRegistry::global().create("proposed", {{"nlm_space", "false"}});
  auto gpu = MethodRegistry::global().create("proposed", {{"nlm_space", "false"}, {"device", "opencl"}});
  const Image a = run_method(*cpu, {.frame = &f}).image;
  const MethodResult b = run_method(*gpu, {.frame = &f});
  EXPECT_EQ(b.stats.counters.at("device_pipeline"), 0);
  const double d = relative_rms(b.image.data(), a.data(), a.size());
  RecordProperty("rel_rms_proposed", sci(d));
  EXPECT_LE(d, 1e-4);
}

}  // namespace
}  // namespace dnb
