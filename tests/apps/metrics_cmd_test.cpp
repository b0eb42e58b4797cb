// `denoisebench metrics` from the outside: every metric, --json, and the refusals (exit 2 with
// a message naming the file and the channel or the sizes).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "core/exr_io.h"
#include "test_util.h"

namespace dnb {
namespace {
using ::testing::HasSubstr;

TEST(MetricsCommand, PrintsEveryMetricAsJson) {
  test::TempDir dir;
  write_rgb(Image(8, 6, 3, 0.0f), dir.file("a.exr"));
  write_rgb(Image(8, 6, 3, 1.0f), dir.file("b.exr"));
  auto r = test::run_denoisebench_stdout("metrics --json " + dir.file("a.exr") + " " + dir.file("b.exr"));
  ASSERT_EQ(r.exit_code, 0) << r.output << r.errors;
  auto j = nlohmann::json::parse(r.output);
  for (const char* m : {"mse", "mse_hdr", "relmse", "psnr", "ssim", "flip"}) EXPECT_TRUE(j.contains(m)) << m;
  EXPECT_DOUBLE_EQ(j["mse"].get<double>(), 255.0 * 255.0);  // black against white, 8-bit
  EXPECT_DOUBLE_EQ(j["mse_hdr"].get<double>(), 1.0);
  // Identical images: psnr is infinite, written as null.
  auto same = test::run_denoisebench_stdout("metrics --json " + dir.file("a.exr") + " " + dir.file("a.exr"));
  ASSERT_EQ(same.exit_code, 0) << same.output << same.errors;
  EXPECT_TRUE(nlohmann::json::parse(same.output)["psnr"].is_null());
  // b.exr has no variance channels: mse_converged cannot be scored and says so.
  EXPECT_TRUE(j["mse_converged"].is_null());
  auto plain = test::run_denoisebench_stdout("metrics " + dir.file("a.exr") + " " + dir.file("b.exr"));
  EXPECT_THAT(plain.output, ::testing::ContainsRegex("mse_converged +n/a .*b\\.exr.*variance"));
}

TEST(MetricsCommand, ScoresMseConvergedFromTheReferencesVariance) {
  // A reference as `denoisebench reference` writes it: R,G,B plus variance.R/G/B. Pixel (0, 0)
  // is a firefly (sd 0.9 on a mean of 1: unconverged), every other pixel has no noise.
  test::TempDir dir;
  AovFrame ref(8, 6);
  Image color(8, 6, 3, 0.25f), var(8, 6, 3, 0.0f);
  for (int c = 0; c < 3; ++c) { color.at(0, 0, c) = 1.0f; var.at(0, 0, c) = 0.81f; }
  ref.set(layer::kColor, color);
  ref.set(layer::kVariance, var);
  write_frame(ref, dir.file("ref.exr"));
  write_rgb(Image(8, 6, 3, 0.25f), dir.file("flat.exr"));  // right everywhere but on the firefly
  auto r = test::run_denoisebench_stdout("metrics --json " + dir.file("flat.exr") + " " + dir.file("ref.exr"));
  ASSERT_EQ(r.exit_code, 0) << r.output << r.errors;
  auto j = nlohmann::json::parse(r.output);
  EXPECT_GT(j["mse"].get<double>(), 0.0);
  EXPECT_EQ(j["mse_converged"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(j["reference_unconverged_share"].get<double>(), 1.0 / 48);
  // A negative variance is refused, naming the file and the pixel.
  var.at(3, 2, 1) = -0.5f;
  ref.set(layer::kVariance, var);
  write_frame(ref, dir.file("bad.exr"));
  auto bad = test::run_denoisebench("metrics " + dir.file("flat.exr") + " " + dir.file("bad.exr"));
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_THAT(bad.output, HasSubstr("bad.exr"));
  EXPECT_THAT(bad.output, HasSubstr("(3, 2)"));
}

TEST(MetricsCommand, RefusesUnequalSizesNamingTheFiles) {
  test::TempDir dir;
  write_rgb(Image(8, 6, 3, 0.5f), dir.file("a.exr"));
  write_rgb(Image(8, 5, 3, 0.5f), dir.file("small.exr"));
  auto r = test::run_denoisebench("metrics " + dir.file("a.exr") + " " + dir.file("small.exr"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("small.exr"));
  EXPECT_THAT(r.output, HasSubstr("8x5"));
}

TEST(MetricsCommand, RefusesAMissingChannelNamingFileAndChannel) {
  test::TempDir dir;
  write_rgb(Image(8, 6, 3, 0.5f), dir.file("a.exr"));
  AovFrame f(8, 6);
  f.add("depth", 1);
  write_frame(f, dir.file("depth_only.exr"));
  auto r = test::run_denoisebench("metrics " + dir.file("depth_only.exr") + " " + dir.file("a.exr"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("depth_only.exr"));
  EXPECT_THAT(r.output, ::testing::ContainsRegex("\\bR\\b"));
}

}  // namespace
}  // namespace dnb
