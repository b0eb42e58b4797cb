// Writes that fail must say so and commit nothing (issue "Nothing lost, nothing half-written"):
// every output goes through AtomicOutput, which checks each write(2), fsync(2) and close(2).
// The full-disk cases run on a small tmpfs the test mounts itself, which needs root (as CI
// runs); elsewhere they are skipped with a message.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "test_util.h"

namespace dnb {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// A 512 KiB tmpfs, filled to the last `free_bytes` (within a page) by a filler file.
class FullDisk : public ::testing::Test {
 protected:
  void SetUp() override {
    if (::geteuid() != 0) GTEST_SKIP() << "mounting a small tmpfs needs root; full-disk cases not run";
    dir_ = fs::path(tmp_.path()) / "disk";
    fs::create_directories(dir_);
    if (::mount("tmpfs", dir_.c_str(), "tmpfs", 0, "size=512k") != 0)
      GTEST_SKIP() << "cannot mount a tmpfs here (" << std::strerror(errno) << "); full-disk cases not run";
    mounted_ = true;
  }
  void TearDown() override {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  // Fills the file system, then frees `free_bytes` of it.
  void fill(std::size_t free_bytes) {
    const std::string filler = (dir_ / "filler").string();
    {
      std::ofstream f(filler, std::ios::binary);
      const std::string block(4096, 'x');
      while (f.write(block.data(), block.size())) {
      }
    }
    const auto size = fs::file_size(filler);
    fs::resize_file(filler, size > free_bytes ? size - free_bytes : 0);
  }
  // Every file of the disk but the filler: what a failed write left behind.
  std::vector<std::string> left_behind() const {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(dir_))
      if (e.path().filename() != "filler") out.push_back(e.path().filename().string());
    return out;
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  test::TempDir tmp_;
  fs::path dir_;
  bool mounted_ = false;
};

std::string error_of(const std::function<void()>& f) { return test::error_of<WorkError>(f); }

TEST_F(FullDisk, TextWriteFailsWithTheSystemsReasonAndLeavesNothing) {
  fill(0);
  const std::string what = error_of([&] { write_text_atomic(path("results.json"), std::string(64 * 1024, 'r')); });
  EXPECT_THAT(what, HasSubstr("results.json"));
  EXPECT_THAT(what, HasSubstr(std::strerror(ENOSPC)));
  EXPECT_TRUE(left_behind().empty()) << left_behind().front();
}

TEST_F(FullDisk, ImageWriteThatDoesNotFitFailsAndLeavesNothing) {
  // Before: OpenEXR's writer lost the data and closed successfully, leaving a 4096-byte file.
  fill(8 * 1024);
  Image noise(96, 64, 3);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (std::size_t i = 0; i < noise.size(); ++i) noise.data()[i] = u(rng);  // incompressible
  const std::string what = error_of([&] { write_rgb(noise, path("out.exr")); });
  EXPECT_THAT(what, HasSubstr("out.exr"));
  EXPECT_THAT(what, HasSubstr(std::strerror(ENOSPC)));
  EXPECT_TRUE(left_behind().empty()) << left_behind().front();
}

TEST_F(FullDisk, AFrameAndItsEdgeFileAreCommittedTogetherOrNotAtAll) {
  // Room for the (small) edge file but not for the frame: before, the edge file was committed
  // and left as an orphan that a later frame could be paired with.
  fill(24 * 1024);
  AovFrame frame(96, 64);
  Image color(96, 64, 3);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (std::size_t i = 0; i < color.size(); ++i) color.data()[i] = u(rng);
  frame.set(layer::kColor, color);
  EdgeSubpixels e;
  e.pixels = {0, 1};
  e.samples.resize(2 * EdgeSubpixels::kPerPixel);
  frame.edges = e;
  const std::string what = error_of([&] { write_frame(frame, path("f.exr")); });
  EXPECT_THAT(what, HasSubstr(std::strerror(ENOSPC)));
  EXPECT_TRUE(left_behind().empty()) << left_behind().front();
}

ino_t inode_of(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 ? st.st_ino : 0;
}

// Every file of `dir` (temporary names included): keep_file leaves nothing but the destination.
std::vector<std::string> files_in(const fs::path& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

// keep_file (the results folder's input frames and references): a hard link when it can, the
// same bytes either way, and nothing done the second time.
TEST(KeepFile, LinksOnceThenLeavesTheSameFileAlone) {
  test::TempDir dir;
  test::write(dir.file("src.exr"), "frame bytes");
  fs::create_directories(dir.path() / "out");
  const std::string dst = dir.file("out/kept.exr");
  EXPECT_EQ(keep_file(dir.file("src.exr"), dst), Kept::Linked);
  EXPECT_EQ(inode_of(dst), inode_of(dir.file("src.exr")));
  EXPECT_EQ(keep_file(dir.file("src.exr"), dst), Kept::Unchanged);
  EXPECT_EQ(files_in(dir.path() / "out"), std::vector<std::string>{"kept.exr"});
  // Another file under the destination's name is replaced, by rename (no temporary left).
  test::write(dir.file("other.exr"), "other bytes, longer");
  EXPECT_EQ(keep_file(dir.file("other.exr"), dst), Kept::Linked);
  EXPECT_EQ(test::slurp(dst), "other bytes, longer");
  EXPECT_EQ(test::slurp(dir.file("src.exr")), "frame bytes") << "replacing a link must not write through it";
  EXPECT_EQ(files_in(dir.path() / "out"), std::vector<std::string>{"kept.exr"});
}

TEST(KeepFile, ACopyIsKeptAsItIsWhenTheBytesAreTheSame) {
  test::TempDir dir;
  test::write(dir.file("src.exr"), "frame bytes");
  const std::string dst = dir.file("kept.exr");
  EXPECT_EQ(keep_file(dir.file("src.exr"), dst, /*allow_link=*/false), Kept::Copied);
  EXPECT_NE(inode_of(dst), inode_of(dir.file("src.exr")));
  EXPECT_EQ(test::slurp(dst), "frame bytes");
  const ino_t copied = inode_of(dst);
  EXPECT_EQ(keep_file(dir.file("src.exr"), dst, false), Kept::Unchanged);
  EXPECT_EQ(keep_file(dir.file("src.exr"), dst), Kept::Unchanged) << "same bytes: no link made over the copy";
  EXPECT_EQ(inode_of(dst), copied);
  // Same size, other bytes: copied again.
  test::write(dir.file("src.exr"), "frame BYTES");
  EXPECT_EQ(keep_file(dir.file("src.exr"), dst, false), Kept::Copied);
  EXPECT_EQ(test::slurp(dst), "frame BYTES");
  EXPECT_THAT(test::error_of<InputError>([&] { keep_file(dir.file("missing.exr"), dst); }), HasSubstr("missing.exr"));
}

// Across file systems link(2) fails (EXDEV): the file is copied instead.
TEST_F(FullDisk, KeepFileCopiesAcrossFileSystems) {
  test::write(tmp_.file("src.exr"), "frame bytes");
  EXPECT_EQ(keep_file(tmp_.file("src.exr"), path("kept.exr")), Kept::Copied);
  EXPECT_EQ(test::slurp(path("kept.exr")), "frame bytes");
  EXPECT_EQ(left_behind(), std::vector<std::string>{"kept.exr"});
  EXPECT_EQ(keep_file(tmp_.file("src.exr"), path("kept.exr")), Kept::Unchanged);
}

TEST(DurableWrite, AFrameIsNeverPairedWithAnotherRendersEdgeFile) {
  test::TempDir dir;
  auto frame_with_edge = [](float v) {
    AovFrame f(8, 6);
    Image c(8, 6, 3);
    for (std::size_t i = 0; i < c.size(); ++i) c.data()[i] = v;
    f.set(layer::kColor, c);
    EdgeSubpixels e;
    e.pixels = {3};
    e.samples.resize(EdgeSubpixels::kPerPixel);
    e.samples[0].depth = v;
    f.edges = e;
    return f;
  };
  write_frame(frame_with_edge(1.f), dir.file("a.exr"));
  write_frame(frame_with_edge(2.f), dir.file("b.exr"));
  EXPECT_EQ(read_frame(dir.file("a.exr"), {}).edges->samples[0].depth, 1.f);
  // b's edge file under a's name: same size and pixel count, another render's data.
  fs::copy_file(dir.file("b.edges.exr"), dir.file("a.edges.exr"), fs::copy_options::overwrite_existing);
  try {
    read_frame(dir.file("a.exr"), {});
    FAIL() << "a stale edge file was paired with the frame";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("a.edges.exr"));
    EXPECT_THAT(e.what(), HasSubstr("not the one written with this frame"));
  }
}


// RunLock (experiment/runner.cpp): the first process of a run waits until every process of the
// last run into the folder has ended, a non-first one among them (the rank a killed mpirun leaves
// running), and only once: the processes of one run share the lock.
TEST(RunLock, TheFirstProcessOfARunWaitsUntilEveryProcessOfTheLastOneHasEnded) {
  test::TempDir dir;
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {  // a rank of the earlier run: holds the lock until it ends, 300 ms on
    ::close(ready[0]);
    new RunLock(dir.path().string(), false);  // released by the process's end, as a killed rank's
    (void)!::write(ready[1], "x", 1);
    ::usleep(300000);
    test::write(dir.file("ended"), "the last thing the earlier run's process does");
    ::_exit(0);
  }
  ::close(ready[1]);
  char c = 0;
  ASSERT_EQ(::read(ready[0], &c, 1), 1);
  ::close(ready[0]);
  int waited = 0;
  {
    RunLock first(dir.path().string(), true, [&] { ++waited; });
    // It returned: the child's last act is done, not merely its sleep begun.
    EXPECT_TRUE(fs::exists(dir.path() / "ended")) << "the lock was granted while the earlier run's process lived";
    EXPECT_EQ(waited, 1);
    // This run's other processes share it at once; a third run's first process would wait.
    RunLock other(dir.path().string(), false);
  }
  ::waitpid(child, nullptr, 0);
  // Nobody holds it now: granted without waiting.
  RunLock again(dir.path().string(), true, [&] { ++waited; });
  EXPECT_EQ(waited, 1);
}

}  // namespace
}  // namespace dnb
