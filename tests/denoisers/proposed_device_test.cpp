// bench/device/proposed_device.cpp (proposed's whole filter on the device, carried to a GPU machine
// by scripts/am_device_bundle) run here on PoCL on a frame recorded by a CPU run of proposed
// (DENOISEBENCH_PROPOSED_CAPTURE): it must time the filter, find it within 2x its own one-ulp
// sensitivity of the recorded CPU output (proposed_opencl_test.cpp's rule), write its JSON, and
// refuse a missing or truncated capture naming the file.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "denoisers/method.h"
#include "denoisers/proposed_capture.h"
#include "test_util.h"
#include "tracer/render.h"
#include "tracer/scene_loader.h"

namespace dnb {
namespace {

namespace fs = std::filesystem;

TEST(ProposedDevice, TimesARecordedFrameAndAgreesWithTheRecordedCpuOutput) {
#ifndef DNB_TEST_PROPOSED_DEVICE
  GTEST_SKIP() << "the driver is built only with OpenCL and the benchmarks";
#else
  test::TempDir dir;
  RenderSettings s;
  s.width = 64;
  s.height = 48;
  s.spp = 16;
  s.reflection_levels = 2;
  const AovFrame f = render_frame(*load_scene("conference"), s);
  const fs::path cap = dir.path() / "proposed.bin";
  ::setenv("DENOISEBENCH_PROPOSED_CAPTURE", cap.c_str(), 1);
  auto m = MethodRegistry::global().create("proposed");
  const Image cpu = run_method(*m, {.frame = &f}).image;
  ::unsetenv("DENOISEBENCH_PROPOSED_CAPTURE");
  ASSERT_TRUE(fs::exists(cap));
  // The capture holds what was run: the frame's layers, its edges and the output, bit for bit.
  const ProposedCapture c = read_proposed_capture(cap.string());
  EXPECT_EQ(c.plan.levels, 2);
  ASSERT_TRUE(c.frame.edges.has_value());
  EXPECT_EQ(*c.frame.edges, *f.edges);
  for (const char* l : {layer::kDirect, layer::kVariance, "refl2.tint"}) {
    ASSERT_TRUE(c.frame.has(l)) << l;
    EXPECT_TRUE(std::equal(f.layer(l).data(), f.layer(l).data() + f.layer(l).size(), c.frame.layer(l).data())) << l;
  }
  EXPECT_TRUE(std::equal(cpu.data(), cpu.data() + cpu.size(), c.cpu_output.data()));

  const fs::path json = dir.path() / "out.json";
  const auto r = test::run_command(std::string(DNB_TEST_PROPOSED_DEVICE) + " --repeat 2 --json '" + json.string() + "' '" +
                                   cap.string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("OpenCL device: "), std::string::npos) << r.output;
  std::ifstream in(json);
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j.at("width"), 64);
  EXPECT_EQ(j.at("reflection_levels"), 2);
  EXPECT_EQ(j.at("edge_pixels").get<std::size_t>(), f.edges->size());
  EXPECT_GT(j.at("median_ms").get<double>(), 0.0);
  const double own = j.at("relative_rms_perturbed").get<double>();
  EXPECT_GT(own, 0.0);
  EXPECT_LE(j.at("relative_rms_vs_cpu").get<double>(), std::max(2.0 * own, 1e-4)) << r.output;

  // A missing and a truncated capture: a non-zero exit naming the file.
  const auto missing = test::run_command(std::string(DNB_TEST_PROPOSED_DEVICE) + " '" + (dir.path() / "missing.bin").string() + "'");
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find("missing.bin"), std::string::npos) << missing.output;
  const fs::path cut = dir.path() / "cut.bin";
  fs::copy_file(cap, cut);
  fs::resize_file(cut, fs::file_size(cap) / 2);
  const auto truncated = test::run_command(std::string(DNB_TEST_PROPOSED_DEVICE) + " '" + cut.string() + "'");
  EXPECT_NE(truncated.exit_code, 0);
  EXPECT_NE(truncated.output.find("cut.bin"), std::string::npos) << truncated.output;
  EXPECT_NE(truncated.output.find("truncated"), std::string::npos) << truncated.output;
#endif
}

}  // namespace
}  // namespace dnb
