// Numbers on the command line are bounded before any work starts (core/bounds.h through
// apps/args.h): out of bounds, or not a whole number, is exit status 2 naming the option, what
// was typed and the bound, and no output file is left behind.
#include <gtest/gtest.h>

#include <filesystem>
#include <vector>

#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;

// Runs `args` (which writes `out`, if anything) and checks the refusal.
void expect_refused(const test::TempDir& dir, const std::string& args, const std::string& option,
                    const std::string& typed, const std::string& bound) {
  const std::string out = dir.file("out.exr");
  auto r = test::run_denoisebench(args + " -o " + out);
  EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
  EXPECT_NE(r.output.find(option), std::string::npos) << args << ": does not name " << option << "\n" << r.output;
  EXPECT_NE(r.output.find(typed), std::string::npos) << args << ": does not name " << typed << "\n" << r.output;
  EXPECT_NE(r.output.find(bound), std::string::npos) << args << ": does not give the bound " << bound << "\n" << r.output;
  EXPECT_FALSE(fs::exists(out)) << args;
}

// render --threads 100000 crashed (SIGSEGV) in most tries; reference capped at 4096 and
// denoise at 1024. Now one rule for all three.
TEST(CommandLineBounds, ThreadsOneRuleForEveryCommand) {
  test::TempDir dir;
  for (const std::string& cmd : std::vector<std::string>{"render cornell-box --size 8x6 --spp 1",
                                                         "reference cornell-box --size 8x6 --spp 1",
                                                         "denoise bilateral " + dir.file("no-frame.exr")})
    expect_refused(dir, cmd + " --threads 100000", "--threads", "100000", "0..1024");
}

// A negative seed wrapped into a huge unsigned one and rendered with exit 0.
TEST(CommandLineBounds, NegativeSeedIsRefused) {
  test::TempDir dir;
  expect_refused(dir, "render cornell-box --size 8x6 --spp 1 --seed -5", "--seed", "-5", ">= 0");
  expect_refused(dir, "reference cornell-box --size 8x6 --spp 1 --seed -5", "--seed", "-5", ">= 0");
  expect_refused(dir, "run " + dir.file("no-config.toml") + " --seed -5", "--seed", "-5", ">= 0");
}

TEST(CommandLineBounds, SppAndDepthAreBounded) {
  test::TempDir dir;
  expect_refused(dir, "render cornell-box --size 8x6 --spp 99999999999", "--spp", "99999999999", "1..16777216");
  expect_refused(dir, "render cornell-box --size 8x6 --spp 0", "--spp", "'0'", "1..16777216");
  expect_refused(dir, "render cornell-box --size 8x6 --spp 1 --max-depth 0", "--max-depth", "'0'", "1..1024");
  expect_refused(dir, "reference cornell-box --size 8x6 --spp 4 --block-spp 0", "--block-spp", "'0'", "1..16777216");
}

// `run` refuses a config whose spp overflowed an int (it ran a cell, then failed with "spp must
// be at least 1 (got -2147483648)") before any cell: exit 2 naming file:line and key, and no
// results folder.
TEST(CommandLineBounds, RunRefusesAnOutOfBoundsConfigBeforeAnyCell) {
  test::TempDir dir;
  const std::string config = dir.file("big.toml");
  test::write(config, "name = \"big\"\nwidth = 8\nheight = 6\nscenes = [\"cornell-box\"]\nspp = [1e12]\n"
                      "methods = [\"bilateral\"]\n");
  auto r = test::run_denoisebench("run " + config + " -o " + dir.file("results"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(config + ":5: key 'spp'"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir.file("results"))) << "work started before the config was checked";
}

}  // namespace
}  // namespace dnb
