// `denoisebench run` on a scene the Blender Cycles back-end renders (renderers/cycles,
// docs/renderers.md "Blender Cycles"): the built-in Cornell box (`scene = "cornell-box"`, which
// the run exports as glTF into its render cache), tiny,
// inputs of three seeds as two halves, the reference, the curve and every method (nfor, svgf and
// kpcn on the halves), then a second run that renders nothing. Skipped (saying why) without
// Blender: DNB_SETUP_BLENDER=1 scripts/setup installs it (CI has none: tests/allowed_skips.txt).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <set>

#include <nlohmann/json.hpp>

#include "core/exr_io.h"
#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;
using test::run_in;
using test::slurp;
using test::write;

const char* kCyclesConfig = R"(name = "cycles"
width = 32
height = 24
seeds = [1, 2, 3]
spp = [4]
max_depth = 6
methods = ["am", "atrous", "bilateral", "guided", "nlmeans", "proposed", "svgf", "nfor", "kpcn", "unet", "oidn", "irradiance_cache"]
[reference]
spp = 16
block_spp = 8
[speedup]
spp = [2, 4]
[timing]
repeats = 1
[[scene]]
renderer = "cycles"
scene = "cornell-box"
label = "box"
)";


std::size_t entries(const fs::path& cache) {
  std::size_t n = 0;
  if (fs::exists(cache))
    for (const auto& kind : fs::directory_iterator(cache))
      if (kind.is_directory())
        for (const auto& e : fs::directory_iterator(kind.path())) n += e.is_directory() && e.path().filename().string()[0] != '.';
  return n;
}

TEST(RunCycles, RendersInputsReferenceCurveAndEveryMethodThenReusesTheCache) {
  if (const std::string why = test::blender_missing(); !why.empty()) GTEST_SKIP() << why;
  test::TempDir dir;
  write(dir.path() / "c.toml", kCyclesConfig);
  auto r = run_in(dir, "run " + dir.file("c.toml") + " -o " + dir.file("first"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto first = nlohmann::json::parse(slurp(dir.file("first/results.json")));
  EXPECT_TRUE(first["failures"].empty()) << first["failures"].dump(1);
  ASSERT_EQ(first["skipped"].size(), 3u);  // irradiance_cache renders with the tracer
  EXPECT_THAT(first["skipped"][0]["reason"].get<std::string>(), HasSubstr("rendered by renderer 'cycles'"));
  EXPECT_EQ(first["config"]["scene_renderers"]["box"]["renderer"], "cycles");
  // The export is in the render cache, at the run's size.
  std::size_t exported = 0;
  for (const auto& e : fs::directory_iterator(dir.path() / "cache" / "scenes"))
    exported += e.path().extension() == ".gltf" && e.path().filename().string().find("-32x24.gltf") != std::string::npos;
  EXPECT_EQ(exported, 1u);
  std::set<std::pair<std::string, std::uint64_t>> cells;
  std::set<int> curve;
  for (const auto& rec : first["records"]) {
    EXPECT_EQ(rec["reference"]["spp"], 16);
    EXPECT_FALSE(rec["input_cache_hit"].get<bool>()) << rec["method"];
    ASSERT_TRUE(rec["metrics"]["mse"].is_number()) << rec.dump();
    if (rec["role"] == "plain") {
      curve.insert(rec["spp"].get<int>());
      continue;
    }
    cells.emplace(rec["method"].get<std::string>(), rec["seed"].get<std::uint64_t>());
  }
  EXPECT_EQ(curve, (std::set<int>{2, 4}));
  for (const char* m : {"input", "am", "atrous", "bilateral", "guided", "nlmeans", "proposed", "svgf", "nfor", "kpcn", "unet", "oidn"})
    for (std::uint64_t seed : {1, 2, 3}) EXPECT_TRUE(cells.count({m, seed})) << m << " seed " << seed;
  // An input is two Cycles renders (half buffers) with the variances they give.
  const ExrChannels frame = read_exr_channels(dir.file("first/frames/box/input_4_s2.exr"), false);
  for (const char* c : {"half0.color.R", "half1.color.R", "half0.albedo.R", "variance.R", "direct_variance.R", "direct.R",
                        "indirect.R", "reflection.R", "emission.R", "normal.X", "depth.Z"})
    EXPECT_TRUE(frame.has(c)) << c;

  // A second run into another folder reads every render from the cache.
  const std::size_t cached = entries(dir.path() / "cache");
  r = run_in(dir, "run " + dir.file("c.toml") + " -o " + dir.file("second"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(entries(dir.path() / "cache"), cached);
  const auto second = nlohmann::json::parse(slurp(dir.file("second/results.json")));
  ASSERT_EQ(second["records"].size(), first["records"].size());
  for (const auto& rec : second["records"]) {
    EXPECT_TRUE(rec["input_cache_hit"].get<bool>()) << rec["method"] << " " << rec["spp"];
    EXPECT_TRUE(rec["reference"]["cache_hit"].get<bool>());
  }
}

}  // namespace
}  // namespace dnb
