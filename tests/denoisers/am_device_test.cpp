// bench/device/am_device.cpp (the adaptive-manifold core alone, carried to a GPU machine by
// scripts/am_device_bundle) run here on PoCL on a recorded call: it must time both paths and
// find them equal within the OpenCL path's tolerance (opencl_test.cpp's 1e-4), and write its JSON.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <nlohmann/json.hpp>

#include "denoisers/am/adaptive_manifold.h"
#include "test_util.h"

namespace dnb {
namespace {

namespace fs = std::filesystem;

TEST(AmDevice, TimesARecordedCallOnBothPaths) {
#ifndef DNB_TEST_AM_DEVICE
  GTEST_SKIP() << "the driver is built only with OpenCL and the benchmarks";
#else
  test::TempDir dir;
  const int w = 96, h = 64;
  Image src(w, h, 3), guide(w, h, 4);
  std::mt19937 rng(11);
  std::normal_distribution<float> g(0.0f, 0.05f);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 4; ++c) {
        const float v = (x < w / 2 ? 0.2f : 0.7f) + 0.1f * c;
        if (c < 3) src.at(x, y, c) = v + g(rng);
        guide.at(x, y, c) = v + 0.5f * g(rng);
      }
  const fs::path cap = dir.path() / "cap";
  fs::create_directories(cap);
  ::setenv("DENOISEBENCH_AM_CAPTURE", cap.c_str(), 1);
  am_filter(src.cview(), guide.cview(), AmSettings{});
  ::unsetenv("DENOISEBENCH_AM_CAPTURE");
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(cap)) files.push_back(e.path());
  ASSERT_EQ(files.size(), 1u);
  const fs::path json = dir.path() / "out.json";
  const auto r = test::run_command(std::string(DNB_TEST_AM_DEVICE) + " --repeat 2 --perturb 1e-6 --json '" + json.string() + "' '" +
                                   files[0].string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("OpenCL device: "), std::string::npos) << r.output;
  std::ifstream in(json);
  const auto j = nlohmann::json::parse(in);
  ASSERT_EQ(j.at("captures").size(), 1u);
  const auto& c = j.at("captures")[0];
  EXPECT_EQ(c.at("width"), w);
  EXPECT_EQ(c.at("guide_channels"), 4);
  EXPECT_GT(c.at("opencl_median_ms").get<double>(), 0.0);
  EXPECT_GT(c.at("cpu_median_ms").get<double>(), 0.0);
  EXPECT_LE(c.at("relative_rms_image").get<double>(), 1e-4);
  // The CPU path on a perturbed guide moved, but by no more than the perturbation's order on this
  // smooth, well-separated input (the bench frame's noise-only layers move far more).
  EXPECT_GT(c.at("relative_rms_perturbed").get<double>(), 0.0);
  EXPECT_LT(c.at("relative_rms_perturbed").get<double>(), 1e-3);
  // An unreadable input: a non-zero exit naming it.
  const auto bad = test::run_command(std::string(DNB_TEST_AM_DEVICE) + " '" + (dir.path() / "missing.bin").string() + "'");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("missing.bin"), std::string::npos) << bad.output;
#endif
}

}  // namespace
}  // namespace dnb
