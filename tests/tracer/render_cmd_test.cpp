// `denoisebench render`: a frame with every channel and its edge file, and exit status 2 with a
// message naming the problem for bad input.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include "core/env.h"
#include "core/exr_io.h"
#include "test_util.h"
#include "tracer/render.h"

namespace dnb {
namespace {

// The program run_denoisebench runs: $DENOISEBENCH_BINARY, else ./denoisebench (tests run in build/).
// CMake builds it before tracer_tests (tests/CMakeLists.txt), so a missing one is a failure of
// the build or of the environment, never a reason to skip.
std::string binary() {
  const char* b = env::get("BINARY");
  return b ? b : "./denoisebench";
}
#define ASSERT_BINARY_BUILT() \
  ASSERT_TRUE(std::filesystem::exists(binary())) << binary() << " is missing: CMake builds it before tracer_tests"

TEST(RenderCommand, WritesAFrameWithEveryLayerAndItsEdgeFile) {
  ASSERT_BINARY_BUILT();
  test::TempDir dir;
  const std::string out = dir.file("f.exr");
  auto r = test::run_denoisebench("render cornell-box --spp 4 --size 48x36 --seed 3 --threads 2 -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  AovFrame f = read_frame(out, {layer::kColor, layer::kDirect, layer::kIndirect, layer::kAlbedo,
                                layer::kReflection, layer::kEmission, layer::kNormal, layer::kDepth,
                                layer::kVariance, layer::kDirectVariance, layer::kIndirectVariance,
                                layer::kEdge, layer::kSamples, "refl1.direct", "refl1.tint", "refl2.albedo"});
  EXPECT_EQ(f.width(), 48);
  EXPECT_EQ(f.meta.spp, 4);
  EXPECT_EQ(f.meta.seed, 3u);
  EXPECT_EQ(f.meta.tracer_version, kTracerVersion);
  ASSERT_TRUE(f.edges.has_value());
  EXPECT_GT(f.edges->size(), 0u);
  EXPECT_TRUE(std::filesystem::exists(edges_path(out)));
}

TEST(RenderCommand, BadInputExitsWithTwoAndSaysWhy) {
  ASSERT_BINARY_BUILT();
  test::TempDir dir;
  auto r = test::run_denoisebench("render no-such-scene -o " + dir.file("f.exr"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("no-such-scene"), std::string::npos) << r.output;
  r = test::run_denoisebench("render cornell-box --size 12by8 -o " + dir.file("f.exr"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("12by8"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir.file("f.exr")));
  // One size parser for render and reference (apps/args.h): a side that overflows an int is
  // named as given, not wrapped to another number (it was reported as "1215752191x48").
  for (const char* cmd : {"render", "reference"}) {
    r = test::run_denoisebench(std::string(cmd) + " cornell-box --size 99999999999x48 -o " + dir.file("f.exr"));
    EXPECT_EQ(r.exit_code, 2) << cmd;
    EXPECT_NE(r.output.find("'99999999999x48'"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("1215752191"), std::string::npos) << r.output;
    r = test::run_denoisebench(std::string(cmd) + " cornell-box --size 70000x70000 -o " + dir.file("f.exr"));
    EXPECT_EQ(r.exit_code, 2) << cmd;
    EXPECT_NE(r.output.find("1..32768"), std::string::npos) << r.output;
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("f.exr")));
}

}  // namespace
}  // namespace dnb
