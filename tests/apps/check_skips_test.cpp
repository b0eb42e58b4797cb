// scripts/check_skips: in CI a skipped test that tests/allowed_skips.txt does not list fails the
// run, naming it and the reason it gave; a listed one (for its build) passes; off CI skips are
// only listed.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>

#include "test_util.h"

namespace dnb {
namespace {
using ::testing::HasSubstr;

std::string junit_with_skip(const std::string& name, const std::string& reason) {
  return "<?xml version=\"1.0\"?>\n<testsuite tests=\"2\">\n<testcase name=\"" + name +
         "\" status=\"notrun\"><skipped message=\"SKIP_REGULAR_EXPRESSION_MATCHED\"/><system-out>x_test.cpp:9: Skipped\n" +
         reason + "\n</system-out></testcase>\n<testcase name=\"Ran.Fine\" status=\"run\"/>\n</testsuite>\n";
}

test::CommandResult check(const test::TempDir& dir, const std::string& build, bool ci) {
  return test::run_command(std::string(ci ? "CI=true " : "CI= ") + "'" + test::source_dir() + "/scripts/check_skips' '" +
                           dir.file("j.xml") + "' " + build);
}

TEST(CheckSkips, AnUnlistedSkipFailsCiNamingTheTestAndItsReason) {
  test::TempDir dir;
  test::write(dir.path() / "j.xml", junit_with_skip("ReportPage.Loads", "Debian's chromium is not installed"));
  auto r = check(dir, "release", true);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_THAT(r.output, HasSubstr("ReportPage.Loads"));
  EXPECT_THAT(r.output, HasSubstr("Debian's chromium is not installed"));
  r = check(dir, "release", false);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("skipped ReportPage.Loads"));
}

TEST(CheckSkips, AListedSkipPassesOnlyForItsBuild) {
  test::TempDir dir;
  test::write(dir.path() / "j.xml", junit_with_skip("AmDevice.TimesARecordedCallOnBothPaths", "no benchmarks"));
  auto r = check(dir, "asan", true);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("allowed"));
  r = check(dir, "release", true);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  test::write(dir.path() / "j.xml", "<?xml version=\"1.0\"?><testsuite><testcase name=\"A.B\" status=\"run\"/></testsuite>");
  EXPECT_EQ(check(dir, "release", true).exit_code, 0);
  EXPECT_EQ(test::run_command("'" + test::source_dir() + "/scripts/check_skips' '" + dir.file("none.xml") + "' release").exit_code, 2);
}

}  // namespace
}  // namespace dnb
