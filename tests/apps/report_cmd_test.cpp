// `denoisebench report` tables from a fixed small results.json (tests/apps/data): compared with
// the checked-in expected files, plus the speed-up computed by hand from the fixture's numbers.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;

using test::slurp;

class ReportTables : public ::testing::Test {
 protected:
  void SetUp() override {
    data = fs::path(test::source_dir()) / "tests/apps/data";
    fs::copy_file(data / "report_results.json", dir.path() / "results.json");
    auto r = test::run_denoisebench("report --no-plots --no-images " + dir.path().string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  test::TempDir dir;
  fs::path data;
};

TEST_F(ReportTables, MatchExpectedFiles) {
  // Regenerate with: denoisebench report --no-plots --no-images on a copy of
  // report_results.json, after checking the difference by hand.
  for (const auto& e : fs::directory_iterator(data / "report_expected")) {
    const auto name = e.path().filename();
    ASSERT_TRUE(fs::exists(dir.path() / name)) << name;
    EXPECT_EQ(slurp(dir.path() / name), slurp(e.path())) << name;
  }
  for (const char* f : {"table1_mse.md", "table1_mse.csv", "table1_mse.tex", "table2_time.md", "table2_time.csv",
                        "table2_time.tex", "speedup.md", "ablation.md", "table1_flip.md", "table1_ssim.md", "index.html"})
    EXPECT_TRUE(fs::exists(dir.path() / f)) << f;
}

TEST_F(ReportTables, SpeedupIsTheHandComputedOne) {
  // Fixture: plain path tracing mse = 100 t^-0.5 with t = spp / 16 (cornell-box); proposed has
  // mse 10 at a total of 2 s. Path tracing reaches mse 10 at t = (10/100)^-2 = 100 s, i.e.
  // 1600 spp: a speed-up of 50x. bilateral: mse 50 -> t = 4 s, 64 spp, / 1.25 s = 3.2x.
  const std::string md = slurp(dir.path() / "speedup.md");
  EXPECT_THAT(md, HasSubstr("| cornell-box | proposed | 10 | 2.00 | 1600 | 100 (extrapolated) | 50.0x |"));
  EXPECT_THAT(md, HasSubstr("| cornell-box | bilateral | 50 | 1.25 | 64 | 4 | 3.2x |"));
  // Table 2's total CPU is input render + proposed's filter time.
  EXPECT_THAT(slurp(dir.path() / "table2_time.md"), HasSubstr("| cornell-box | 1.00 | 1.00 | 2.00 | n/a | n/a | n/a | 600.00 |"));
  EXPECT_THAT(slurp(dir.path() / "ablation.md"), HasSubstr("| proposed-no-nlm | 12.5 (+25%) | 25 (+25%) |"));
}

TEST_F(ReportTables, RatiosAndTheConvergedMseComeFromTheResults) {
  // Fixture: cornell-box proposed mse 10, bilateral 50 (0.20); mse_converged 4 against 40
  // (0.10), its reference leaving out 1.25% of the pixels. bedroom's records predate
  // mse_converged: n/a, not a made-up number.
  const std::string ra = slurp(dir.path() / "ratios.md");
  EXPECT_THAT(ra, HasSubstr("| cornell-box | mse | 0.20 |"));
  EXPECT_THAT(ra, HasSubstr("| cornell-box | mse_converged | 0.10 |"));
  EXPECT_THAT(ra, HasSubstr("| bedroom | mse | 0.20 |"));
  EXPECT_THAT(ra, HasSubstr("| bedroom | mse_converged | n/a |"));
  const std::string t1 = slurp(dir.path() / "table1_mse_converged.md");
  EXPECT_THAT(t1, HasSubstr("| cornell-box | 4 | 40 | 90 | 1.250% |"));
  EXPECT_THAT(t1, HasSubstr("| bedroom | n/a | n/a | n/a | n/a |"));
  EXPECT_THAT(slurp(dir.path() / "index.html"), HasSubstr("Ratios: proposed"));
}

TEST(ReportCommand, RefusesAFolderWithoutResults) {
  test::TempDir dir;
  auto r = test::run_denoisebench("report " + dir.path().string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("results.json"));
}

}  // namespace
}  // namespace dnb
