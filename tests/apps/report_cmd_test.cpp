// `denoisebench report` tables from a fixed small results.json (tests/apps/data): compared with
// the checked-in expected files, plus the speed-up computed by hand from the fixture's numbers.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <vector>

#include <nlohmann/json.hpp>

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

// Every metric table puts each record's own number in its own cell. The
// fixture's metrics repeat across rows and columns (ssim is 0.9 everywhere), so a swap goes
// unseen there; here every metric of every record gets a value of its own, 0.KSM (K the
// metric's position, S the scene's, M the method's: three digits, printed exactly by the
// tables' 4 significant digits), and every cell of every table1_<metric>.md is checked against
// the record of its row's scene and its column's method.
TEST(ReportCommand, EveryMetricTableCellIsItsRecordsValue) {
  test::TempDir dir;
  auto res = nlohmann::json::parse(slurp(fs::path(test::source_dir()) / "tests/apps/data/report_results.json"));
  const std::vector<std::string> metrics = {"mse", "mse_hdr", "relmse", "psnr", "ssim", "flip", "hdrflip", "mse_converged"};
  const std::vector<std::string> scenes = {"cornell-box", "bedroom"};
  const std::vector<std::string> methods = {"path_tracing", "input", "proposed", "bilateral", "proposed-no-nlm"};
  auto index_of = [](const std::vector<std::string>& v, const std::string& x) {
    return int(std::find(v.begin(), v.end(), x) - v.begin());
  };
  auto value = [&](int k, int s, int m) { return double((k + 1) * 100 + (s + 1) * 10 + (m + 1)) / 1000.0; };
  auto printed = [](double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%.4g", v);
    return std::string(b);
  };
  for (auto& rec : res["records"]) {
    const int s = index_of(scenes, rec["scene"]), m = index_of(methods, rec["method"]);
    ASSERT_LT(s, int(scenes.size())) << rec["scene"];
    ASSERT_LT(m, int(methods.size())) << rec["method"];
    for (std::size_t k = 0; k < metrics.size(); ++k) rec["metrics"][metrics[k]] = value(int(k), s, m);
  }
  test::write(dir.path() / "results.json", res.dump());
  auto r = test::run_denoisebench("report --no-plots --no-images " + dir.path().string());
  ASSERT_EQ(r.exit_code, 0) << r.output;

  // "| a | b |" -> {"a", "b"}
  auto cells = [](const std::string& line) {
    std::vector<std::string> out;
    std::stringstream ss(line.substr(1));
    for (std::string c; std::getline(ss, c, '|');) out.push_back(c.substr(1, c.size() - 2));
    return out;
  };
  for (std::size_t k = 0; k < metrics.size(); ++k) {
    SCOPED_TRACE("table1_" + metrics[k] + ".md");
    std::stringstream md(slurp(dir.path() / ("table1_" + metrics[k] + ".md")));
    std::vector<std::string> header;
    int checked = 0;
    std::set<std::string> rows;
    for (std::string line; std::getline(md, line);) {
      if (line.rfind("| scene |", 0) == 0) {
        header = cells(line);
        continue;
      }
      if (line.empty() || line[0] != '|' || line.rfind("|---", 0) == 0) continue;
      const auto row = cells(line);
      ASSERT_EQ(row.size(), header.size()) << line;
      const int s = index_of(scenes, row[0]);
      ASSERT_LT(s, int(scenes.size())) << line;
      rows.insert(row[0]);
      for (std::size_t c = 1; c < header.size(); ++c) {
        if (header[c] == "reference pixels left out") continue;  // mse_converged's reference column
        const std::string method = header[c].rfind("input (", 0) == 0 ? "input" : header[c];
        const int m = index_of(methods, method);
        ASSERT_LT(m, int(methods.size())) << header[c];
        EXPECT_EQ(row[c], printed(value(int(k), s, m))) << row[0] << " / " << header[c];
        ++checked;
      }
    }
    EXPECT_EQ(rows, std::set<std::string>(scenes.begin(), scenes.end()));
    EXPECT_EQ(checked, 6) << "2 scenes x (proposed, bilateral, input)";
  }
}

TEST(ReportCommand, RefusesAFolderWithoutResults) {
  test::TempDir dir;
  auto r = test::run_denoisebench("report " + dir.path().string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("results.json"));
}

}  // namespace
}  // namespace dnb
