// `denoisebench reference` end to end, on a small cornell-box: SIGKILL mid-render and resume,
// `mpirun -np 2` against one process, the cache hit on a second run, a corrupted cache entry
// and a truncated checkpoint. Bit-identical means every float of R,G,B and variance.R/G/B.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>

#include <fmt/format.h>

#include "core/env.h"
#include "core/atomic_file.h"
#include "core/exr_io.h"
#include "test_util.h"
#include "distributed/mpi_context.h"
#include "tracer/reference.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;

std::string binary() {
  const char* b = env::get("BINARY");
  return b ? b : "./denoisebench";
}

// Small enough for seconds on two shared cores, with enough blocks to be killed mid-render.
std::string args(const std::string& out, const std::string& cache, int spp = 64, const std::string& extra = "") {
  return fmt::format("reference cornell-box --size 48x36 --spp {} --block-spp 8 --seed 3 -o {} --cache-dir {} {}", spp,
                     out, cache, extra);
}

void expect_same_image(const std::string& a, const std::string& b) {
  AovFrame fa = read_frame(a, {layer::kColor, layer::kVariance});
  AovFrame fb = read_frame(b, {layer::kColor, layer::kVariance});
  EXPECT_TRUE(fa.layer(layer::kColor) == fb.layer(layer::kColor)) << a << " and " << b << " differ in R,G,B";
  EXPECT_TRUE(fa.layer(layer::kVariance) == fb.layer(layer::kVariance)) << a << " and " << b << " differ in variance";
}

TEST(ReferenceCli, WritesReferenceVarianceMetadataAndConvergenceLog) {
  test::TempDir tmp;
  auto r = test::run_denoisebench(args(tmp.file("ref.exr"), tmp.file("cache")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  AovFrame f = read_frame(tmp.file("ref.exr"), {layer::kColor, layer::kVariance});
  EXPECT_EQ(f.width(), 48);
  EXPECT_EQ(f.meta.spp, 64);
  EXPECT_EQ(f.meta.seed, 3u);
  EXPECT_EQ(f.meta.tracer_version, kTracerVersion);
  EXPECT_EQ(f.meta.extra.at("block_spp"), "8");
  EXPECT_EQ(count_non_finite(f.layer(layer::kColor).view()), 0u);
  auto rows = parse_convergence_csv(read_text_file(tmp.file("ref.convergence.csv")), "csv");
  ASSERT_EQ(rows.size(), 8u);
  EXPECT_EQ(rows.back().spp, 64);
  // The expected relMSE of the mean falls like 1/spp: 8x the samples, 1/8 of it for a light-
  // tailed estimator. Caustic paths of the cornell box are heavy-tailed, so variance estimates
  // at 8 spp run low (most pixels have not met a firefly yet): only require that it halves.
  EXPECT_LT(rows.back().est_relmse, 0.5 * rows.front().est_relmse);
  EXPECT_GT(rows.back().est_relmse, 0.0);
}

TEST(ReferenceCli, SecondRunIsACacheHitAndADamagedEntryIsRendered) {
  test::TempDir tmp;
  auto first = test::run_denoisebench(args(tmp.file("a.exr"), tmp.file("cache")));
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_NE(first.output.find("cache miss, rendering"), std::string::npos) << first.output;

  auto second = test::run_denoisebench(args(tmp.file("b.exr"), tmp.file("cache")));
  ASSERT_EQ(second.exit_code, 0) << second.output;
  EXPECT_NE(second.output.find("cache hit"), std::string::npos) << second.output;
  EXPECT_EQ(second.output.find("rendered"), std::string::npos) << "second run rendered:\n" << second.output;
  expect_same_image(tmp.file("a.exr"), tmp.file("b.exr"));
  EXPECT_EQ(read_text_file(tmp.file("a.convergence.csv")), read_text_file(tmp.file("b.convergence.csv")));

  // Corrupt one byte of the cached EXR's pixel data: detected by checksum, rendered again.
  fs::path exr;
  for (auto& e : fs::recursive_directory_iterator(tmp.file("cache")))
    if (e.path().filename() == "reference.exr") exr = e.path();
  ASSERT_FALSE(exr.empty());
  {
    std::fstream f(exr, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(std::streamoff(fs::file_size(exr) - 64));
    char c = 0;
    f.get(c);
    f.seekp(std::streamoff(fs::file_size(exr) - 64));
    f.put(char(c ^ 0x5a));
  }
  auto third = test::run_denoisebench(args(tmp.file("c.exr"), tmp.file("cache")));
  ASSERT_EQ(third.exit_code, 0) << third.output;
  EXPECT_NE(third.output.find("damaged"), std::string::npos) << third.output;
  EXPECT_NE(third.output.find("rendered 8 blocks"), std::string::npos) << third.output;
  expect_same_image(tmp.file("a.exr"), tmp.file("c.exr"));

  // --no-cache renders although the entry is intact.
  auto fourth = test::run_denoisebench(args(tmp.file("d.exr"), tmp.file("cache"), 64, "--no-cache"));
  ASSERT_EQ(fourth.exit_code, 0) << fourth.output;
  EXPECT_NE(fourth.output.find("rendered 8 blocks"), std::string::npos) << fourth.output;
}

// Starts denoisebench, waits until its first checkpoint exists, then kills it with SIGKILL.
// Returns false if the render finished before it could be killed.
bool start_and_kill(const std::string& arguments, const std::string& checkpoint) {
  std::string cmd = "exec " + binary() + " " + arguments + " > /dev/null 2>&1";
  pid_t pid = ::fork();
  if (pid == 0) {
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  bool killed = false;
  for (int i = 0; i < 6000; ++i) {
    int status = 0;
    if (::waitpid(pid, &status, WNOHANG) == pid) return false;  // finished first
    if (fs::exists(checkpoint)) {
      ::kill(pid, SIGKILL);
      killed = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return killed && WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
}

TEST(ReferenceCli, KilledRenderResumesBitIdentical) {
  test::TempDir tmp;
  const int spp = 256;  // 32 blocks: the kill lands well before the end
  // The uninterrupted render, with another thread count (the image must not depend on it).
  auto whole = test::run_denoisebench(args(tmp.file("whole.exr"), tmp.file("cache-whole"), spp, "--threads 1"));
  ASSERT_EQ(whole.exit_code, 0) << whole.output;

  const std::string ckdir = tmp.file("ck");
  const std::string ck = ckdir + "/reference.ckpt";
  ASSERT_TRUE(start_and_kill(args(tmp.file("resumed.exr"), tmp.file("cache"), spp, "--checkpoint " + ckdir), ck))
      << "the render ended before it could be killed";
  EXPECT_FALSE(fs::exists(tmp.file("resumed.exr"))) << "killed mid-render, yet an output exists";
  auto saved = read_checkpoint(ck);
  ASSERT_TRUE(saved) << "the checkpoint left by SIGKILL is not valid";
  EXPECT_GT(saved->blocks_done, 0);
  EXPECT_LT(saved->blocks_done, spp / 8);

  // Other arguments with that checkpoint: refused, exit 2, the checkpoint kept.
  auto refused = test::run_denoisebench(args(tmp.file("other.exr"), tmp.file("cache"), spp, "--max-depth 5 --checkpoint " + ckdir));
  EXPECT_EQ(refused.exit_code, 2) << refused.output;
  EXPECT_NE(refused.output.find("different reference"), std::string::npos) << refused.output;
  EXPECT_TRUE(fs::exists(ck));

  auto resumed = test::run_denoisebench(args(tmp.file("resumed.exr"), tmp.file("cache"), spp, "--checkpoint " + ckdir));
  ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
  EXPECT_NE(resumed.output.find("resuming from checkpoint"), std::string::npos) << resumed.output;
  expect_same_image(tmp.file("whole.exr"), tmp.file("resumed.exr"));
  EXPECT_FALSE(fs::exists(ck)) << "the checkpoint of a finished reference is removed";
}

TEST(ReferenceCli, TruncatedCheckpointIsIgnoredAndRenderedAgain) {
  test::TempDir tmp;
  const std::string ckdir = tmp.file("ck");
  const std::string ck = ckdir + "/reference.ckpt";
  ASSERT_TRUE(start_and_kill(args(tmp.file("ref.exr"), tmp.file("cache"), 256, "--checkpoint " + ckdir), ck));
  fs::resize_file(ck, fs::file_size(ck) / 2);
  auto r = test::run_denoisebench(args(tmp.file("ref.exr"), tmp.file("cache"), 256, "--checkpoint " + ckdir));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("damaged"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("rendered 32 blocks (0 resumed"), std::string::npos) << r.output;
}

TEST(ReferenceCli, TwoMpiRanksGiveTheImageOfOneProcess) {
  if (!mpi::built_with_mpi()) GTEST_SKIP() << "built with DNB_WITH_MPI=OFF";
#ifdef DNB_TEST_MPIEXEC
  const std::string mpirun = DNB_TEST_MPIEXEC;
#else
  const std::string mpirun;
#endif
  // An MPI build whose launcher is missing cannot distribute anything: that fails, it is not a skip.
  ASSERT_FALSE(mpirun.empty()) << "built with MPI but CMake found no MPI launcher (MPIEXEC_EXECUTABLE)";
  ASSERT_EQ(test::run_command("'" + mpirun + "' --version").exit_code, 0)
      << "built with MPI but its launcher '" << mpirun << "' does not run";
  test::TempDir tmp;
  auto one = test::run_denoisebench(args(tmp.file("one.exr"), tmp.file("cache1")));
  ASSERT_EQ(one.exit_code, 0) << one.output;
  // --oversubscribe: the test machine may have fewer cores than ranks. One thread per rank.
  // mpirun may run as root here (containers, CI): test_util.cpp sets the OMPI_* switches.
  auto two = test::run_command("'" + mpirun + "' --oversubscribe -np 2 " + binary() + " " +
                               args(tmp.file("two.exr"), tmp.file("cache2"), 64, "--threads 1"));
  ASSERT_EQ(two.exit_code, 0) << two.output;
  EXPECT_NE(two.output.find("(2 ranks)"), std::string::npos) << two.output;
  EXPECT_NE(two.output.find("rendered 8 blocks"), std::string::npos) << two.output;
  expect_same_image(tmp.file("one.exr"), tmp.file("two.exr"));
}

}  // namespace
}  // namespace dnb
