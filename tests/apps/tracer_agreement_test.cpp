// scripts/tracer_agreement: the check a new tracer version must pass (docs/speed.md). A build
// against itself agrees (other seeds on each side, so only the noise differs); a "new tracer"
// that cuts paths at 2 segments instead of 8 (no indirect light at all) is refused, naming the
// channels; bad arguments exit 2 before any render.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "test_util.h"

namespace dnb {
namespace {
using ::testing::HasSubstr;

test::CommandResult agreement(const std::string& old_bin, const std::string& new_bin, const std::string& extra) {
  // Small on purpose: one scene, 16x12, 64 spp in 4 seeds per side (a few seconds).
  return test::run_command("'" + test::source_dir() + "/scripts/tracer_agreement' '" + old_bin + "' '" + new_bin +
                           "' --scenes cornell-box --size 16x12 --spp 64 --seeds 4 " + extra);
}

TEST(TracerAgreement, ABuildAgreesWithItselfAndRefusesOneThatCutsItsPaths) {
  test::TempDir dir;
  const std::string bin = test::binary().string();
  auto r = agreement(bin, bin, "--out '" + dir.file("same.json") + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("all within 4 standard errors"));
  const nlohmann::json same = nlohmann::json::parse(test::slurp(dir.file("same.json")));
  EXPECT_EQ(same.at("comparisons").get<int>(), same.at("scenes").at("cornell-box").at("channels").get<int>());
  EXPECT_GT(same.at("comparisons").get<int>(), 100);  // every channel of the frame, not a few
  EXPECT_TRUE(same.at("outside").empty());
  // Independent seeds on the two sides: the colour differs by noise, not by nothing.
  EXPECT_NE(same.at("scenes").at("cornell-box").at("z").at("R").get<double>(), 0.0);

  // The same binary, but every render cut to path length 2: direct light only.
  const std::string cut = dir.file("cut.sh");
  test::write(cut, "#!/bin/sh\nfor a; do shift; set -- \"$@\" \"$a\"; [ \"$a\" = render ] && set -- \"$@\" --max-depth 2; "
                   "done\nexec '" + bin + "' \"$@\"\n");
  std::filesystem::permissions(cut, std::filesystem::perms::owner_all);
  r = agreement(bin, cut, "--out '" + dir.file("cut.json") + "'");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_THAT(r.output, HasSubstr("FAIL"));
  const nlohmann::json c = nlohmann::json::parse(test::slurp(dir.file("cut.json")));
  const auto& outside = c.at("outside");
  EXPECT_NE(std::find(outside.begin(), outside.end(), "cornell-box indirect.R"), outside.end()) << outside.dump();
}

TEST(TracerAgreement, BadArgumentsExit2BeforeAnyRender) {
  const std::string bin = test::binary().string();
  auto r = agreement(bin, "/no/such/denoisebench", "");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("/no/such/denoisebench: not an executable"));
  r = agreement(bin, bin, "--seeds 3");  // 64 spp is no multiple of 3 seeds
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("--spp 64"));
  r = agreement(bin, bin, "--seeds 1");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("--seeds: at least 2"));
}

}  // namespace
}  // namespace dnb
