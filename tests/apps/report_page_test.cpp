// The report as a researcher's tool: the page's viewer driven in headless Chromium,
// the page's tables at 800 and 1400 px, the HTML parsed strictly, the plots' colours and PDFs,
// and a missing image as bad input. One small run (2 scenes, 2 seeds, 2 methods and a variant)
// is made once for the suite and reported; each test reads it.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;
using test::binary;
using test::run_in;
using test::slurp;

const char* kConfig = R"(name = "page"
width = 48
height = 36
scenes = ["cornell-box", "conference"]
spp = [16]
seeds = [1, 2]
methods = ["bilateral", "atrous"]
[reference]
spp = 64
block_spp = 16
[speedup]
spp = [1, 4]
[timing]
repeats = 1
[[variant]]
name = "bilateral-wide"
method = "bilateral"
group = "ablation"
set = { sigma_space = 16.0 }
)";

class ReportViewer : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<test::TempDir>();
    test::write(dir_->path() / "page.toml", kConfig);
    auto r = run_in(*dir_, "run " + dir_->file("page.toml") + " -o " + dir_->file("out"));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    r = run_in(*dir_, "report " + dir_->file("out"));
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  static void TearDownTestSuite() { dir_.reset(); }
  static std::string out() { return dir_->file("out"); }
  static std::unique_ptr<test::TempDir> dir_;
};
std::unique_ptr<test::TempDir> ReportViewer::dir_;

// tests/apps/report_page.py says what it checks: both selectors list every image of each scene
// (against results.json), two chosen images change both sides, a wheel event scales every view
// of the scene, a drag pans them, an error map shows a colour bar, keys and the loupe work, no
// table is wider than the viewport at 800 and 1400 px without a scroll box, and the page logs no
// console error and no failed request, and the tiles where a method is worse than its input are
// outlined (at 16 spp against a 64-spp reference, the wide bilateral, sigma_space 16 at 48x36, blurs
// cornell-box's first seed worse than its input in 7 of 9 tiles: checked here, so that check is
// not vacuous).
TEST_F(ReportViewer, TheViewerWorksInHeadlessChromium) {
  if (!fs::exists("/usr/bin/chromium")) GTEST_SKIP() << "Debian's chromium is not installed (scripts/setup installs it)";
  const nlohmann::json doc = nlohmann::json::parse(slurp(out() + "/results.json"));
  bool some_worse = false;
  for (const auto& rec : doc["records"])
    some_worse = some_worse || (rec.value("seed", 0) == 1 && rec.contains("worse_tiles") && !rec["worse_tiles"].empty());
  EXPECT_TRUE(some_worse) << "no method of the first seed is worse than its input anywhere: the viewer's tile check would not run";
  const fs::path shots = binary().parent_path() / "report_page_shots";
  const std::string cmd = "timeout 120 /usr/bin/python3 '" + test::source_dir() + "/tests/apps/report_page.py' '" + out() +
                          "' --shots '" + shots.string() + "' 2>&1";
  auto r = test::run_command(cmd);
  EXPECT_EQ(r.exit_code, 0) << cmd << "\n" << r.output;
  EXPECT_THAT(r.output, HasSubstr("every check passed")) << r.output;
  for (const char* s : {"page_800_top.png", "page_1400_top.png", "page_800_images.png", "page_1400_images.png"})
    EXPECT_TRUE(fs::exists(shots / s)) << s;
}

// html5lib's strict mode stops at the first parse error of the HTML5 parsing algorithm
// (unclosed or misnested elements, stray end tags, bad attributes): the page as written by
// `report`, before any script runs.
TEST_F(ReportViewer, TheHtmlParsesWithoutErrors) {
  if (test::run_command("/usr/bin/python3 -c 'import html5lib'").exit_code != 0)
    GTEST_SKIP() << "python3-html5lib is not installed (scripts/setup installs it)";
  auto r = test::run_command("/usr/bin/python3 -c 'import html5lib, sys; html5lib.HTMLParser(strict=True).parse(open(sys.argv[1], \"rb\"))' '" +
                             out() + "/index.html' 2>&1");
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

// Every method keeps one colour across every plot of the run (plots/colours.json: what
// matplotlib drew each series in), different methods differ, a variant has its parent's colour,
// and every plot is also a PDF that poppler opens.
TEST_F(ReportViewer, EveryMethodHasOneColourInEveryPlotAndEveryPlotIsAPdf) {
  const auto colours = nlohmann::json::parse(slurp(out() + "/plots/colours.json"));
  std::map<std::string, std::set<std::string>> of;
  for (const auto& [plot, series] : colours.items())
    for (const auto& [method, colour] : series.items()) of[method].insert(colour.get<std::string>());
  for (const char* m : {"input", "bilateral", "atrous", "bilateral-wide", "path_tracing"}) ASSERT_TRUE(of.count(m)) << m;
  for (const auto& [m, cs] : of) EXPECT_EQ(cs.size(), 1u) << m << " is drawn in " << ::testing::PrintToString(cs);
  std::map<std::string, std::string> owner;
  for (const auto& [m, cs] : of) {
    if (m == "bilateral-wide") continue;
    const std::string c = *cs.begin();
    EXPECT_FALSE(owner.count(c)) << m << " and " << owner[c] << " share " << c;
    owner[c] = m;
  }
  EXPECT_EQ(of["bilateral-wide"], of["bilateral"]) << "a variant is drawn in its parent's colour";
  EXPECT_GE(colours.size(), 7u) << "the bars and three plots per scene";

  const bool pdfinfo = fs::exists("/usr/bin/pdfinfo");
  int pngs = 0;
  for (const auto& e : fs::directory_iterator(out() + "/plots")) {
    if (e.path().extension() != ".png") continue;
    ++pngs;
    const fs::path pdf = fs::path(e.path()).replace_extension(".pdf");
    ASSERT_TRUE(fs::exists(pdf)) << pdf;
    EXPECT_TRUE(colours.contains(e.path().stem().string())) << e.path();
    if (!pdfinfo) continue;
    auto r = test::run_command("/usr/bin/pdfinfo '" + pdf.string() + "' 2>&1");
    EXPECT_EQ(r.exit_code, 0) << pdf << ": " << r.output;
    EXPECT_THAT(r.output, HasSubstr("Pages:")) << pdf;
  }
  EXPECT_EQ(pngs, 7);
  if (!pdfinfo) GTEST_SKIP() << "the PDFs exist; pdfinfo (poppler-utils, scripts/setup) is not installed to open them";
}

// Table 2 gives every method's filter time, each from its record.
TEST_F(ReportViewer, Table2GivesEveryMethodsFilterTime) {
  const std::string md = slurp(out() + "/table2_filter_times.md");
  EXPECT_THAT(md, HasSubstr("| scene | render input (16 spp) | bilateral | atrous | bilateral-wide |"));
  const auto res = nlohmann::json::parse(slurp(out() + "/results.json"));
  for (const auto& rec : res["records"]) {
    if (rec["role"] == "plain" || rec["seed"] != 1 || rec["scene"] != "conference" || rec["method"] != "atrous") continue;
    char b[32];
    std::snprintf(b, sizeof b, "%.3g", rec["times"]["filter"].get<double>());
    EXPECT_THAT(md, HasSubstr(std::string(" | ") + b + " | ")) << md;
  }
}

// A missing image that results.json names is bad input: exit 2 naming the file and the key.
TEST_F(ReportViewer, AMissingImageIsBadInputNamingTheFileAndKey) {
  test::TempDir copy;
  fs::copy(out(), copy.path() / "out", fs::copy_options::recursive);
  const auto res = nlohmann::json::parse(slurp(copy.path() / "out/results.json"));
  int index = -1;
  std::string rel;
  for (std::size_t i = 0; i < res["records"].size(); ++i)
    if (res["records"][i]["method"] == "atrous" && res["records"][i]["seed"] == 1) {
      index = int(i);
      rel = res["records"][i]["files"]["error_relmse"];
      break;
    }
  ASSERT_GE(index, 0);
  fs::remove(copy.path() / "out" / rel);
  auto r = test::run_denoisebench("report " + copy.file("out"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("records[" + std::to_string(index) + "].files.error_relmse")) << r.output;
  EXPECT_THAT(r.output, HasSubstr(rel)) << r.output;
}

}  // namespace
}  // namespace dnb
