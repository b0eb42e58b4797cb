// DENOISEBENCH_AM_CAPTURE (denoisers/am/capture.h): a recorded call of the adaptive-manifold core read back
// gives the same inputs, and the core run on them the same output bit for bit; a file that is
// not a whole capture is refused with its name.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>

#include "core/errors.h"
#include "denoisers/am/adaptive_manifold.h"
#include "denoisers/am/capture.h"

namespace dnb {
namespace {

namespace fs = std::filesystem;

struct TempDir {
  fs::path path = fs::temp_directory_path() / ("dnb-am-capture-" + std::to_string(::getpid()));
  TempDir() {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
};

std::vector<fs::path> captures_in(const fs::path& dir) {
  std::vector<fs::path> r;
  for (const auto& e : fs::directory_iterator(dir)) r.push_back(e.path());
  std::sort(r.begin(), r.end());
  return r;
}

TEST(AmCapture, RecordedCallReplaysBitForBit) {
  const int w = 40, h = 30, C = 3, D = 5;
  Image src(w, h, C), guide(w, h, D);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (std::size_t i = 0; i < src.size(); ++i) src.data()[i] = u(rng);
  for (std::size_t i = 0; i < guide.size(); ++i) guide.data()[i] = u(rng);
  std::vector<float> qg(D, 0.4f), qs(C, 0.7f);
  std::vector<AmQuery> queries{{3, 4, qg.data(), qs.data(), true}, {w - 1, h - 1, guide.pixel(w - 1, h - 1), nullptr, false}};
  AmSettings s;
  s.sigma_s = 8;
  s.sigma_r = 0.3;
  s.adjust_outliers = true;
  s.outlier_scale = 0.5;
  s.pca_iterations = 2;
  // A view with a row stride wider than its rows: the capture holds the pixels, not the padding.
  Image wide(w + 7, h, D);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < D; ++c) wide.at(x, y, c) = guide.at(x, y, c);
  const ConstImageView guide_view = wide.cview().crop(0, 0, w, h);

  TempDir dir;
  std::vector<float> q_direct;
  // The older DNB_ spelling, still read where DENOISEBENCH_AM_CAPTURE is unset (core/env.h).
  ::setenv("DNB_AM_CAPTURE", dir.path.c_str(), 1);
  const Image direct = am_filter(src.cview(), guide_view, s, queries, &q_direct);
  ::unsetenv("DNB_AM_CAPTURE");
  const auto files = captures_in(dir.path);
  ASSERT_EQ(files.size(), 1u);
  EXPECT_EQ(files[0].extension(), ".bin");  // no temporary left behind

  const AmCapture cap = read_am_capture(files[0].string());
  EXPECT_EQ(cap.src.width(), w);
  EXPECT_EQ(cap.src.height(), h);
  EXPECT_EQ(cap.src.channels(), C);
  EXPECT_EQ(cap.guide.channels(), D);
  EXPECT_EQ(cap.settings.sigma_s, s.sigma_s);
  EXPECT_EQ(cap.settings.sigma_r, s.sigma_r);
  EXPECT_EQ(cap.settings.adjust_outliers, s.adjust_outliers);
  EXPECT_EQ(cap.settings.outlier_scale, s.outlier_scale);
  EXPECT_EQ(cap.settings.pca_iterations, s.pca_iterations);
  ASSERT_EQ(cap.queries.size(), queries.size());
  EXPECT_EQ(cap.queries[0].x, 3);
  EXPECT_EQ(cap.queries[0].y, 4);
  ASSERT_NE(cap.queries[0].src, nullptr);
  EXPECT_EQ(cap.queries[0].src[2], 0.7f);
  EXPECT_EQ(cap.queries[1].src, nullptr);
  EXPECT_FALSE(cap.queries[1].adjust_outliers);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < D; ++c) ASSERT_EQ(cap.guide.at(x, y, c), guide.at(x, y, c)) << x << "," << y;

  std::vector<float> q_replay;
  const Image replay = am_filter(cap.src.cview(), cap.guide.cview(), cap.settings, cap.queries, &q_replay);
  ASSERT_EQ(replay.size(), direct.size());
  for (std::size_t i = 0; i < direct.size(); ++i) ASSERT_EQ(replay.data()[i], direct.data()[i]) << i;
  EXPECT_EQ(q_replay, q_direct);

  // Cut short: refused, naming the file.
  const fs::path cut = dir.path / "cut.bin";
  {
    std::ifstream in(files[0], std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(cut, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size() / 2));
  }
  try {
    read_am_capture(cut.string());
    FAIL() << "a truncated capture was read";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(cut.string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("truncated"), std::string::npos) << e.what();
  }
  const fs::path other = dir.path / "other.bin";
  std::ofstream(other) << "not a capture at all";
  EXPECT_THROW(read_am_capture(other.string()), InputError);
}

}  // namespace
}  // namespace dnb
