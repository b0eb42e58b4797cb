// The results folder is self-contained: a run keeps the AOV frames its cells read and
// the reference files themselves, so that re-scoring from the folder alone gives results.json's
// numbers; and a config can name a frame and a reference by file instead of rendering them.
// Each test runs a tiny experiment in-process (32x24, 2 spp, a 16 spp reference, one filter)
// with a render cache of its own.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <map>

#include "core/exr_io.h"
#include "core/hash.h"
#include "core/json_file.h"
#include "experiment/config.h"
#include "experiment/report.h"
#include "denoisers/method.h"
#include "experiment/runner.h"
#include "metrics/metrics.h"
#include "test_util.h"

namespace dnb::experiment {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const char* kRendered = R"(name = "tiny"
width = 32
height = 24
scenes = ["cornell-box"]
spp = [2]
methods = ["bilateral"]
[reference]
spp = 16
block_spp = 8
[timing]
repeats = 1
)";

ResultsDocument run(const test::TempDir& dir, const std::string& config_name, const std::string& text, const std::string& out) {
  test::write(dir.file(config_name), text);
  return run_experiment(load_config(dir.file(config_name)), {.out_dir = dir.file(out), .cache_dir = dir.file("cache")},
                        MethodRegistry::global());
}

const CellRecord& record(const ResultsDocument& d, const std::string& method) {
  const CellRecord* r = nullptr;
  for (const auto& rec : d.records)
    if (rec.method == method) r = &rec;
  if (!r) throw std::runtime_error("no record of " + method);
  return *r;
}

ino_t inode_of(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? st.st_ino : 0;
}

// The stored score and the file's agree to float rounding: the run scores the image in memory
// and score_files the EXR it wrote, both float32, so only the order of the double sums (the
// metrics' parallel reductions) may differ.
void expect_scores_equal(const CellRecord& rec, const metrics::FileScores& again) {
  for (const auto& [name, value] : again.values) {
    const auto stored = rec.metric(name);
    ASSERT_TRUE(stored) << rec.method << " " << name << " is null in results.json";
    EXPECT_NEAR(*stored, value, 1e-9 * std::max(1.0, std::abs(value))) << rec.method << " " << name;
  }
}

// [reference.scene.NAME] spp: that scene's reference is rendered with its own spp, every record
// says so, and the cells are keyed by it (a change reruns them; the render cache keeps the frames).
TEST(ResultsFolder, AScenesOwnReferenceSppIsRenderedRecordedAndKeyed) {
  test::TempDir dir;
  const ResultsDocument base = run(dir, "tiny.toml", kRendered, "out");
  const ResultsDocument d = run(dir, "more.toml", std::string(kRendered) + "[reference.scene.cornell-box]\nspp = 32\n", "out");
  EXPECT_EQ(d.config.reference_scene_spp, (std::map<std::string, int>{{"cornell-box", 32}}));
  for (const CellRecord& r : d.records) EXPECT_EQ(r.reference.spp, 32) << r.method;
  EXPECT_EQ(read_frame(dir.file("out") + "/" + d.records[0].reference.image, {layer::kColor}).meta.spp, 32);
  EXPECT_NE(record(d, "bilateral").cell_key, record(base, "bilateral").cell_key);
  // Twice the samples: about half the reference's own error (variance of the mean ~ 1 / spp).
  EXPECT_LT(record(d, "input").reference.estimated_error->at("mse_hdr"),
            0.75 * record(base, "input").reference.estimated_error->at("mse_hdr"));
}

TEST(ResultsFolder, RescoresAloneWithTheReferencesVarianceAndTheFramesTheCellsRead) {
  test::TempDir dir;
  const ResultsDocument d = run(dir, "tiny.toml", kRendered, "out");
  const std::string out = dir.file("out");
  const CellRecord& input = record(d, "input");
  const std::string ref_path = out + "/" + input.reference.image;

  // The folder's reference.exr is the cached reference itself: variance and metadata kept.
  const AovFrame ref = read_frame(ref_path, {layer::kColor, layer::kVariance});
  EXPECT_EQ(ref.meta.spp, 16);
  for (const CellRecord& rec : d.records) {
    const metrics::FileScores again = metrics::score_files(out + "/" + rec.image(), ref_path);
    EXPECT_TRUE(again.has_variance);
    expect_scores_equal(rec, again);
    EXPECT_TRUE(rec.metric("mse_converged")) << rec.method;
  }

  // The input record names the frame file every cell read, byte for byte the cached render (a
  // hard link here: one file system), with its edge file; its colour scores as the input did.
  ASSERT_EQ(input.file("frame"), "frames/cornell-box/input_2.exr");
  ASSERT_EQ(input.file("frame_edges"), "frames/cornell-box/input_2.edges.exr");
  const std::string frame = out + "/" + input.file("frame");
  const AovFrame f = read_frame(frame, {layer::kColor, layer::kDirect, layer::kNormal});
  EXPECT_EQ(f.meta.spp, 2);
  EXPECT_TRUE(f.edges);
  EXPECT_EQ(fs::hard_link_count(frame), 2u) << "linked to the render cache's frame.exr, not copied";
  expect_scores_equal(input, metrics::score_files(frame, ref_path));
  EXPECT_EQ(record(d, "bilateral").file("frame"), "") << "the frame is named once, by the input record";

  // A resumed run neither copies again nor duplicates: the same inodes, the same files.
  const ino_t frame_inode = inode_of(frame), ref_inode = inode_of(ref_path);
  std::vector<std::string> before;
  for (const auto& e : fs::recursive_directory_iterator(out)) before.push_back(e.path().string());
  const auto image_time = fs::last_write_time(out + "/" + record(d, "bilateral").image());
  run(dir, "tiny.toml", kRendered, "out");
  std::vector<std::string> after;
  for (const auto& e : fs::recursive_directory_iterator(out)) after.push_back(e.path().string());
  std::sort(before.begin(), before.end());
  std::sort(after.begin(), after.end());
  EXPECT_EQ(after, before);
  EXPECT_EQ(inode_of(frame), frame_inode);
  EXPECT_EQ(inode_of(ref_path), ref_inode);
  EXPECT_EQ(fs::hard_link_count(frame), 2u);
  EXPECT_EQ(fs::last_write_time(out + "/" + record(d, "bilateral").image()), image_time);
}

// A folder written before the frames were kept (schema 3: no files.frame, an RGB-only
// reference.exr) gets both on its next run, without recomputing its method cells.
TEST(ResultsFolder, AnOlderFolderGetsItsFramesAndFullReferenceOnResume) {
  test::TempDir dir;
  const ResultsDocument d = run(dir, "tiny.toml", kRendered, "out");
  const std::string out = dir.file("out");
  for (const char* name : {"results.json", "finished_cells.json"}) {
    nlohmann::json j = json_file::read(out + "/" + name);
    j["schema_version"] = 3;
    for (auto& r : j["records"]) r["files"].erase("frame"), r["files"].erase("frame_edges");
    json_file::write(out + "/" + name, j);
  }
  fs::remove_all(out + "/frames");
  const std::string ref_path = out + "/" + record(d, "input").reference.image;
  write_rgb(read_rgb(ref_path), ref_path);  // what the folder's reference.exr used to be
  ASSERT_FALSE(metrics::score_files(out + "/" + record(d, "bilateral").image(), ref_path).has_variance);
  const auto image_time = fs::last_write_time(out + "/" + record(d, "bilateral").image());

  const ResultsDocument again = run(dir, "tiny.toml", kRendered, "out");
  EXPECT_EQ(record(again, "input").file("frame"), "frames/cornell-box/input_2.exr");
  EXPECT_TRUE(fs::exists(out + "/frames/cornell-box/input_2.exr"));
  EXPECT_TRUE(metrics::score_files(out + "/" + record(d, "bilateral").image(), ref_path).has_variance);
  EXPECT_EQ(fs::last_write_time(out + "/" + record(d, "bilateral").image()), image_time) << "a method cell was recomputed";
  EXPECT_EQ(record(again, "bilateral").cell_key, record(d, "bilateral").cell_key);
}

// A scene read from files: the folder's own frame and reference, named by a config, give the
// rendered run's filter scores; the renderer-type method is skipped with its reason; editing a
// file reruns the cells keyed by it, and nothing else does.
TEST(ResultsFolder, ASceneReadFromFilesIsScoredAgainstItsReferenceFile) {
  test::TempDir dir;
  const ResultsDocument rendered = run(dir, "tiny.toml", kRendered, "out");
  fs::create_directories(dir.path() / "mine");
  fs::copy_file(dir.file("out/frames/cornell-box/input_2.exr"), dir.file("mine/in.exr"));
  fs::copy_file(dir.file("out/frames/cornell-box/input_2.edges.exr"), dir.file("mine/in.edges.exr"));
  fs::copy_file(dir.file("out/images/cornell-box/reference.exr"), dir.file("mine/ref.exr"));
  const std::string config = R"(name = "files"
methods = ["bilateral", "irradiance_cache"]
[timing]
repeats = 1
[[scene]]
frame = "mine/in.exr"
reference = "mine/ref.exr"
label = "box"
)";
  const ResultsDocument d = run(dir, "files.toml", config, "files");
  ASSERT_EQ(d.records.size(), 2u);  // the input and bilateral: no plain curve, no irradiance cache
  for (const char* m : {"input", "bilateral"}) {
    const CellRecord& r = record(d, m);
    EXPECT_EQ(r.scene, "box");
    EXPECT_EQ(r.spp, 2);
    EXPECT_FALSE(r.seed);
    EXPECT_EQ(r.reference.spp, 16);
    // The same frame and reference as the rendered run's: the same scores, to float rounding.
    for (const auto& [name, v] : record(rendered, m).metrics)
      EXPECT_NEAR(*r.metric(name), *v, 1e-9 * std::max(1.0, std::abs(*v))) << m << " " << name;
  }
  ASSERT_EQ(d.skipped.size(), 1u);
  EXPECT_EQ(d.skipped[0].method, "irradiance_cache");
  EXPECT_THAT(d.skipped[0].reason, HasSubstr("read from files"));
  EXPECT_TRUE(d.failures.empty());
  // Table 1 (drawn at the file scene's spp, the config having no rendered one) says so.
  const Table t = table1(d, "mse");
  ASSERT_EQ(t.rows.size(), 1u);
  ASSERT_EQ(t.header, (std::vector<std::string>{"scene", "bilateral", "irradiance_cache", "input (2 spp)",
                                                 "reference's own (est.)"}));
  EXPECT_NE(t.rows[0].back(), "n/a");  // the reference file has variance.R/G/B: its own error is estimated
  EXPECT_EQ(t.rows[0][0], "box");
  EXPECT_EQ(t.rows[0][2], "skipped");
  EXPECT_EQ(d.config.scene_files.at("box").frame, dir.file("mine/in.exr"));
  EXPECT_EQ(sha256_file(dir.file("files/frames/box/input_2.exr")), sha256_file(dir.file("mine/in.exr")));
  EXPECT_EQ(sha256_file(dir.file("files/images/box/reference.exr")), sha256_file(dir.file("mine/ref.exr")));

  // Unchanged files: every cell reused. An edited reference: every cell scored again.
  const std::string bilateral_key = record(d, "bilateral").cell_key;
  EXPECT_EQ(record(run(dir, "files.toml", config, "files"), "bilateral").cell_key, bilateral_key);
  AovFrame ref = read_frame(dir.file("mine/ref.exr"));
  ref.layer(layer::kColor).data()[0] += 1.0f;
  write_frame(ref, dir.file("mine/ref.exr"));
  const ResultsDocument edited = run(dir, "files.toml", config, "files");
  EXPECT_NE(record(edited, "bilateral").cell_key, bilateral_key);
  EXPECT_NE(record(edited, "input").cell_key, record(d, "input").cell_key);
  EXPECT_NE(record(edited, "input").metric("mse_hdr"), record(d, "input").metric("mse_hdr"));
  EXPECT_EQ(sha256_file(dir.file("files/images/box/reference.exr")), sha256_file(dir.file("mine/ref.exr")))
      << "the folder's reference is the edited file";
  // An edited frame (its edge sub-pixels, rewritten with it): the frame's cells again.
  const std::string edited_key = record(edited, "bilateral").cell_key;
  AovFrame frame = read_frame(dir.file("mine/in.exr"));
  frame.edges->samples[0].depth += 1.0f;
  write_frame(frame, dir.file("mine/in.exr"));
  EXPECT_NE(record(run(dir, "files.toml", config, "files"), "bilateral").cell_key, edited_key);
}

}  // namespace
}  // namespace dnb::experiment
