// References: the block driver (fixed-order reduction, checkpoints, resume, refusal of foreign
// checkpoints, convergence log) tested with synthetic sums, so that every property is checked
// independently of the tracer.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "core/errors.h"
#include "test_util.h"
#include "tracer/reference.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;

// A synthetic "tracer": sample s of pixel-channel i is a uniform [0, 1) number from a hash of
// (s, i), so the sums of a range depend only on the range, like render_color_sums.
double synthetic_sample(std::uint64_t s, std::uint64_t i) {
  std::uint64_t z = s * 0x9E3779B97F4A7C15ull + i * 0xBF58476D1CE4E5B9ull + 0x94D049BB133111EBull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return double(z >> 11) * 0x1.0p-53;
}

struct Synthetic {
  int width = 12, height = 8;
  int calls = 0;
  int fail_after = -1;  // throw on this call (a crash mid-render)
  ColorSums operator()(int begin, int end, const std::function<void(std::int64_t)>& on_progress) {
    if (fail_after >= 0 && calls >= fail_after) throw WorkError("synthetic crash");
    ++calls;
    ColorSums s;
    s.width = width;
    s.height = height;
    s.samples = end - begin;
    s.sum.assign(std::size_t(width) * height * 3, 0.0);
    s.group_sum.assign(s.sum.size() * kSampleGroups, 0.0);
    // Groups as the tracer takes them (render.h): sample k in group k mod kSampleGroups.
    for (int k = begin; k < end; ++k) {
      const int g = k % kSampleGroups;
      ++s.group_samples[g];
      for (std::size_t i = 0; i < s.sum.size(); ++i) {
        const double v = synthetic_sample(std::uint64_t(k), i);
        s.sum[i] += v;
        s.group_sum[(i / 3 * kSampleGroups + std::size_t(g)) * 3 + i % 3] += v;
      }
    }
    if (on_progress) on_progress(std::int64_t(end - begin) * width * height);
    return s;
  }
  BlockRenderer renderer() {
    return [this](int b, int e, const std::function<void(std::int64_t)>& p) { return (*this)(b, e, p); };
  }
};

BlockJob small_job(const std::string& checkpoint = "") {
  BlockJob job;
  job.width = 12;
  job.height = 8;
  job.spp = 100;
  job.block_spp = 16;  // 7 blocks, the last one of 4 samples
  job.identity = "test\nspp=100\nblock_spp=16\n";
  job.checkpoint_path = checkpoint;
  return job;
}

bool bit_identical(const ColorSums& a, const ColorSums& b) {
  return a.width == b.width && a.height == b.height && a.samples == b.samples &&
         std::equal(a.group_samples, a.group_samples + kSampleGroups, b.group_samples) && a.dropped == b.dropped &&
         a.sum.size() == b.sum.size() && a.group_sum.size() == b.group_sum.size() &&
         std::memcmp(a.sum.data(), b.sum.data(), a.sum.size() * sizeof(double)) == 0 &&
         std::memcmp(a.group_sum.data(), b.group_sum.data(), a.group_sum.size() * sizeof(double)) == 0;
}

TEST(ReferenceBlocks, FoldsBlocksInOrder) {
  Synthetic synth;
  BlockResult r = accumulate_blocks(small_job(), synth.renderer());
  EXPECT_EQ(r.blocks_rendered, 7);
  EXPECT_EQ(r.blocks_resumed, 0);
  EXPECT_EQ(r.sums.samples, 100);
  ASSERT_EQ(r.convergence.size(), 7u);
  EXPECT_EQ(r.convergence.back().spp, 100);
  // The same left fold written out by hand.
  Synthetic again;
  ColorSums expected = again(0, 16, nullptr);
  for (int b = 1; b < 7; ++b) add_block(expected, again(b * 16, std::min(100, b * 16 + 16), nullptr));
  EXPECT_TRUE(bit_identical(r.sums, expected));
}

TEST(ReferenceBlocks, RejectsBlocksOfTheWrongShape) {
  BlockRenderer wrong = [](int b, int e, const std::function<void(std::int64_t)>&) {
    Synthetic s;
    s.width = 5;
    return s(b, e, nullptr);
  };
  EXPECT_THROW(accumulate_blocks(small_job(), wrong), WorkError);
}

TEST(ReferenceBlocks, InterruptedRenderResumesBitIdentical) {
  test::TempDir tmp;
  const std::string ck = tmp.file("ckpt/reference.ckpt");
  Synthetic whole;
  BlockResult uninterrupted = accumulate_blocks(small_job(), whole.renderer());

  // A crash during the fourth block: three blocks are in the checkpoint.
  Synthetic crashing;
  crashing.fail_after = 3;
  EXPECT_THROW(accumulate_blocks(small_job(ck), crashing.renderer()), WorkError);
  std::string damage;
  auto saved = read_checkpoint(ck, &damage);
  ASSERT_TRUE(saved) << damage;
  EXPECT_EQ(saved->blocks_done, 3);
  EXPECT_EQ(saved->sums.samples, 48);

  Synthetic resumed_renderer;
  BlockResult resumed = accumulate_blocks(small_job(ck), resumed_renderer.renderer());
  EXPECT_EQ(resumed.blocks_resumed, 3);
  EXPECT_EQ(resumed.blocks_rendered, 4);
  EXPECT_EQ(resumed_renderer.calls, 4);
  EXPECT_TRUE(bit_identical(resumed.sums, uninterrupted.sums));
  // The convergence log spans both sessions.
  ASSERT_EQ(resumed.convergence.size(), 7u);
  EXPECT_EQ(resumed.convergence[2].spp, 48);
}

TEST(ReferenceBlocks, FinishedCheckpointRendersNothing) {
  test::TempDir tmp;
  const std::string ck = tmp.file("reference.ckpt");
  Synthetic first;
  BlockResult a = accumulate_blocks(small_job(ck), first.renderer());
  Synthetic second;
  BlockResult b = accumulate_blocks(small_job(ck), second.renderer());
  EXPECT_EQ(second.calls, 0);
  EXPECT_TRUE(bit_identical(a.sums, b.sums));
}

TEST(ReferenceBlocks, CheckpointOfOtherArgumentsIsRefused) {
  test::TempDir tmp;
  const std::string ck = tmp.file("reference.ckpt");
  Synthetic crashing;
  crashing.fail_after = 2;
  EXPECT_THROW(accumulate_blocks(small_job(ck), crashing.renderer()), WorkError);
  BlockJob other = small_job(ck);
  other.identity = "test\nspp=200\nblock_spp=16\n";
  Synthetic synth;
  try {
    accumulate_blocks(other, synth.renderer());
    FAIL() << "a checkpoint of other arguments was accepted";
  } catch (const InputError& e) {
    std::string msg = e.what();
    EXPECT_NE(msg.find("different reference"), std::string::npos) << msg;
    EXPECT_NE(msg.find("spp=100"), std::string::npos) << msg;
    EXPECT_NE(msg.find("spp=200"), std::string::npos) << msg;
  }
  EXPECT_EQ(synth.calls, 0);
}

class DamagedCheckpoint : public ::testing::Test {
 protected:
  void SetUp() override {
    Synthetic crashing;
    crashing.fail_after = 4;
    EXPECT_THROW(accumulate_blocks(small_job(ck), crashing.renderer()), WorkError);
    ASSERT_TRUE(read_checkpoint(ck));
  }
  // The damaged checkpoint is detected, ignored, and the render starts over to the same result.
  void expect_detected_and_restarted(const std::string& expected_reason) {
    std::string damage;
    EXPECT_FALSE(read_checkpoint(ck, &damage));
    EXPECT_NE(damage.find(expected_reason), std::string::npos) << damage;
    Synthetic synth;
    BlockResult r = accumulate_blocks(small_job(ck), synth.renderer());
    EXPECT_EQ(r.blocks_resumed, 0);
    EXPECT_EQ(synth.calls, 7);
    Synthetic whole;
    EXPECT_TRUE(bit_identical(r.sums, accumulate_blocks(small_job(), whole.renderer()).sums));
  }
  test::TempDir tmp;
  std::string ck = tmp.file("reference.ckpt");
};

TEST_F(DamagedCheckpoint, TruncatedPayload) {
  fs::resize_file(ck, fs::file_size(ck) - 8);
  expect_detected_and_restarted("truncated");
}

TEST_F(DamagedCheckpoint, TruncatedHeader) {
  fs::resize_file(ck, 30);
  expect_detected_and_restarted("truncated");
}

TEST_F(DamagedCheckpoint, FlippedPayloadByte) {
  {
    std::fstream f(ck, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(std::streamoff(fs::file_size(ck) - 100));
    f.put('\x5a');
  }
  expect_detected_and_restarted("checksum");
}

TEST(ReferenceCheckpoint, RoundTripIsExact) {
  test::TempDir tmp;
  Synthetic synth;
  Checkpoint ck;
  ck.identity = "id\n";
  ck.blocks_done = 2;
  ck.sums = synth(0, 32, nullptr);
  ck.sums.dropped = 3;
  ck.convergence = {{16, 1.5, 0.1, 0.01}, {32, 3.0, NAN, 0.005}};
  ck.seconds = 3.25;
  write_checkpoint(tmp.file("c.ckpt"), ck);
  auto back = read_checkpoint(tmp.file("c.ckpt"));
  ASSERT_TRUE(back);
  EXPECT_EQ(back->identity, ck.identity);
  EXPECT_EQ(back->blocks_done, 2);
  EXPECT_TRUE(bit_identical(back->sums, ck.sums));
  EXPECT_EQ(back->seconds, 3.25);
  ASSERT_EQ(back->convergence.size(), 2u);
  EXPECT_EQ(back->convergence[0].rel_error, 0.1);
  EXPECT_TRUE(std::isnan(back->convergence[1].rel_error));
}

// Uniform [0, 1) samples: mean 1/2, variance 1/12, so the variance of the mean after n samples
// is 1/(12 n) and the relative RMS error sqrt((1/(12 n)) / (1/4)) = 1/sqrt(3 n).
TEST(ReferenceConvergence, MatchesAnalyticVarianceOfTheMean) {
  Synthetic synth;
  synth.width = 64;
  synth.height = 48;
  BlockJob job = small_job();
  job.width = 64;
  job.height = 48;
  job.spp = 256;
  job.block_spp = 64;
  BlockResult r = accumulate_blocks(job, synth.renderer());
  ASSERT_EQ(r.convergence.size(), 4u);
  for (auto& row : r.convergence) {
    const double expected = 1.0 / std::sqrt(3.0 * double(row.spp));
    // 9216 pixel-channels, each with n / 2 >= 32 degrees of freedom (the pairs): the
    // estimate's relative spread is about sqrt(2 / (9216 n / 2)) plus the spread of the mean^2
    // sum, far below 3%.
    EXPECT_NEAR(row.rel_error / expected, 1.0, 0.03) << "spp " << row.spp;
    // est_relmse = mean(var / (mean^2 + 0.01)) ~ (1/(12 n)) / (0.25 + 0.01 + 1/(12 n)), within 5%
    // (mean^2 varies from pixel to pixel, and the expectation of a ratio is not a ratio).
    const double var = 1.0 / (12.0 * double(row.spp));
    EXPECT_NEAR(row.est_relmse / (var / 0.26), 1.0, 0.05) << "spp " << row.spp;
  }
  EXPECT_EQ(convergence_csv(r.convergence).substr(0, 34), "spp,seconds,rel_error,est_relmse\n6");
}

TEST(ReferenceConvergence, CsvRoundTripAndErrors) {
  std::vector<ConvergenceRow> rows = {{64, 1.25, 0.125, 0.5}, {128, 2.5, NAN, 0.25}};
  auto back = parse_convergence_csv(convergence_csv(rows), "log.csv");
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[1].spp, 128);
  EXPECT_EQ(back[0].rel_error, 0.125);
  EXPECT_TRUE(std::isnan(back[1].rel_error));
  try {
    parse_convergence_csv("spp,seconds,rel_error,est_relmse\n64,1,x,2\n", "log.csv");
    FAIL() << "a malformed line was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("log.csv' line 2"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dnb
