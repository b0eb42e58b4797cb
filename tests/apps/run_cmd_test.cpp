// `denoisebench run` and `report` end to end on a tiny config (one scene, a few samples), and
// the report page in headless Chromium: it loads without console errors, every image it
// references exists, and a screenshot is taken (build/report_screenshot.png).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/exr_io.h"
#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;

using test::binary;
using test::run_in;
using test::slurp;
using test::write;

const char* kTinyConfig = R"(name = "tiny"
width = 32
height = 24
scenes = ["cornell-box"]
spp = [2]
methods = ["bilateral"]
[reference]
spp = 16
block_spp = 8
[speedup]
spp = [1, 4]
[timing]
repeats = 2
[[variant]]
name = "bilateral-wide"
method = "bilateral"
group = "ablation"
set = { sigma_space = 6.0 }
)";

// Runs kTinyConfig into DIR/out (exit 0) and reads its results.json.
void run_tiny(const test::TempDir& dir, std::string& out, nlohmann::json& res) {
  write(dir.path() / "tiny.toml", kTinyConfig);
  out = dir.file("out");
  auto r = run_in(dir, "run " + dir.file("tiny.toml") + " -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  res = nlohmann::json::parse(slurp(out + "/results.json"));
}

TEST(RunCommand, WritesEveryRecordAndResumesWithoutRedoingCells) {
  test::TempDir dir;
  write(dir.path() / "tiny.toml", kTinyConfig);
  const std::string out = dir.file("out");
  auto r = run_in(dir, "run " + dir.file("tiny.toml") + " -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto res = nlohmann::json::parse(slurp(out + "/results.json"));
  // 2 plain path tracing renders + the input + bilateral + its variant.
  ASSERT_EQ(res["records"].size(), 5u);
  std::set<std::string> methods;
  for (const auto& rec : res["records"]) {
    methods.insert(rec["method"].get<std::string>());
    for (const char* m : {"mse", "mse_hdr", "relmse", "psnr", "ssim", "flip"}) EXPECT_TRUE(rec["metrics"].contains(m)) << m;
    for (const char* t : {"input_render", "filter", "total", "reference"}) EXPECT_TRUE(rec["times"].contains(t)) << t;
    EXPECT_TRUE(fs::exists(out + "/" + rec["files"]["image"].get<std::string>()));
    EXPECT_GT(rec["metrics"]["mse"].get<double>(), 0.0);
  }
  EXPECT_EQ(methods, (std::set<std::string>{"path_tracing", "input", "bilateral", "bilateral-wide"}));
  EXPECT_TRUE(res.contains("machine") && res.contains("build") && res.contains("git_revision"));
  for (const auto& rec : res["records"]) {
    if (rec["method"] == "bilateral-wide") {
      EXPECT_EQ(rec["params"]["sigma_space"], "6");
    }
  }
  // results.csv: a header and one line per record.
  const std::string csv = slurp(out + "/results.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 6);

  // A second run finds every cell finished: no output image is written again.
  const auto before = fs::last_write_time(out + "/images/cornell-box/bilateral_2.exr");
  auto again = run_in(dir, "run " + dir.file("tiny.toml") + " -o " + out);
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_THAT(again.output, HasSubstr("cache hit"));
  EXPECT_EQ(fs::last_write_time(out + "/images/cornell-box/bilateral_2.exr"), before);
  EXPECT_EQ(nlohmann::json::parse(slurp(out + "/results.json"))["records"].size(), 5u);

  // A run that does not reach a cell (killed, or here a config without the variant) must not
  // make the folder forget it: results.json then lists that run's cells only, but the next run
  // of the full config reuses the variant's cell instead of recomputing it.
  const std::string variant_image = out + "/images/cornell-box/bilateral-wide_2.exr";
  ASSERT_TRUE(fs::exists(variant_image));
  const auto variant_before = fs::last_write_time(variant_image);
  std::string subset = kTinyConfig;
  subset.resize(subset.find("[[variant]]"));
  write(dir.path() / "subset.toml", subset);
  auto part = run_in(dir, "run " + dir.file("subset.toml") + " -o " + out);
  ASSERT_EQ(part.exit_code, 0) << part.output;
  EXPECT_EQ(nlohmann::json::parse(slurp(out + "/results.json"))["records"].size(), 4u);
  auto full = run_in(dir, "run " + dir.file("tiny.toml") + " -o " + out);
  ASSERT_EQ(full.exit_code, 0) << full.output;
  EXPECT_EQ(fs::last_write_time(variant_image), variant_before) << "the variant's finished cell was recomputed";
  EXPECT_EQ(nlohmann::json::parse(slurp(out + "/results.json"))["records"].size(), 5u);

  // Another build (here: the same program with one byte appended, so its file hash differs)
  // must not reuse the method cells another build computed: after a code change the tables
  // would silently keep the old numbers. The plain path-tracing cells are scored again (the
  // metrics are code), their render read from the render cache instead of rendered again.
  const fs::path other = dir.path() / "denoisebench-rebuilt";
  fs::copy_file(binary(), other);
  std::ofstream(other, std::ios::app | std::ios::binary) << '\n';
  fs::permissions(other, fs::perms::owner_exec, fs::perm_options::add);
  auto rebuilt = test::run_command("DENOISEBENCH_CACHE='" + dir.file("cache") + "' '" + other.string() + "' run " +
                                   dir.file("tiny.toml") + " -o " + out);
  ASSERT_EQ(rebuilt.exit_code, 0) << rebuilt.output;
  EXPECT_NE(fs::last_write_time(out + "/images/cornell-box/bilateral_2.exr"), before);
  const auto res3 = nlohmann::json::parse(slurp(out + "/results.json"));
  EXPECT_EQ(res3["records"].size(), 5u);
  EXPECT_NE(res3["build"]["build_id"], res["build"]["build_id"]);
  const auto plain = [](const nlohmann::json& doc) {
    std::map<int, nlohmann::json> by_spp;
    for (const auto& rec : doc["records"])
      if (rec["role"] == "plain") by_spp[rec["spp"].get<int>()] = rec;
    return by_spp;
  };
  const auto plain_before = plain(res), plain_after = plain(res3);
  ASSERT_EQ(plain_after.size(), 2u);
  for (const auto& [spp, rec] : plain_after) {
    const auto& old = plain_before.at(spp);
    EXPECT_EQ(old["input_cache_hit"], false) << "the first run rendered the curve";
    EXPECT_EQ(rec["input_cache_hit"], true) << rec.dump();
    EXPECT_NE(rec["cell_key"], old["cell_key"]) << "scored again by the other build";
    EXPECT_EQ(rec["metrics"]["mse"], old["metrics"]["mse"]) << "the same points, read from the cache";
    EXPECT_EQ(rec["times"]["total"], old["times"]["total"]) << "the render's own time, as first measured";
  }

  // The timing settings are part of a method cell: a run with another repeat threshold times
  // the filters again instead of keeping times taken under the old one.
  const auto timed_before = fs::last_write_time(out + "/images/cornell-box/bilateral_2.exr");
  std::string retimed = kTinyConfig;
  retimed.replace(retimed.find("repeats = 2"), 11, "repeats = 2\nrepeat_below_seconds = 5.0");
  write(dir.path() / "retimed.toml", retimed);
  auto rt = test::run_command("DENOISEBENCH_CACHE='" + dir.file("cache") + "' '" + other.string() + "' run " +
                              dir.file("retimed.toml") + " -o " + out);
  ASSERT_EQ(rt.exit_code, 0) << rt.output;
  EXPECT_NE(fs::last_write_time(out + "/images/cornell-box/bilateral_2.exr"), timed_before);
}

// results.json's numbers are the scores of the images it names against the reference it names:
// each metric recomputed from the written files by `denoisebench metrics` agrees (a record that
// stored another cell's score, or a stale image, fails here); every method beats the 2 spp input;
// and the reference was rendered with a seed of its own, not the inputs'.
// Two configs with the same method and spp but other parameters write the same file names into a
// folder. Going back to the first config must not reuse its record beside the second one's image
// (the record's scores would then describe another picture): the image names its cell's key.
TEST(RunCommand, ACellWhoseImageAnotherCellOverwroteIsComputedAgain) {
  test::TempDir dir;
  std::string out;
  nlohmann::json first;
  ASSERT_NO_FATAL_FAILURE(run_tiny(dir, out, first));
  const auto bilateral = [](const nlohmann::json& res) {
    for (const auto& rec : res["records"])
      if (rec["method"] == "bilateral") return rec;
    return nlohmann::json();
  };
  const std::string image = out + "/images/cornell-box/bilateral_2.exr";
  const auto key_in_image = [&] { return read_exr_channels(image, false).attributes.at("denoisebench:cell_key"); };
  EXPECT_EQ(key_in_image(), bilateral(first)["cell_key"]);

  std::string wide_config = kTinyConfig;
  wide_config.resize(wide_config.find("[[variant]]"));
  write(dir.path() / "wide.toml", wide_config + "[params.bilateral]\nsigma_space = 4.0\n");
  auto wide = run_in(dir, "run " + dir.file("wide.toml") + " -o " + out);
  ASSERT_EQ(wide.exit_code, 0) << wide.output;
  const auto wide_record = bilateral(nlohmann::json::parse(slurp(out + "/results.json")));
  ASSERT_NE(wide_record["cell_key"], bilateral(first)["cell_key"]);
  EXPECT_EQ(key_in_image(), wide_record["cell_key"]);

  auto back = run_in(dir, "run " + dir.file("tiny.toml") + " -o " + out);
  ASSERT_EQ(back.exit_code, 0) << back.output;
  const auto again = bilateral(nlohmann::json::parse(slurp(out + "/results.json")));
  EXPECT_EQ(key_in_image(), bilateral(first)["cell_key"]) << "the first config's record was kept beside another image";
  EXPECT_EQ(again["metrics"]["mse"], bilateral(first)["metrics"]["mse"]);
  EXPECT_NE(again["metrics"]["mse"], wide_record["metrics"]["mse"]);
}

TEST(RunCommand, RecordedMetricsAreTheScoresOfTheWrittenImages) {
  test::TempDir dir;
  std::string out;
  nlohmann::json res;
  ASSERT_NO_FATAL_FAILURE(run_tiny(dir, out, res));
  double input_mse = -1;
  std::vector<double> method_mse;
  for (const auto& rec : res["records"]) {
    const std::string image = out + "/" + rec["files"]["image"].get<std::string>();
    const std::string ref = out + "/" + rec["reference"]["image"].get<std::string>();
    auto m = test::run_denoisebench_stdout("metrics '" + image + "' '" + ref + "' --json");
    ASSERT_EQ(m.exit_code, 0) << m.errors;
    const auto again = nlohmann::json::parse(m.output);
    // mse_converged too: the folder's reference.exr is the reference file itself, variance kept.
    for (const char* name : {"mse", "mse_hdr", "relmse", "psnr", "ssim", "flip", "mse_converged"}) {
      ASSERT_TRUE(rec["metrics"][name].is_number()) << rec["method"] << " " << name;
      const double stored = rec["metrics"][name].get<double>(), recomputed = again[name].get<double>();
      // The run scores the image in memory, the command reads the written EXR: float32 both, so
      // equal up to the last bits of the sums.
      EXPECT_NEAR(stored, recomputed, 1e-9 * std::max(1.0, std::abs(stored))) << rec["method"] << " " << name;
    }
    EXPECT_NE(rec["reference"]["seed"], rec["seed"]) << rec["method"];
    if (rec["role"] == "input") input_mse = rec["metrics"]["mse"].get<double>();
    if (rec["role"] == "method" || rec["role"] == "ablation") method_mse.push_back(rec["metrics"]["mse"].get<double>());
  }
  ASSERT_GT(input_mse, 0);
  ASSERT_EQ(method_mse.size(), 2u);
  for (double m : method_mse) EXPECT_LT(m, input_mse);
}

// The reference's samples are independent of the input's: the run records a
// reference seed other than the inputs' seed, and the reference in the folder is the one that
// seed renders, not the one the inputs' seed renders. (Rendering it with the inputs' seed would
// reuse the inputs' random numbers for its first samples: each input's error would then be
// partly the reference's, and every score too low.) Likewise the kept input frame is the render
// of the inputs' seed.
TEST(RunCommand, ReferenceIsRenderedWithItsOwnSeedAndTheInputWithTheInputsSeed) {
  test::TempDir dir;
  std::string out;
  nlohmann::json res;
  ASSERT_NO_FATAL_FAILURE(run_tiny(dir, out, res));
  nlohmann::json input;
  for (const auto& rec : res["records"])
    if (rec["role"] == "input") input = rec;
  ASSERT_TRUE(input.is_object()) << res.dump();
  const auto input_seed = input["seed"].get<std::uint64_t>(), ref_seed = input["reference"]["seed"].get<std::uint64_t>();
  ASSERT_NE(input_seed, ref_seed);

  const Image in_run = read_rgb(out + "/" + input["reference"]["image"].get<std::string>());
  ASSERT_EQ(in_run.width(), 32);
  // The reference command with the config's reference settings (kTinyConfig: 32x24, 16 spp in
  // blocks of 8) and either seed; its own cache, so it renders.
  auto reference_with = [&](std::uint64_t seed) {
    const std::string file = dir.file("ref_" + std::to_string(seed) + ".exr");
    auto c = test::run_denoisebench("reference cornell-box --size 32x24 --spp 16 --block-spp 8 --seed " +
                                    std::to_string(seed) + " --cache-dir '" + dir.file("refcache") + "' -o '" + file + "'");
    EXPECT_EQ(c.exit_code, 0) << c.output;
    return read_rgb(file);
  };
  // Bit for bit: a reference depends only on (scene, settings, block_spp) (tracer/reference.h).
  EXPECT_TRUE(in_run == reference_with(ref_seed)) << "the folder's reference is not the render of its recorded seed";
  const Image with_input_seed = reference_with(input_seed);
  ASSERT_EQ(with_input_seed.size(), in_run.size());
  std::size_t same = 0;
  for (std::size_t i = 0; i < in_run.size(); ++i) same += in_run.data()[i] == with_input_seed.data()[i];
  // Background and light pixels may agree whatever the seed; a reference drawn with the inputs'
  // seed agrees everywhere.
  EXPECT_LT(same, in_run.size() / 2) << "the folder's reference is the render of the inputs' seed";

  // The kept input frame is the 2 spp render of the inputs' seed.
  const std::string frame = out + "/" + input["files"]["frame"].get<std::string>();
  auto c = test::run_denoisebench("render cornell-box --size 32x24 --spp 2 --seed " + std::to_string(input_seed) + " -o '" +
                                  dir.file("input.exr") + "'");
  ASSERT_EQ(c.exit_code, 0) << c.output;
  EXPECT_TRUE(read_rgb(frame) == read_rgb(dir.file("input.exr")));
  EXPECT_TRUE(read_rgb(frame) == read_rgb(out + "/" + input["files"]["image"].get<std::string>()));
}

// The plain path-tracing curve is one progressive render: every point's record says
// so ("curve": the largest point's spp and its own), and its image is, bit for bit, what
// `render --spp N` writes with the record's seed and the config's size.
TEST(RunCommand, ThePlainCurveIsOneRenderWhosePointsAreTheRendersOfTheirSpp) {
  test::TempDir dir;
  std::string out;
  nlohmann::json res;
  ASSERT_NO_FATAL_FAILURE(run_tiny(dir, out, res));
  std::set<int> points;
  for (const auto& rec : res["records"]) {
    if (rec["role"] != "plain") {
      EXPECT_FALSE(rec.contains("curve")) << rec.dump();
      continue;
    }
    const int spp = rec["spp"].get<int>();
    points.insert(spp);
    ASSERT_TRUE(rec.contains("curve")) << rec.dump();
    EXPECT_EQ(rec["curve"]["rendered_spp"].get<int>(), 4);  // kTinyConfig: [speedup] spp = [1, 4]
    EXPECT_EQ(rec["curve"]["prefix_spp"].get<int>(), spp);
    const std::string file = dir.file("render_" + std::to_string(spp) + ".exr");
    auto c = test::run_denoisebench("render cornell-box --size 32x24 --spp " + std::to_string(spp) + " --seed " +
                                    std::to_string(rec["seed"].get<std::uint64_t>()) + " -o '" + file + "'");
    ASSERT_EQ(c.exit_code, 0) << c.output;
    EXPECT_TRUE(read_rgb(file) == read_rgb(out + "/" + rec["files"]["image"].get<std::string>())) << "spp " << spp;
  }
  EXPECT_EQ(points, (std::set<int>{1, 4}));
}

// A results folder re-scores alone: a config naming the folder's own input frame and reference
// by file (`[[scene]] frame = ..., reference = ...`) runs with exit 0, gives the rendered run's
// bilateral score, and `metrics` on the files it wrote agrees; a [[scene]] naming a missing
// file exits 2 naming the key and the file, before any work.
TEST(RunCommand, ASceneReadFromTheFolderOfAnotherRunGivesItsScores) {
  test::TempDir dir;
  write(dir.path() / "tiny.toml", kTinyConfig);
  auto r = run_in(dir, "run " + dir.file("tiny.toml") + " -o " + dir.file("out"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto res = nlohmann::json::parse(slurp(dir.file("out/results.json")));
  EXPECT_EQ(res["schema_version"], 4);
  nlohmann::json input, bilateral;
  for (const auto& rec : res["records"]) {
    if (rec["method"] == "input") input = rec;
    if (rec["method"] == "bilateral") bilateral = rec;
  }
  ASSERT_TRUE(input["files"].contains("frame")) << input.dump();
  write(dir.path() / "files.toml", "name = \"files\"\nmethods = [\"bilateral\"]\n[[scene]]\nframe = \"out/" +
                                       input["files"]["frame"].get<std::string>() + "\"\nreference = \"out/" +
                                       input["reference"]["image"].get<std::string>() + "\"\nlabel = \"again\"\n");
  r = run_in(dir, "run " + dir.file("files.toml") + " -o " + dir.file("again"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto again = nlohmann::json::parse(slurp(dir.file("again/results.json")));
  ASSERT_EQ(again["records"].size(), 2u);
  const auto& rec = again["records"][1];
  ASSERT_EQ(rec["method"], "bilateral");
  EXPECT_EQ(rec["scene"], "again");
  const double mse = rec["metrics"]["mse"].get<double>(), was = bilateral["metrics"]["mse"].get<double>();
  EXPECT_NEAR(mse, was, 1e-9 * was);
  auto m = test::run_denoisebench_stdout("metrics '" + dir.file("again/" + rec["files"]["image"].get<std::string>()) + "' '" +
                                         dir.file("again/" + rec["reference"]["image"].get<std::string>()) + "' --json");
  ASSERT_EQ(m.exit_code, 0) << m.errors;
  EXPECT_NEAR(nlohmann::json::parse(m.output)["mse_converged"].get<double>(), rec["metrics"]["mse_converged"].get<double>(),
              1e-9 * std::max(1.0, rec["metrics"]["mse_converged"].get<double>()));

  write(dir.path() / "missing.toml", "name = \"m\"\nmethods = [\"bilateral\"]\n[[scene]]\nframe = \"no/such.exr\"\n"
                                         "reference = \"out/" + input["reference"]["image"].get<std::string>() + "\"\n");
  r = run_in(dir, "run " + dir.file("missing.toml") + " -o " + dir.file("o3"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("missing.toml:4: key 'scene[0].frame'"));
  EXPECT_THAT(r.output, HasSubstr(dir.file("no/such.exr")));
  EXPECT_FALSE(fs::exists(dir.file("o3") + "/results.json"));
}

TEST(RunCommand, RefusesUnknownMethodsAndKeys) {
  test::TempDir dir;
  write(dir.path() / "bad_method.toml", std::regex_replace(kTinyConfig, std::regex("\"bilateral\"\\]"), "\"bilateral\", \"no_such_filter\"]"));
  auto r = run_in(dir, "run " + dir.file("bad_method.toml") + " -o " + dir.file("o1"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("no_such_filter"));
  EXPECT_THAT(r.output, HasSubstr("bad_method.toml"));
  write(dir.path() / "bad_key.toml", std::string(kTinyConfig) + "colour_space = \"srgb\"\n");
  r = run_in(dir, "run " + dir.file("bad_key.toml") + " -o " + dir.file("o2"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("colour_space"));
  EXPECT_FALSE(fs::exists(dir.file("o2") + "/results.json"));
}

TEST(ReportPage, LoadsInHeadlessChromiumWithEveryImage) {
  test::TempDir dir;
  write(dir.path() / "tiny.toml", kTinyConfig);
  const std::string out = dir.file("out");
  auto r = run_in(dir, "run " + dir.file("tiny.toml") + " -o " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = run_in(dir, "report " + out);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* f : {"table1_mse.md", "table2_time.md", "table2_filter_times.md", "speedup.md", "ablation.md",
                        "plots/mse_bars.png", "plots/mse_bars.pdf", "plots/error_time_cornell-box.png",
                        "web/viewer/viewer.js", "web/viewer/manifest.js", "index.html"})
    EXPECT_TRUE(fs::exists(out + "/" + f)) << f;

  // Every src/href of the page exists beside it (the page is opened from disk).
  const std::string html = slurp(out + "/index.html");
  std::regex ref_re(R"((?:src|href)=\"([^\"#]+)\")");
  int plots = 0, scripts = 0;
  for (auto it = std::sregex_iterator(html.begin(), html.end(), ref_re); it != std::sregex_iterator(); ++it) {
    const std::string ref = (*it)[1];
    if (ref.rfind("data:", 0) == 0 || ref.find('.') == std::string::npos) continue;
    EXPECT_TRUE(fs::exists(out + "/" + ref)) << ref;
    if (ref.size() > 4 && ref.substr(ref.size() - 4) == ".png") ++plots;
    if (ref.size() > 3 && ref.substr(ref.size() - 3) == ".js") ++scripts;
  }
  EXPECT_GE(plots, 4);  // the bars, and three plots of the one scene
  EXPECT_EQ(scripts, 2);  // the viewer's data and code

  if (!fs::exists("/usr/bin/chromium")) GTEST_SKIP() << "Debian's chromium is not installed (scripts/setup)";
  const fs::path shot = binary().parent_path() / "report_screenshot.png";
  fs::remove(shot);
  const std::string chromium =
      "/usr/bin/chromium --headless --no-sandbox --disable-gpu --disable-background-networking --no-first-run "
      "--disable-component-update --disable-sync --user-data-dir='" + dir.file("profile") +
      "' --enable-logging=stderr --v=0 --virtual-time-budget=5000 --window-size=1400,2400 --screenshot='" + shot.string() +
      "' 'file://" + out + "/index.html' 2>&1";
  auto c = test::run_command("timeout 120 " + chromium);
  ASSERT_EQ(c.exit_code, 0) << c.output;
  // Any console message is a failure: the page logs nothing unless something is wrong (a
  // script error, a missing file, the comparison component not defined).
  EXPECT_THAT(c.output, ::testing::Not(HasSubstr(":CONSOLE"))) << c.output;
  EXPECT_THAT(c.output, ::testing::Not(HasSubstr("ERR_FILE_NOT_FOUND"))) << c.output;
  ASSERT_TRUE(fs::exists(shot));
  EXPECT_GT(fs::file_size(shot), 10000u);
}

}  // namespace
}  // namespace dnb

namespace dnb {
namespace {

// Several input seeds: every input and method cell once per seed, each record with its seed and
// its own image, the inputs different from one another, and Table 1 with intervals.
TEST(RunCommand, SeveralSeedsGiveACellPerSeedAndTable1Intervals) {
  test::TempDir dir;
  std::string config = kTinyConfig;
  config.replace(config.find("spp = [2]"), 9, "spp = [2]\nseeds = [3, 4, 5]");
  write(dir.file("exp.toml"), config);
  auto r = run_in(dir, "run " + dir.file("exp.toml") + " -o " + dir.file("out"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto doc = nlohmann::json::parse(slurp(dir.file("out/results.json")));
  std::map<std::string, std::set<std::uint64_t>> seeds;
  std::set<std::string> images;
  for (const auto& rec : doc["records"]) {
    if (rec["role"] == "plain") continue;
    seeds[rec["method"].get<std::string>()].insert(rec["seed"].get<std::uint64_t>());
    images.insert(rec["files"]["image"].get<std::string>());
  }
  for (const char* m : {"input", "bilateral", "bilateral-wide"})
    EXPECT_EQ(seeds[m], (std::set<std::uint64_t>{3, 4, 5})) << m;
  EXPECT_EQ(images.size(), 9u);  // a file per seed, none overwritten
  const Image a = read_rgb(dir.file("out/images/cornell-box/input_2_s3.exr"));
  const Image b = read_rgb(dir.file("out/images/cornell-box/input_2_s4.exr"));
  EXPECT_FALSE(std::equal(a.data(), a.data() + a.size(), b.data())) << "two seeds gave the same input";
  ASSERT_EQ(run_in(dir, "report " + dir.file("out")).exit_code, 0);
  EXPECT_THAT(slurp(dir.file("out/table1_mse.md")), HasSubstr(" ± "));
  // Each method record says where it is worse than its input, and the report's table shows it.
  for (const auto& rec : doc["records"])
    if (rec["role"] == "method") {
      ASSERT_TRUE(rec.contains("blocks")) << rec.dump();
      EXPECT_EQ(rec["blocks"]["count"].get<int>(), 2 * 2);  // 32x24 in 16x16 tiles
      EXPECT_GE(rec["blocks"]["worse"].get<double>(), rec["blocks"]["worse_twice"].get<double>());
      // ... and which tiles: as many as the share says (4 tiles here, under the list's cap).
      const double worse = rec["blocks"]["worse"].get<double>();
      const std::size_t listed = rec.contains("worse_tiles") ? rec["worse_tiles"].size() : 0;
      EXPECT_EQ(listed, std::size_t(std::lround(worse * 4))) << rec.dump();
      if (listed) {
        EXPECT_GT(rec["worse_tiles"][0][4].get<double>(), 1.0) << rec.dump();
      }
    }
  EXPECT_THAT(slurp(dir.file("out/worse_blocks.md")), ::testing::ContainsRegex("[0-9.]+% \\([0-9.]+%\\)"));
}

// Two columns of the same method and parameters (here two variants with the same settings) are
// two cells: each computed, each record under its own name with its own image. Keyed without the
// column's name, the second reused the first's record and was listed under the first's name.
TEST(RunCommand, TwoColumnsWithTheSameSettingsAreTwoCells) {
  test::TempDir dir;
  const std::string config = std::string(kTinyConfig) +
                             "[[variant]]\nname = \"bilateral-wide-too\"\nmethod = \"bilateral\"\n"
                             "group = \"ablation\"\nset = { sigma_space = 6.0 }\n";
  write(dir.file("exp.toml"), config);
  auto r = run_in(dir, "run " + dir.file("exp.toml") + " -o " + dir.file("out"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto doc = nlohmann::json::parse(slurp(dir.file("out/results.json")));
  std::map<std::string, nlohmann::json> by_name;
  for (const auto& rec : doc["records"])
    if (rec["role"] != "plain") by_name[rec["method"].get<std::string>()] = rec;
  ASSERT_EQ(by_name.count("bilateral-wide"), 1u) << doc["records"].dump();
  ASSERT_EQ(by_name.count("bilateral-wide-too"), 1u) << doc["records"].dump();
  const auto& a = by_name["bilateral-wide"];
  const auto& b = by_name["bilateral-wide-too"];
  EXPECT_NE(a["cell_key"], b["cell_key"]);
  EXPECT_EQ(b["files"]["image"], "images/cornell-box/bilateral-wide-too_2.exr");
  EXPECT_TRUE(fs::exists(dir.file("out/" + b["files"]["image"].get<std::string>())));
  EXPECT_EQ(a["metrics"]["mse"], b["metrics"]["mse"]) << "the same filter on the same frame";
}

}  // namespace
}  // namespace dnb
