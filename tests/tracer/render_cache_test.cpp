// The content-keyed cache: hits, misses, and damaged entries detected by checksum and never used.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "test_util.h"
#include "tracer/render_cache.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;

CacheKey example_key(int spp = 16) {
  CacheKey key("frame");
  key.add("scene", "abc123").add("spp", spp).add("seed", std::uint64_t(7)).add("scale", 0.1);
  return key;
}

void write_file(const std::string& path, const std::string& content) {
  std::ofstream(path, std::ios::binary) << content;
}

TEST(CacheKey, DigestDependsOnEveryPartAndOrder) {
  EXPECT_EQ(example_key().digest(), example_key().digest());
  EXPECT_NE(example_key(16).digest(), example_key(17).digest());
  CacheKey a("frame"), b("frame"), c("reference");
  a.add("x", 1).add("y", 2);
  b.add("y", 2).add("x", 1);
  c.add("x", 1).add("y", 2);
  EXPECT_NE(a.digest(), b.digest());
  EXPECT_NE(a.digest(), c.digest());  // the kind is part of the key
  EXPECT_EQ(a.digest().size(), 64u);
  EXPECT_THROW(a.add("x", 3), WorkError);
  EXPECT_EQ(example_key().canonical(), "frame\nscene=abc123\nspp=16\nseed=7\nscale=0.10000000000000001\n");
}

TEST(Cache, StoreThenLookupHits) {
  test::TempDir tmp;
  Cache cache(tmp.file("cache"));
  EXPECT_FALSE(cache.lookup(example_key()));
  EXPECT_EQ(cache.stats().misses, 1);
  cache.store(example_key(), [](const std::string& dir) {
    write_file(dir + "/a.txt", "hello");
    write_file(dir + "/b.bin", std::string(1000, 'x'));
  });
  auto entry = cache.lookup(example_key());
  ASSERT_TRUE(entry);
  EXPECT_EQ(entry->files, (std::vector<std::string>{"a.txt", "b.bin"}));
  EXPECT_EQ(read_text_file(entry->file("a.txt")), "hello");
  EXPECT_EQ(cache.stats().hits, 1);
  EXPECT_EQ(cache.stats().stores, 1);
  // Another key misses; no staging folders are left behind.
  EXPECT_FALSE(cache.lookup(example_key(32)));
  int entries = 0;
  for (auto& e : fs::directory_iterator(tmp.file("cache") + "/frame")) {
    EXPECT_NE(e.path().filename().string()[0], '.') << e.path();
    ++entries;
  }
  EXPECT_EQ(entries, 1);
}

class DamagedEntry : public ::testing::Test {
 protected:
  void SetUp() override {
    cache.store(example_key(), [](const std::string& dir) {
      write_file(dir + "/data.bin", std::string(4096, 'd'));
      write_file(dir + "/other.txt", "other");
    });
    dir = cache.entry_dir(example_key());
  }
  void expect_detected() {
    EXPECT_TRUE(verify_cache_entry(dir, example_key()).has_value());
    EXPECT_FALSE(cache.lookup(example_key()));
    EXPECT_EQ(cache.stats().corrupt, 1);
    EXPECT_EQ(cache.stats().hits, 0);
    EXPECT_FALSE(fs::exists(dir)) << "a damaged entry is removed so that it is rebuilt";
  }
  test::TempDir tmp;
  Cache cache{tmp.file("cache")};
  std::string dir;
};

TEST_F(DamagedEntry, FlippedByteDetected) {
  ASSERT_FALSE(verify_cache_entry(dir, example_key()));
  {
    std::fstream f(dir + "/data.bin", std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(1000);
    f.put('X');
  }
  auto why = verify_cache_entry(dir, example_key());
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("checksum"), std::string::npos) << *why;
  expect_detected();
}

TEST_F(DamagedEntry, TruncatedFileDetected) {
  fs::resize_file(dir + "/data.bin", 100);
  auto why = verify_cache_entry(dir, example_key());
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("truncated"), std::string::npos) << *why;
  expect_detected();
}

TEST_F(DamagedEntry, TruncatedManifestDetected) {
  fs::resize_file(dir + "/MANIFEST.json", fs::file_size(dir + "/MANIFEST.json") / 2);
  expect_detected();
}

TEST_F(DamagedEntry, MissingFileDetected) {
  fs::remove(dir + "/other.txt");
  expect_detected();
}

TEST_F(DamagedEntry, ForeignFileDetected) {
  write_file(dir + "/stray.txt", "not from the writer");
  expect_detected();
}

TEST_F(DamagedEntry, DamagedEntryIsRebuiltByTheNextStore) {
  fs::resize_file(dir + "/data.bin", 0);
  EXPECT_FALSE(cache.lookup(example_key()));
  cache.store(example_key(), [](const std::string& d) { write_file(d + "/data.bin", "fresh"); });
  auto entry = cache.lookup(example_key());
  ASSERT_TRUE(entry);
  EXPECT_EQ(read_text_file(entry->file("data.bin")), "fresh");
}

TEST(Cache, StoreReplacesOlderEntry) {
  test::TempDir tmp;
  Cache cache(tmp.file("cache"));
  cache.store(example_key(), [](const std::string& d) { write_file(d + "/v.txt", "one"); });
  cache.store(example_key(), [](const std::string& d) { write_file(d + "/v.txt", "two"); });
  auto entry = cache.lookup(example_key());
  ASSERT_TRUE(entry);
  EXPECT_EQ(read_text_file(entry->file("v.txt")), "two");
}

TEST(Cache, FailedWriterStoresNothing) {
  test::TempDir tmp;
  Cache cache(tmp.file("cache"));
  EXPECT_THROW(cache.store(example_key(),
                           [](const std::string& d) {
                             write_file(d + "/half.txt", "half");
                             throw WorkError("render failed");
                           }),
               WorkError);
  EXPECT_FALSE(cache.lookup(example_key()));
  EXPECT_TRUE(fs::is_empty(tmp.file("cache") + "/frame")) << "staging folder left behind";
}

TEST(Cache, StaleStagingFoldersOfKilledStoresAreRemoved) {
  test::TempDir tmp;
  Cache cache(tmp.file("cache"));
  const fs::path kind = fs::path(tmp.file("cache")) / "frame";
  fs::create_directories(kind / ".staging-old");
  fs::create_directories(kind / ".staging-recent");
  fs::last_write_time(kind / ".staging-old", fs::file_time_type::clock::now() - std::chrono::hours(48));
  cache.store(example_key(), [](const std::string& d) { write_file(d + "/v.txt", "v"); });
  EXPECT_FALSE(fs::exists(kind / ".staging-old"));
  EXPECT_TRUE(fs::exists(kind / ".staging-recent")) << "may belong to a store in progress";
}

TEST(Cache, DefaultDirFollowsEnvironment) {
  ::setenv("DENOISEBENCH_CACHE", "/some/where", 1);
  EXPECT_EQ(Cache::default_dir(), "/some/where");
  ::unsetenv("DENOISEBENCH_CACHE");
  EXPECT_FALSE(Cache::default_dir().empty());
}

// The runner's input-frame cache keeps the frame and its deep edge file, both checksummed.
TEST(CachedFrame, RendersOnceThenHitsWithEdges) {
  test::TempDir tmp;
  Cache cache(tmp.file("cache"));
  AovFrame frame(8, 6);
  Image& color = frame.add(layer::kColor, 3);
  for (std::size_t i = 0; i < color.size(); ++i) color.data()[i] = float(i) * 0.25f;
  frame.meta.scene = "synthetic";
  frame.meta.spp = 4;
  EdgeSubpixels edges;
  edges.pixels = {3, 17};
  edges.samples.resize(2 * EdgeSubpixels::kPerPixel);
  for (std::size_t i = 0; i < edges.samples.size(); ++i) edges.samples[i].depth = float(i);
  frame.edges = edges;

  int renders = 0;
  auto render = [&] {
    ++renders;
    return frame;
  };
  bool hit = true;
  AovFrame first = cached_frame(cache, example_key(), render, &hit);
  EXPECT_FALSE(hit);
  AovFrame second = cached_frame(cache, example_key(), render, &hit);
  EXPECT_TRUE(hit);
  EXPECT_EQ(renders, 1);
  EXPECT_EQ(second.layer(layer::kColor), color);
  ASSERT_TRUE(second.edges);
  EXPECT_EQ(*second.edges, edges);
  auto entry = cache.lookup(example_key());
  ASSERT_TRUE(entry);
  EXPECT_EQ(entry->files.size(), 2u) << "frame.exr and its edge file";

  // A damaged edge file makes the whole entry a miss: the frame is rendered again.
  fs::resize_file(edges_path(entry->file("frame.exr")), 10);
  AovFrame third = cached_frame(cache, example_key(), render, &hit);
  EXPECT_FALSE(hit);
  EXPECT_EQ(renders, 2);
}

}  // namespace
}  // namespace dnb
