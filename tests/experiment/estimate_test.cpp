// `run --estimate` (experiment/estimate.h): the plan it prices is the run's (every cell and render
// counted), what the render cache and the results folder hold is counted as held and costs
// nothing, nothing is written into either, and --ranks divides the parallel part. Its accuracy
// is measured against real runs (docs/estimate.md), never timed in a test.
#include <gtest/gtest.h>

#include <filesystem>

#include "denoisers/method.h"
#include "experiment/config.h"
#include "experiment/estimate.h"
#include "experiment/runner.h"
#include "test_util.h"

namespace dnb::experiment {
namespace {

namespace fs = std::filesystem;

const char* kTiny = R"(name = "tiny"
width = 32
height = 24
scenes = ["cornell-box"]
seeds = [1, 2]
spp = [2]
methods = ["bilateral", "atrous"]
[reference]
spp = 16
block_spp = 8
[speedup]
spp = [1, 2]
[timing]
repeats = 1
)";

std::size_t files_under(const fs::path& p) {
  std::error_code ec;
  if (!fs::exists(p, ec)) return 0;
  std::size_t n = 0;
  for (const auto& e : fs::recursive_directory_iterator(p)) n += e.is_regular_file();
  return n;
}

TEST(Estimate, CountsThePlanAndWhatIsHeldAndWritesNothing) {
  test::TempDir dir;
  test::write(dir.file("tiny.toml"), kTiny);
  const ExperimentConfig c = load_config(dir.file("tiny.toml"));
  const RunOptions opt{.out_dir = dir.file("out"), .cache_dir = dir.file("cache")};

  const RunEstimate cold = estimate_run(c, opt, MethodRegistry::global());
  ASSERT_EQ(cold.scenes.size(), 1u);
  const SceneEstimate& s = cold.scenes[0];
  EXPECT_EQ(s.reference.items, 1);
  EXPECT_EQ(s.inputs.items, 2);   // one input frame per seed
  EXPECT_EQ(s.curve.items, 2);    // the plain curve's points
  EXPECT_EQ(s.methods.items, 4);  // two methods per input
  EXPECT_EQ(s.reference.held + s.inputs.held + s.curve.held + s.methods.held, 0);
  for (const StageEstimate* st : {&s.reference, &s.inputs, &s.curve, &s.methods}) EXPECT_GT(st->seconds, 0);
  EXPECT_EQ(s.method_cell_seconds.size(), 2u);
  EXPECT_NEAR(cold.one_process_seconds, s.total(), 1e-12);
  EXPECT_EQ(files_under(dir.file("out")) + files_under(dir.file("cache")), 0u) << "the estimate wrote nothing";

  // N ranks: the references and cells are shared, the loads are not, and no run is shorter than
  // its longest group of cells.
  EXPECT_LT(cold.with_ranks(4), cold.one_process_seconds);
  EXPECT_GE(cold.with_ranks(4), cold.load_seconds + cold.longest_group_seconds);
  EXPECT_LE(cold.with_ranks(1000), cold.with_ranks(4));
  EXPECT_GT(cold.longest_group_seconds, 0);
  EXPECT_NE(cold.text({4}).find("with 4 ranks"), std::string::npos);

  // After the run, everything is held: nothing left to render or compute.
  (void)run_experiment(c, opt, MethodRegistry::global());
  const RunEstimate warm = estimate_run(c, opt, MethodRegistry::global());
  const SceneEstimate& w = warm.scenes[0];
  EXPECT_EQ(w.reference.held, 1);
  EXPECT_EQ(w.inputs.held, 2);
  EXPECT_EQ(w.curve.held, 2);
  EXPECT_EQ(w.methods.held, 4);
  EXPECT_EQ(w.reference.seconds + w.inputs.seconds + w.curve.seconds + w.methods.seconds, 0.0);

  // A new results folder with the same cache: the renders are held (read, not rendered), the
  // cells are not.
  const RunEstimate fresh = estimate_run(c, {.out_dir = dir.file("out2"), .cache_dir = dir.file("cache")},
                                         MethodRegistry::global());
  const SceneEstimate& f = fresh.scenes[0];
  EXPECT_EQ(f.reference.held, 1);
  EXPECT_EQ(f.reference.seconds, 0.0);
  EXPECT_EQ(f.inputs.held, 0);
  EXPECT_EQ(f.methods.held, 0);
  EXPECT_GT(f.methods.seconds, 0);
  EXPECT_GT(f.inputs.seconds, 0) << "the input cells are computed again (their frames read from the cache)";
}

// A sequence (docs/sequences.md) is priced frame by frame with its first frame's probe: a
// reference and an input per frame (and spp and seed), no plain curve, every method on every
// frame; after the run all of it is held (its frames keyed as the run keys them).
TEST(Estimate, ASequenceCountsEveryFrameAndWhatIsHeld) {
  test::TempDir dir;
  test::write(dir.file("slide.toml"), test::slurp(test::source_dir() + "/tests/data/slide-sequence.toml"));
  test::write(dir.file("seq.toml"), "name = \"seq\"\nwidth = 32\nheight = 24\nseeds = [1]\nspp = [2]\nmethods = "
                                    "[\"atrous\", \"temporal_accumulation\"]\n[[scene]]\nname = \"" + dir.file("slide.toml") +
                                        "\"\nframes = 3\n[reference]\nspp = 16\nblock_spp = 8\n[timing]\nrepeats = 1\n");
  const ExperimentConfig c = load_config(dir.file("seq.toml"));
  const RunOptions opt{.out_dir = dir.file("out"), .cache_dir = dir.file("cache")};
  const RunEstimate cold = estimate_run(c, opt, MethodRegistry::global());
  ASSERT_EQ(cold.scenes.size(), 1u);
  const SceneEstimate& s = cold.scenes[0];
  EXPECT_TRUE(s.estimated) << s.why_not;
  EXPECT_EQ(s.reference.items, 3);
  EXPECT_EQ(s.inputs.items, 3);
  EXPECT_EQ(s.curve.items, 0);
  EXPECT_EQ(s.methods.items, 6);
  EXPECT_GT(s.reference.seconds, 0);
  EXPECT_EQ(files_under(dir.file("out")) + files_under(dir.file("cache")), 0u) << "the estimate wrote nothing";
  (void)run_experiment(c, opt, MethodRegistry::global());
  const RunEstimate warm = estimate_run(c, opt, MethodRegistry::global());
  const SceneEstimate& w = warm.scenes[0];
  EXPECT_EQ(w.reference.held, 3);
  EXPECT_EQ(w.inputs.held, 3);
  EXPECT_EQ(w.methods.held, 6);
  EXPECT_EQ(w.reference.seconds + w.inputs.seconds + w.methods.seconds, 0.0);
}

}  // namespace
}  // namespace dnb::experiment
