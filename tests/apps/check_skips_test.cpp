// scripts/check_skips: in CI a skipped test that tests/allowed_skips.txt does not list fails the
// run, naming it and the reason it gave; a listed one (for its build) passes; off CI skips are
// only listed. Also scripts/lsan_exit_crashes, which reads the same JUnit files.
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

// scripts/lsan_exit_crashes: names the failed tests for a rerun only when every failure of the
// run is LeakSanitizer crashing at exit after the test passed; any other failure, or a crash
// before PASSED, names none.
std::string failed_case(const std::string& name, const std::string& out) {
  return "<testcase name=\"" + name + "\" status=\"fail\"><system-out>" + out + "</system-out></testcase>\n";
}

TEST(LsanExitCrashes, RerunsOnlyTestsThatPassedBeforeLeakSanitizerCrashed) {
  const std::string passed = "[ RUN      ] OpenCl.A\n[       OK ] OpenCl.A (3 ms)\n[  PASSED  ] 1 test.\n";
  const std::string crash = "Tracer caught signal 11: addr=0x2b20\n==7==LeakSanitizer has encountered a fatal error.\n";
  const std::string ok = "<testcase name=\"Ran.Fine\" status=\"run\"/>\n";
  test::TempDir dir;
  auto run = [&](const std::string& cases) {
    test::write(dir.path() / "j.xml", "<?xml version=\"1.0\"?>\n<testsuite>\n" + ok + cases + "</testsuite>\n");
    return test::run_command("'" + test::source_dir() + "/scripts/lsan_exit_crashes' '" + dir.file("j.xml") + "'");
  };
  auto r = run(failed_case("OpenCl.A", passed + crash) + failed_case("Suite/P.B/0", passed + crash));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output, "^(OpenCl\\.A|Suite/P\\.B/0)$\n");  // regex-escaped, anchored: exactly these
  // Beside an assertion's failure, nothing is rerun.
  r = run(failed_case("OpenCl.A", passed + crash) + failed_case("X.Y", "[  FAILED  ] X.Y\n"));
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.output, "");
  // The crash before the test finished, or with a finding, is a failure of its own.
  EXPECT_EQ(run(failed_case("OpenCl.A", crash + passed)).output, "");
  EXPECT_EQ(run(failed_case("OpenCl.A", "ERROR: AddressSanitizer: heap-use-after-free\n" + passed + crash)).output, "");
  EXPECT_EQ(run("").output, "");  // nothing failed
  EXPECT_EQ(test::run_command("'" + test::source_dir() + "/scripts/lsan_exit_crashes' '" + dir.file("none.xml") + "'").exit_code,
            2);
}

}  // namespace
}  // namespace dnb
