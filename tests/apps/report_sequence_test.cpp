// The report of a run with an animated sequence (docs/report.md, "Sequences"): a 3-frame scene
// written here, run at 32x24 with a still and a temporal method, reported once for the suite;
// each test reads the folder: the per-frame plots, the MP4 (one video frame per frame), the
// viewer's manifest and frame slider, the page's links, and the report without ffmpeg.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;
using test::slurp;


// The scene is named by its file's path relative to the run's folder: the sequence is
// "slide.toml", its rows slide.toml.f00 .. f02.
const char* kConfig = R"(name = "tiny-sequence"
width = 32
height = 24
seeds = [1]
spp = [4]
methods = ["atrous", "temporal_accumulation"]
[[scene]]
name = "slide.toml"
frames = 3
[reference]
spp = 16
block_spp = 16
[timing]
repeats = 1
)";

const std::string kSequence = "slide.toml";
const std::vector<std::string> kRows = {"slide.toml.f00", "slide.toml.f01", "slide.toml.f02"};

bool have(const char* program) { return test::run_command(std::string("command -v ") + program + " >/dev/null").exit_code == 0; }

class ReportSequence : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<test::TempDir>();
    // Four frames (the camera and a box sliding over a checkered wall), of which the config runs three.
    test::write(dir_->path() / "slide.toml", slurp(test::source_dir() + "/tests/data/slide-sequence.toml"));
    test::write(dir_->path() / "seq.toml", kConfig);
    const std::string cd = "cd '" + dir_->path().string() + "' && DENOISEBENCH_CACHE='" + dir_->file("cache") + "' '" +
                           test::binary().string() + "' ";
    auto r = test::run_command(cd + "run seq.toml -o out");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    r = test::run_command(cd + "report out");
    log_ = r.output;
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  static void TearDownTestSuite() { dir_.reset(); }
  static std::string out() { return dir_->file("out"); }
  static std::unique_ptr<test::TempDir> dir_;
  static std::string log_;
};
std::unique_ptr<test::TempDir> ReportSequence::dir_;
std::string ReportSequence::log_;

TEST_F(ReportSequence, TheRunHasTheSequence) {
  const auto res = nlohmann::json::parse(slurp(out() + "/results.json"));
  ASSERT_EQ(res["config"]["sequences"], nlohmann::json({{kSequence, 3}}));
  std::set<std::string> columns;
  for (const auto& s : res["sequences"]) {
    EXPECT_EQ(s["sequence"], kSequence);
    EXPECT_EQ(s["images"].size(), 3u) << s.dump();
    columns.insert(s["method"].get<std::string>());
  }
  EXPECT_EQ(columns, (std::set<std::string>{"input", "atrous", "temporal_accumulation"}));
}

// plots/sequence_<seq>_<spp>spp_{mse,tmse}: PNG and PDF, a line for every column of results.json's
// sequences (plots/colours.json: the series matplotlib drew), linked from the page.
TEST_F(ReportSequence, PerFramePlotsOfEveryColumn) {
  const auto colours = nlohmann::json::parse(slurp(out() + "/plots/colours.json"));
  const std::string page = slurp(out() + "/index.html");
  for (const char* metric : {"mse", "tmse"}) {
    const std::string stem = "sequence_slide.toml_4spp_" + std::string(metric);
    EXPECT_TRUE(fs::exists(out() + "/plots/" + stem + ".png")) << stem;
    EXPECT_TRUE(fs::exists(out() + "/plots/" + stem + ".pdf")) << stem;
    ASSERT_TRUE(colours.contains(stem)) << colours.dump();
    std::set<std::string> series;
    for (const auto& [m, c] : colours[stem].items()) series.insert(m);
    EXPECT_EQ(series, (std::set<std::string>{"input", "atrous", "temporal_accumulation"})) << stem;
    EXPECT_THAT(page, HasSubstr("src=\"plots/" + stem + ".png\"")) << stem;
  }
}

// videos/<seq>_<spp>spp.mp4: as many video frames as the sequence has frames, even sizes, yuv420p.
TEST_F(ReportSequence, TheVideoHasOneFramePerFrameOfTheSequence) {
  if (!have("ffmpeg") || !have("ffprobe"))
    GTEST_SKIP() << "ffmpeg/ffprobe are not installed (Debian's ffmpeg; scripts/setup installs it): no video to check";
  const std::string mp4 = out() + "/videos/slide.toml_4spp.mp4";
  ASSERT_TRUE(fs::exists(mp4)) << log_;
  auto r = test::run_command_stdout("ffprobe -v error -count_frames -select_streams v:0 -show_entries "
                                    "stream=nb_read_frames,width,height,pix_fmt,codec_name -of json '" + mp4 + "'");
  ASSERT_EQ(r.exit_code, 0) << r.errors;
  const auto probe = nlohmann::json::parse(r.output);
  ASSERT_EQ(probe["streams"].size(), 1u) << r.output;
  const auto& s = probe["streams"][0];
  EXPECT_EQ(s["nb_read_frames"], "3") << r.output;
  EXPECT_EQ(s["pix_fmt"], "yuv420p") << r.output;
  EXPECT_THAT((std::set<std::string>{"h264", "mpeg4"}), ::testing::Contains(s["codec_name"].get<std::string>()));
  EXPECT_EQ(s["width"].get<int>() % 2, 0);
  EXPECT_EQ(s["height"].get<int>() % 2, 0);
  // Four 32x24 tiles (input, two methods, reference), each enlarged to at least 160 px wide.
  EXPECT_GE(s["width"].get<int>(), 4 * 160);
  EXPECT_THAT(slurp(out() + "/index.html"), HasSubstr("src=\"videos/slide.toml_4spp.mp4\""));
  EXPECT_THAT(log_, HasSubstr("videos/slide.toml_4spp.mp4: 3 frames"));
}

// web/viewer/manifest.js lists the sequence with its frame rows in order, each a scene of the
// manifest marked with its sequence and frame.
TEST_F(ReportSequence, TheViewerManifestListsTheSequencesFrames) {
  std::string js = slurp(out() + "/web/viewer/manifest.js");
  const std::string head = "var DNB_MANIFEST = ";
  ASSERT_EQ(js.rfind(head, 0), 0u) << js.substr(0, 80);
  js = js.substr(head.size());
  js = js.substr(0, js.rfind(';'));
  const auto m = nlohmann::json::parse(js);
  ASSERT_EQ(m["sequences"].size(), 1u) << m["sequences"].dump();
  const auto& q = m["sequences"][0];
  EXPECT_EQ(q["name"], kSequence);
  EXPECT_EQ(q["frames"], 3);
  EXPECT_EQ(q["rows"], nlohmann::json(kRows));
  ASSERT_EQ(q["scenes"].size(), 3u);
  for (int t = 0; t < 3; ++t) {
    const auto& sc = m["scenes"][q["scenes"][t].get<int>()];
    EXPECT_EQ(sc["name"], kRows[t]);
    EXPECT_EQ(sc["sequence"], kSequence);
    EXPECT_EQ(sc["frame"], t);
    std::set<std::string> radiance;
    for (const auto& e : sc["images"])
      if (e["kind"] == "radiance") radiance.insert(e["method"].get<std::string>());
    EXPECT_EQ(radiance, (std::set<std::string>{"input", "reference", "atrous", "temporal_accumulation"})) << kRows[t];
  }
}

// In headless Chromium (tests/apps/report_page.py): the sequence is one viewer whose frame slider,
// buttons and keys switch frames keeping the two chosen images, plus the page checks of stills.
TEST_F(ReportSequence, TheFrameSliderKeepsTheChosenImagesInChromium) {
  if (!fs::exists("/usr/bin/chromium")) GTEST_SKIP() << "Debian's chromium is not installed (scripts/setup installs it)";
  const std::string cmd = "timeout 120 /usr/bin/python3 '" + test::source_dir() + "/tests/apps/report_page.py' '" + out() + "' 2>&1";
  auto r = test::run_command(cmd);
  EXPECT_EQ(r.exit_code, 0) << cmd << "\n" << r.output;
  EXPECT_THAT(r.output, HasSubstr("every check passed")) << r.output;
}

// The page with its Sequences section (video.py's HTML) parses in html5lib's strict mode, and the
// header links to it.
TEST_F(ReportSequence, ThePageWithTheSequencesSectionParsesWithoutErrors) {
  if (test::run_command("/usr/bin/python3 -c 'import html5lib'").exit_code != 0)
    GTEST_SKIP() << "python3-html5lib is not installed (scripts/setup installs it)";
  auto r = test::run_command("/usr/bin/python3 -c 'import html5lib, sys; html5lib.HTMLParser(strict=True).parse(open(sys.argv[1], \"rb\"))' '" +
                             out() + "/index.html' 2>&1");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  const std::string page = slurp(out() + "/index.html");
  EXPECT_THAT(page, HasSubstr("<h2 id=\"sequences\">Sequences</h2>"));
  EXPECT_THAT(page, HasSubstr("<a href=\"#sequences\">sequences</a>"));
}

// Without ffmpeg the report goes on: exit 0, the log and the page say the video is skipped and why.
TEST_F(ReportSequence, WithoutFfmpegTheReportSaysTheVideoIsSkippedAndWhy) {
  test::TempDir copy;
  fs::copy(out(), copy.path() / "out", fs::copy_options::recursive);
  fs::remove_all(copy.path() / "out/videos");
  auto r = test::run_command("DENOISEBENCH_FFMPEG='" + copy.file("no-ffmpeg") + "' '" + test::binary().string() +
                             "' report --no-plots " + copy.file("out"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("sequence videos skipped: DENOISEBENCH_FFMPEG='" + copy.file("no-ffmpeg") +
                                  "' is not an executable file"));
  EXPECT_FALSE(fs::exists(copy.path() / "out/videos/slide.toml_4spp.mp4"));
  EXPECT_THAT(slurp(copy.path() / "out/index.html"), HasSubstr("No video: DENOISEBENCH_FFMPEG="));
}

// An image that a sequence record names but that is gone is bad input: exit 2 naming the key.
TEST_F(ReportSequence, AMissingFrameImageIsBadInputNamingTheKey) {
  if (!have("ffmpeg")) GTEST_SKIP() << "ffmpeg is not installed (scripts/setup installs it): the video, which reads the frames, is skipped";
  test::TempDir copy;
  fs::copy(out(), copy.path() / "out", fs::copy_options::recursive);
  const auto res = nlohmann::json::parse(slurp(copy.path() / "out/results.json"));
  int index = -1;
  for (std::size_t i = 0; i < res["sequences"].size(); ++i)
    if (res["sequences"][i]["method"] == "temporal_accumulation") index = int(i);
  ASSERT_GE(index, 0);
  const std::string rel = res["sequences"][index]["images"][2];
  // The viewer reads the first seed's images at the tables' spp too: take the frame's image away
  // from the record as well, so that the video is what meets the missing file.
  auto doc = res;
  for (auto& rec : doc["records"])
    if (rec["scene"] == kRows[2] && rec["method"] == "temporal_accumulation") rec["files"].erase("image");
  test::write(copy.path() / "out/results.json", doc.dump());
  fs::remove(copy.path() / "out" / rel);
  auto r = test::run_command(std::string("'").append(test::binary().string()).append("' report --no-plots ").append(copy.file("out")));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("sequences[" + std::to_string(index) + "].images[2]")) << r.output;
  EXPECT_THAT(r.output, HasSubstr(rel)) << r.output;
}

}  // namespace
}  // namespace dnb
