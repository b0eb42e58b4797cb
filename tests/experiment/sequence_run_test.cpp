// Sequences in a run (docs/sequences.md): an animated scene's frames are rows of their own, a
// temporal method gets them in order from one instance per (column, spp, seed) and starts afresh
// for each sequence, a run resumed mid-sequence replays the history and gives the uninterrupted
// run's images, and results.json holds the sequence scores the tables show. Each test runs a
// tiny sequence in-process (3 or 4 frames at 32x24, 2 spp, a 16 spp reference).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <mutex>
#include <string>
#include <vector>

#include "core/errors.h"
#include "core/exr_io.h"
#include "denoisers/method.h"
#include "experiment/config.h"
#include "experiment/report.h"
#include "experiment/runner.h"
#include "test_util.h"

namespace dnb::experiment {
namespace {

using ::testing::HasSubstr;

// What the recording temporal method saw: (sequence, index, whether it had a previous frame,
// whether its own history was fresh) per call, in call order.
struct Seen {
  std::string sequence;
  int index;
  bool previous;
  int calls_before;  // frames this instance had seen before this one (since its last reset)
};
std::mutex seen_mutex;
std::vector<Seen> seen;

// A temporal method that records its calls and returns the colour: so that the test sees the
// order and the resets the harness gives it.
class Recorder : public Method {
 public:
  std::vector<std::string> required_layers() const override { return {layer::kColor}; }
  bool temporal() const override { return true; }
  void reset() override { count_ = 0; }
  MethodResult execute(const MethodInput& in) override {
    if (!in.sequence || in.sequence->index == 0 || in.sequence->sequence != last_) count_ = 0;
    {
      std::lock_guard lock(seen_mutex);
      seen.push_back({in.sequence ? in.sequence->sequence : "", in.sequence ? in.sequence->index : -1,
                      in.sequence && in.sequence->previous, count_});
    }
    if (in.sequence) last_ = in.sequence->sequence;
    ++count_;
    MethodResult r;
    r.image = in.frame->layer(layer::kColor);
    return r;
  }

 private:
  int count_ = 0;
  std::string last_;
};

void register_recorder() {
  if (MethodRegistry::global().contains("test_recorder")) return;
  MethodInfo info;
  info.name = "test_recorder";
  info.description = "records the frames it is given (tests)";
  info.temporal = true;
  info.create = [](const Params&) { return std::make_unique<Recorder>(); };
  MethodRegistry::global().add(info);
}


// tests/data/slide-sequence.toml copied into the test's folder (four frames: the camera slides
// right while a box slides across a textured wall).
std::string scene_file(const test::TempDir& dir) {
  test::write(dir.file("slide.toml"), test::slurp(test::source_dir() + "/tests/data/slide-sequence.toml"));
  return dir.file("slide.toml");
}

std::string config(const std::string& scene_path, int frames, const std::string& methods, const std::string& seeds = "[1]") {
  return "name = \"seq\"\nwidth = 32\nheight = 24\nseeds = " + seeds + "\nspp = [2]\nmethods = " + methods +
         "\n[[scene]]\nname = \"" + scene_path + "\"\nframes = " + std::to_string(frames) +
         "\n[reference]\nspp = 16\nblock_spp = 8\n[timing]\nrepeats = 1\n";
}

ResultsDocument run(const test::TempDir& dir, const std::string& text, const std::string& out) {
  test::write(dir.file(out + ".toml"), text);
  return run_experiment(load_config(dir.file(out + ".toml")), {.out_dir = dir.file(out), .cache_dir = dir.file("cache")},
                        MethodRegistry::global());
}

TEST(SequenceRun, FramesAreRowsAndTheSequenceIsScored) {
  test::TempDir dir;
  const std::string scene = scene_file(dir);
  const ResultsDocument d = run(dir, config(scene, 3, R"(["atrous", "temporal_accumulation"])"), "out");
  ASSERT_EQ(d.config.sequences.count(scene), 1u);
  EXPECT_EQ(d.config.sequences.at(scene), 3);
  EXPECT_EQ(d.config.scenes, (std::vector<std::string>{sequence_row(scene, 0), sequence_row(scene, 1), sequence_row(scene, 2)}));
  // Every frame's cells (input and two methods), no plain curve.
  EXPECT_EQ(d.records.size(), 9u);
  for (const auto& r : d.records) EXPECT_NE(r.role, Role::Plain);
  // The input frames carry the motion layer; frame 0's is zero, later ones are not.
  for (int t = 0; t < 3; ++t) {
    const CellRecord* in = d.find(sequence_row(scene, t), "input", 2);
    ASSERT_NE(in, nullptr);
    const AovFrame f = read_frame(dir.file("out/" + in->file("frame")), {layer::kMotion});
    double sum = 0;
    const Image& m = f.layer(layer::kMotion);
    for (std::size_t i = 0; i < m.size(); ++i) sum += std::abs(m.data()[i]);
    if (t == 0) EXPECT_EQ(sum, 0.0);
    else EXPECT_GT(sum, 0.0);
  }
  // A sequence record per column, with finite temporal metrics and a value per frame.
  ASSERT_EQ(d.sequences.size(), 3u);
  for (const auto& s : d.sequences) {
    EXPECT_EQ(s.frames, 3);
    ASSERT_TRUE(s.metric("tmse")) << s.method;
    EXPECT_GE(*s.metric("tmse"), 0.0);
    ASSERT_TRUE(s.metric("mse"));
    // The mean of the frames' records' mse.
    double mean = 0;
    for (int t = 0; t < 3; ++t) mean += *d.find(sequence_row(scene, t), s.method, 2)->metric("mse") / 3;
    EXPECT_NEAR(*s.metric("mse"), mean, 1e-9 * mean);
    ASSERT_EQ(s.per_frame.at("tmse").size(), 3u);
    EXPECT_FALSE(s.per_frame.at("tmse")[0]);  // frame 0 has no previous frame
    EXPECT_TRUE(s.per_frame.at("tmse")[1]);
    EXPECT_EQ(s.images.size(), 3u);
  }
  // The tables show them: a row per metric.
  const Table t = sequence_table(d);
  ASSERT_EQ(t.rows.size(), 3u);
  EXPECT_EQ(t.rows[1][2], "tmse");
  EXPECT_THAT(t.header, ::testing::Contains("temporal_accumulation"));
  // results.json reads back with them.
  const ResultsDocument back = ResultsDocument::load(dir.file("out/results.json"));
  ASSERT_EQ(back.sequences.size(), 3u);
  EXPECT_EQ(back.sequences[0].per_frame, d.sequences[0].per_frame);
  EXPECT_EQ(back.config.sequences, d.config.sequences);
}

TEST(SequenceRun, ATemporalMethodGetsTheFramesInOrderAndStartsAfreshPerSequence) {
  register_recorder();
  test::TempDir dir;
  const std::string scene = scene_file(dir);
  {
    std::lock_guard lock(seen_mutex);
    seen.clear();
  }
  run(dir, config(scene, 3, R"(["test_recorder"])", "[1, 2]"), "out");
  std::lock_guard lock(seen_mutex);
  // Frames in order per seed: (seed 1: 0) (seed 2: 0) (seed 1: 1) (seed 2: 1) ...: the run visits
  // a frame's seeds before the next frame; each seed is its own sequence with its own history.
  ASSERT_EQ(seen.size(), 6u);
  std::map<std::string, std::vector<int>> order;
  for (const auto& s : seen) {
    order[s.sequence].push_back(s.index);
    EXPECT_EQ(s.calls_before, s.index) << "the instance saw every earlier frame of its sequence, and only those";
    EXPECT_EQ(s.previous, s.index > 0);
  }
  ASSERT_EQ(order.size(), 2u) << "one sequence per seed";
  for (const auto& [name, indices] : order) EXPECT_EQ(indices, (std::vector<int>{0, 1, 2})) << name;
}

TEST(SequenceRun, AResumedSequenceReplaysTheHistoryAndGivesTheSameImages) {
  test::TempDir dir;
  const std::string scene = scene_file(dir);
  const std::string methods = R"(["temporal_accumulation"])";
  // Uninterrupted: four frames in one run.
  const ResultsDocument whole = run(dir, config(scene, 4, methods), "whole");
  // Interrupted: two frames, then the same folder with four: frames 2 and 3 of the temporal
  // method start from a replay of frames 0 and 1.
  const ResultsDocument first = run(dir, config(scene, 2, methods), "resumed");
  const ResultsDocument resumed = run(dir, config(scene, 4, methods), "resumed");
  for (int t = 0; t < 4; ++t) {
    const CellRecord* a = whole.find(sequence_row(scene, t), "temporal_accumulation", 2);
    const CellRecord* b = resumed.find(sequence_row(scene, t), "temporal_accumulation", 2);
    ASSERT_TRUE(a && b);
    EXPECT_EQ(a->cell_key, b->cell_key) << "frame " << t << ": a frame's cell does not depend on the sequence's length";
    EXPECT_TRUE(read_rgb(dir.file("whole/" + a->image())) == read_rgb(dir.file("resumed/" + b->image())))
        << "frame " << t << " after the replay";
  }
  ASSERT_EQ(resumed.sequences.size(), 2u);
  EXPECT_EQ(resumed.sequences[1].frames, 4);
}

TEST(SequenceRun, AConfigsFramesMustFitAnAnimatedScene) {
  test::TempDir dir;
  const std::string scene = scene_file(dir);
  auto refused = [&](const std::string& text) {
    test::write(dir.file("bad.toml"), text);
    return test::error_of<InputError>([&] { load_config(dir.file("bad.toml")); });
  };
  EXPECT_THAT(refused(config(scene, 5, R"(["atrous"])")), HasSubstr("5 frames asked"));
  EXPECT_THAT(refused(config("cornell-box", 2, R"(["atrous"])")), HasSubstr("still"));
  EXPECT_THAT(refused(config(scene, 0, R"(["atrous"])")), HasSubstr("frames"));
}

}  // namespace
}  // namespace dnb::experiment
