// `denoisebench denoise` and `denoisebench list methods` from the outside (issue 5): exit codes,
// the messages users see, and that a refused run leaves no output file behind.
#include <gtest/gtest.h>
#include <gmock/gmock.h>

#include <filesystem>

#include <nlohmann/json.hpp>

#include "core/exr_io.h"
#include "test_util.h"

namespace dnb {
namespace {
using ::testing::HasSubstr;
namespace fs = std::filesystem;

// A small frame with a smooth colour and the layers the illumination filters read.
void write_small_frame(const std::string& path, bool with_color = true) {
  AovFrame f(24, 16);
  for (const char* name : {"direct", "indirect", "albedo", "reflection", "emission", "normal"}) {
    Image& img = f.add(name, 3);
    for (std::size_t k = 0; k < img.size(); ++k) img.data()[k] = 0.25f + 0.001f * float(k % 97);
  }
  Image& depth = f.add("depth", 1);
  for (std::size_t k = 0; k < depth.size(); ++k) depth.data()[k] = 2.0f;
  if (with_color) {
    Image& c = f.add("color", 3);
    for (std::size_t k = 0; k < c.size(); ++k) c.data()[k] = 0.5f + 0.002f * float(k % 89);
  }
  f.meta.scene = "unit";
  write_frame(f, path);
}

TEST(DenoiseCommand, RunsAMethodAndWritesRgb) {
  test::TempDir dir;
  write_small_frame(dir.file("f.exr"));
  auto r = test::run_denoisebench("denoise bilateral " + dir.file("f.exr") + " -o " + dir.file("out.exr") +
                                  " --set sigma_space=2 --set range_map=reinhard");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("sigma_space"));
  EXPECT_THAT(r.output, HasSubstr("repaired_samples"));
  Image out = read_rgb(dir.file("out.exr"));
  EXPECT_EQ(out.width(), 24);
  EXPECT_EQ(out.height(), 16);
}

TEST(DenoiseCommand, JsonStatistics) {
  test::TempDir dir;
  write_small_frame(dir.file("f.exr"));
  auto r = test::run_denoisebench("denoise bilateral " + dir.file("f.exr") + " -o " + dir.file("out.exr") +
                                  " --json --set range_map=log");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto j = nlohmann::json::parse(r.output.substr(r.output.find('{')));
  EXPECT_EQ(j["method"], "bilateral");
  EXPECT_EQ(j["params"]["range_map"], "log");
  EXPECT_GE(j["total_seconds"].get<double>(), 0.0);
  EXPECT_EQ(j["counters"]["repaired_samples"].get<double>(), 0.0);
}

TEST(DenoiseCommand, RefusalsExitTwoNameWhatIsWrongAndWriteNothing) {
  test::TempDir dir;
  write_small_frame(dir.file("f.exr"));
  write_small_frame(dir.file("nocolor.exr"), false);
  const std::string out = dir.file("out.exr");
  struct Case {
    std::string args, message;
  } cases[] = {
      {"denoise bilatral " + dir.file("f.exr") + " -o " + out, "unknown method 'bilatral' (valid methods: "},
      {"denoise bilateral " + dir.file("f.exr") + " -o " + out + " --set sigma=3",
       "has no parameter 'sigma' (valid parameters: sigma_space, sigma_color, diameter, range_map)"},
      {"denoise bilateral " + dir.file("f.exr") + " -o " + out + " --set sigma_space=-1",
       "parameter 'sigma_space' = '-1': expected a finite number in [0.1, 100]"},
      {"denoise bilateral " + dir.file("f.exr") + " -o " + out + " --set range_map=cube", "one of linear, log"},
      {"denoise bilateral " + dir.file("f.exr") + " -o " + out + " --set sigma_space",
       "--set 'sigma_space': expected key=value"},
      {"denoise bilateral " + dir.file("nocolor.exr") + " -o " + out, "nocolor.exr"},
      {"denoise bilateral " + dir.file("absent.exr") + " -o " + out, "absent.exr"},
  };
  for (const auto& c : cases) {
    auto r = test::run_denoisebench(c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.output;
    EXPECT_THAT(r.output, HasSubstr(c.message)) << c.args;
    EXPECT_FALSE(fs::exists(out)) << c.args;
  }
}

TEST(ListCommand, MethodsShowEveryParameterWithTypeDefaultAndDoc) {
  auto r = test::run_denoisebench("list methods");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("bilateral  (filter)"));
  EXPECT_THAT(r.output, HasSubstr("layers: color"));
  EXPECT_THAT(r.output, HasSubstr("sigma_space        float   default "));
  EXPECT_THAT(r.output, HasSubstr("a finite number in [0.1, 100]"));
  EXPECT_THAT(r.output, HasSubstr("spatial Gaussian sigma in pixels"));
  EXPECT_EQ(test::run_denoisebench("list nothing").exit_code, 2);
}

TEST(ListCommand, ScenesListsTheBuiltInScenes) {
  auto r = test::run_denoisebench("list scenes");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("cornell-box"));
}

TEST(ListCommand, MetricsListsEveryMetricWithItsDirection) {
  auto r = test::run_denoisebench("list metrics");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* m : {"mse ", "mse_hdr", "relmse", "psnr", "ssim", "flip"}) EXPECT_THAT(r.output, HasSubstr(m));
  EXPECT_THAT(r.output, HasSubstr("higher is better"));  // psnr, ssim
  EXPECT_THAT(r.output, HasSubstr("lower is better"));
}

}  // namespace
}  // namespace dnb
