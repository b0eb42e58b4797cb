// Writes that fail must say so and commit nothing (issue "Nothing lost, nothing half-written"):
// every output goes through AtomicOutput, which checks each write(2), fsync(2) and close(2).
// The full-disk cases run on a small tmpfs the test mounts itself, which needs root (as CI
// runs); elsewhere they are skipped with a message.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/mount.h>
#include <unistd.h>

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

}  // namespace
}  // namespace dnb
