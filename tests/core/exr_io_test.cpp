// The AOV frame's EXR round trip and the refusals of bad files.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <string>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imageio.h>
#include <fmt/format.h>

#include "core/atomic_file.h"
#include "core/errors.h"
#include "core/exr_io.h"
#include "core/memory_budget.h"
#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;

// Fills every layer with distinct values (including negative zero and denormal-free extremes)
// so that a channel swapped or lost in the round trip changes the result.
AovFrame make_full_frame(int w, int h) {
  AovFrame f(w, h);
  const char* rgb[] = {"color", "direct", "indirect", "albedo", "reflection", "emission", "variance",
                       "direct_variance", "indirect_variance", "refl1.direct", "refl1.indirect",
                       "refl1.albedo", "refl1.tint", "refl1.reflection", "refl1.emission", "refl1.normal"};
  int k = 0;
  for (const char* n : rgb) {
    Image& img = f.add(n, 3);
    for (std::size_t i = 0; i < img.size(); ++i) img.data()[i] = float(k * 1000 + i) * 0.001f - 0.5f;
    ++k;
  }
  Image& normal = f.add("normal", 3);
  for (std::size_t i = 0; i < normal.size(); ++i) normal.data()[i] = std::sin(float(i));
  for (const char* n : {"depth", "edge", "samples", "refl1.depth"}) {
    Image& img = f.add(n, 1);
    for (std::size_t i = 0; i < img.size(); ++i) img.data()[i] = float(i % 7) + 0.25f * k;
    ++k;
  }
  f.meta.scene = "unit-test";
  f.meta.spp = 256;
  f.meta.seed = 0xFFFFFFFFFFFFull;
  f.meta.tracer_version = "tracer-9";
  f.meta.build_version = "0.1.0 (abc)";
  f.meta.render_seconds = 12.345678901234567;
  f.meta.dropped_samples = 3;
  f.meta.reflection_levels = 1;
  f.meta.extra["note"] = "kept";
  EdgeSubpixels e;
  for (int p : {1, 5, w * h - 1}) {
    e.pixels.push_back(p);
    for (int s = 0; s < EdgeSubpixels::kPerPixel; ++s) {
      EdgeSample es;
      for (int c = 0; c < 3; ++c) {
        es.normal[c] = 0.1f * c + s;
        es.albedo[c] = 0.01f * (p + c);
        es.direct[c] = 1.5f * s + c;
        es.indirect[c] = 0.25f * s - c;
      }
      es.depth = 3.0f + s;
      e.samples.push_back(es);
    }
  }
  f.edges = e;
  return f;
}

TEST(ExrIo, FullFrameRoundTripIsBitExact) {
  test::TempDir dir;
  AovFrame f = make_full_frame(13, 7);
  const std::string path = dir.file("frame.exr");
  write_frame(f, path);
  AovFrame g = read_frame(path, {"color", "direct", "refl1.tint"});
  ASSERT_EQ(g.width(), 13);
  ASSERT_EQ(g.height(), 7);
  ASSERT_EQ(g.layers().size(), f.layers().size());
  for (const auto& [name, img] : f.layers()) {
    ASSERT_TRUE(g.has(name)) << name;
    EXPECT_TRUE(g.layer(name) == img) << "layer " << name << " changed in the round trip";
  }
  EXPECT_EQ(g.meta.scene, "unit-test");
  EXPECT_EQ(g.meta.spp, 256);
  EXPECT_EQ(g.meta.seed, 0xFFFFFFFFFFFFull);
  EXPECT_EQ(g.meta.tracer_version, "tracer-9");
  EXPECT_EQ(g.meta.build_version, "0.1.0 (abc)");
  EXPECT_EQ(g.meta.render_seconds, f.meta.render_seconds);
  EXPECT_EQ(g.meta.dropped_samples, 3);
  EXPECT_EQ(g.meta.reflection_levels, 1);
  EXPECT_EQ(g.meta.extra.at("note"), "kept");
  ASSERT_TRUE(g.edges.has_value());
  EXPECT_TRUE(*g.edges == *f.edges);
}

// Frames are read and written a strip of at most 64 rows at a time (to bound the memory of a 1080p frame): a
// frame of several strips and a last partial one round-trips to the bit, and so do tiled copies
// of it as other renderers write them (OpenImageIO's read_scanlines divided by zero on a tiled
// file: SIGFPE, found trying a tiled frame by hand).
TEST(ExrIo, FramesOfManyStripsAndTiledFilesReadBitExact) {
  test::TempDir dir;
  const AovFrame f = make_full_frame(19, 150);
  const std::string path = dir.file("frame.exr");
  write_frame(f, path);
  auto same = [&](const AovFrame& g, const std::string& what) {
    ASSERT_EQ(g.layers().size(), f.layers().size()) << what;
    for (const auto& [name, img] : f.layers()) {
      ASSERT_TRUE(g.has(name)) << what << ": " << name;
      EXPECT_TRUE(g.layer(name) == img) << what << ": layer " << name << " changed";
    }
    ASSERT_TRUE(g.edges.has_value()) << what;
    EXPECT_TRUE(*g.edges == *f.edges) << what;
  };
  same(read_frame(path), "scanlines");
  for (auto [tw, th] : {std::pair{16, 16}, std::pair{5, 7}, std::pair{32, 200}}) {
    const std::string tiled = dir.file(fmt::format("tiled-{}x{}.exr", tw, th));
    OIIO::ImageBuf buf(path);
    buf.set_write_tiles(tw, th);
    ASSERT_TRUE(buf.write(tiled)) << buf.geterror();
    fs::copy_file(edges_path(path), edges_path(tiled));
    ASSERT_GT(OIIO::ImageInput::open(tiled)->spec().tile_width, 0) << "not written tiled";
    same(read_frame(tiled), fmt::format("tiles of {}x{}", tw, th));
  }
  // `only` keeps the layers listed, none when the list is empty; the edge file is read anyway.
  const AovFrame two = read_frame(path, {"color"}, std::vector<std::string>{"color", "refl1.depth"});
  EXPECT_EQ(two.layers().size(), 2u);
  EXPECT_TRUE(two.layer("refl1.depth") == f.layer("refl1.depth"));
  const AovFrame none = read_frame(path, {}, std::vector<std::string>{});
  EXPECT_TRUE(none.layers().empty());
  EXPECT_EQ(none.width(), 19);
  EXPECT_EQ(none.meta.spp, 256);
  EXPECT_TRUE(none.edges.has_value());
}

TEST(ExrIo, ChannelsAreNamedAsDesignSays) {
  test::TempDir dir;
  AovFrame f = make_full_frame(4, 3);
  f.edges.reset();
  write_frame(f, dir.file("f.exr"));
  auto in = OIIO::ImageInput::open(dir.file("f.exr"));
  ASSERT_TRUE(in);
  const auto& spec = in->spec();
  for (const char* ch : {"R", "G", "B", "direct.R", "indirect.B", "albedo.G", "reflection.R", "emission.B",
                         "normal.X", "normal.Y", "normal.Z", "depth.Z", "variance.R", "direct_variance.G",
                         "indirect_variance.B", "edge.Y", "refl1.direct.R", "refl1.tint.B", "refl1.depth.Z",
                         "refl1.normal.Z"})
    EXPECT_GE(spec.channelindex(ch), 0) << "channel " << ch << " missing from the file";
}

TEST(ExrIo, MissingRequiredChannelIsRefusedByName) {
  test::TempDir dir;
  AovFrame f(8, 8);
  f.add("color", 3);
  f.add("albedo", 3);
  write_frame(f, dir.file("f.exr"));
  try {
    read_frame(dir.file("f.exr"), {"color", "direct"});
    FAIL() << "a frame without direct.* was accepted";
  } catch (const InputError& e) {
    std::string msg = e.what();
    EXPECT_NE(msg.find("direct.R"), std::string::npos) << msg;
    EXPECT_NE(msg.find("f.exr"), std::string::npos) << msg;
  }
}

TEST(ExrIo, ReadRgbNamesTheMissingChannel) {
  test::TempDir dir;
  Image y(4, 4, 1, 0.5f);
  OIIO::ImageSpec spec(4, 4, 1, OIIO::TypeDesc::FLOAT);
  spec.channelnames = {"Y"};
  auto out = OIIO::ImageOutput::create(dir.file("y.exr"));
  ASSERT_TRUE(out->open(dir.file("y.exr"), spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, y.data()));
  out->close();
  try {
    read_rgb(dir.file("y.exr"));
    FAIL() << "a luminance-only file was read as RGB";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("'R'"), std::string::npos) << e.what();
  }
}

TEST(ExrIo, MissingFileIsAnInputError) {
  EXPECT_THROW(read_frame("/nonexistent/frame.exr"), InputError);
  EXPECT_THROW(read_rgb("/nonexistent/image.exr"), InputError);
}

TEST(ExrIo, EdgeFileMissingBesideFrameIsRefused) {
  test::TempDir dir;
  AovFrame f = make_full_frame(6, 6);
  write_frame(f, dir.file("f.exr"));
  fs::remove(edges_path(dir.file("f.exr")));
  EXPECT_THROW(read_frame(dir.file("f.exr")), InputError);
}

// Found by fuzz/frame_fuzz.cpp: a frame whose header declares a 2 GB string attribute made
// OpenEXR 3.1 allocate (and fill) it before finding the file too short: 4 GB and 15 s for a
// 10 KB file. The header is now checked by OpenEXR's C core first, with no large allocation.
TEST(ExrIo, FuzzHeaderAttributeLargerThanTheFileIsRefusedByName) {
  test::TempDir dir;
  AovFrame f(4, 3);
  f.add("color", 3);
  f.meta.scene = "cornell-box";
  write_frame(f, dir.file("f.exr"));
  std::string bytes;
  {
    std::ifstream in(dir.file("f.exr"), std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  // The attribute's name, its type "string\0", then its int32 size: made 0x7fff0000.
  const std::string attr = std::string("denoisebench:scene") + '\0' + "string" + '\0';
  const std::size_t at = bytes.find(attr);
  ASSERT_NE(at, std::string::npos) << "the scene attribute is not in the header";
  const std::int32_t huge = 0x7fff0000;
  bytes.replace(at + attr.size(), 4, reinterpret_cast<const char*>(&huge), 4);
  {
    std::ofstream out(dir.file("f.exr"), std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), std::streamsize(bytes.size()));
  }
  for (auto read : {+[](const std::string& p) { (void)read_frame(p); }, +[](const std::string& p) { (void)read_rgb(p); }}) {
    try {
      read(dir.file("f.exr"));
      FAIL() << "a header attribute of 2 GB in a small file was accepted";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("f.exr"), std::string::npos) << msg;
      EXPECT_NE(msg.find("OpenEXR header"), std::string::npos) << msg;
    }
  }
}

// Found by fuzz/frame_fuzz.cpp (the input as it found it): every attribute size fits the file,
// but one of them disagrees with its type, so OpenEXR's C++ reader reads the next attributes
// out of step and finds a "string" of 1.7 GB, which it allocated. The C core refuses the header.
// A second input of that kind that OpenEXR's C core accepted (it reads the channel list within
// its declared size; the C++ reader reads it up to its terminator): refused by the size walk.
// Found by fuzz/frame_fuzz.cpp: a 1.8 KB frame whose dataWindow attribute declares 17 bytes for
// a box2i (16). OpenEXR's C core reports it and reads on (exr_start_read succeeds), so the check
// passed it; the C++ reader then read the rest out of step and took 7 s and 2 GB before
// "unexpected end of file". Any complaint of the core now refuses the file, naming it.
TEST(ExrIo, FuzzAttributeSizeTheCoreReadsPastIsRefusedFromTheHeader) {
  const std::string path = std::string(DNB_TEST_SOURCE_DIR) + "/tests/core/data/fuzz-frame-attribute-size-read-past.exr";
  ASSERT_TRUE(fs::exists(path)) << path;
  for (auto read : {+[](const std::string& p) { (void)read_frame(p); }, +[](const std::string& p) { (void)read_rgb(p); }}) {
    try {
      read(path);
      FAIL() << "an attribute of the wrong size was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("not a readable OpenEXR header: Attribute 'dataWindow': Invalid size 17"),
                std::string::npos)
          << e.what();
    }
  }
}

TEST(ExrIo, FuzzHeaderReadOutOfStepIsRefused) {
  for (const char* name : {"fuzz-frame-out-of-step-header.exr", "fuzz-frame-channel-list-out-of-step.exr"}) {
  const std::string path = std::string(DNB_TEST_SOURCE_DIR) + "/tests/core/data/" + name;
  ASSERT_TRUE(fs::exists(path)) << path;
  for (auto read : {+[](const std::string& p) { (void)read_frame(p); }, +[](const std::string& p) { (void)read_rgb(p); }}) {
    try {
      read(path);
      FAIL() << name << ": a header read out of step was accepted";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_TRUE(msg.find("OpenEXR header") != std::string::npos || msg.find("OpenEXR channel list") != std::string::npos)
          << msg;
    }
  }
  }
}

// Frames and images are read as OpenEXR only, checked before any decoder runs: otherwise a PNG
// named f.exr would be decoded by OIIO's PNG reader (every image decoder of OIIO would be
// reachable from a frame path).
TEST(ExrIo, FileThatIsNotOpenExrIsRefused) {
  test::TempDir dir;
  Image rgb(4, 4, 3, 0.5f);
  OIIO::ImageSpec spec(4, 4, 3, OIIO::TypeDesc::UINT8);
  auto out = OIIO::ImageOutput::create("png");
  ASSERT_TRUE(out && out->open(dir.file("f.exr"), spec));
  ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, rgb.data()));
  out->close();
  for (auto read : {+[](const std::string& p) { (void)read_frame(p); }, +[](const std::string& p) { (void)read_rgb(p); }}) {
    try {
      read(dir.file("f.exr"));
      FAIL() << "a PNG file named .exr was read";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("not an OpenEXR file"), std::string::npos) << e.what();
    }
  }
}

TEST(Image, AbsurdAndZeroSizesAreRefused) {
  EXPECT_THROW(Image(0, 10, 3), InputError);
  EXPECT_THROW(Image(10, -1, 3), InputError);
  EXPECT_THROW(Image(100000, 100000, 3), InputError);
  EXPECT_THROW(Image(10, 10, 0), InputError);
  EXPECT_NO_THROW(Image(1, 1, 1));
}

TEST(Image, ViewsShareStorageAndCropWithoutCopy) {
  Image img(5, 4, 2);
  ImageView v = img.view();
  ImageView c = v.crop(1, 2, 3, 2);
  c.at(0, 0, 1) = 7.0f;
  EXPECT_EQ(img.at(1, 2, 1), 7.0f);
  EXPECT_EQ(c.row_stride, std::size_t(10));
  Image copy = to_image(c);
  EXPECT_EQ(copy.width(), 3);
  EXPECT_EQ(copy.at(0, 0, 1), 7.0f);
}

TEST(AtomicWrite, FailingWriteLeavesNoFileAtTheDestination) {
  test::TempDir dir;
  const std::string dest = dir.file("out.exr");
  {
    AovFrame bad(4, 4);  // no layers: the write fails before anything is renamed
    EXPECT_THROW(write_frame(bad, dest), WorkError);
  }
  EXPECT_FALSE(fs::exists(dest));
  {
    AtomicOutput out(dir.file("x.txt"));
    std::FILE* f = std::fopen(out.temp_path().c_str(), "w");
    std::fputs("partial", f);
    std::fclose(f);
    // destroyed without commit(): an interrupted write
  }
  EXPECT_FALSE(fs::exists(dir.file("x.txt")));
  std::size_t leftovers = 0;
  for (auto& e : fs::directory_iterator(dir.path())) leftovers += !e.path().empty();
  EXPECT_EQ(leftovers, 0u) << "temporary files were left behind";
}

TEST(AtomicWrite, CommittedWriteReplacesTheDestination) {
  test::TempDir dir;
  write_text_atomic(dir.file("a.txt"), "one");
  write_text_atomic(dir.file("a.txt"), "two");
  EXPECT_EQ(read_text_file(dir.file("a.txt")), "two");
}

}  // namespace
}  // namespace dnb

namespace dnb {
namespace {

// A small file may declare the largest size Image::check_size allows; the readers refuse it when
// decoding would need more than the machine's memory, naming the file, instead of dying with
// std::bad_alloc or the out-of-memory killer.
TEST(ExrIo, DecodingMoreThanTheMachinesMemoryIsRefusedNamingTheFile) {
  const double gib = double(1ull << 30);
  try {
    check_decode_memory("huge.exr", 32768, 8192, 1024, 24 * gib);  // 2^28 pixels, 1024 channels: 2 TiB
    FAIL() << "not refused";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("'huge.exr': decoding 32768x8192 with 1024 channels needs about 2048.0 GiB"));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("24.0 GiB this process may use"));
  }
  EXPECT_NO_THROW(check_decode_memory("frame.exr", 1024, 768, 64, 24 * gib));  // 0.4 GiB
  EXPECT_NO_THROW(check_decode_memory("frame.exr", 32768, 8192, 1024, 0));     // memory unknown: not refused
  EXPECT_GT(physical_memory_bytes(), 0.0);
}

TEST(ExrIo, MemorySizesParseWithUnitsAndBadOnesNameTheVariable) {
  EXPECT_EQ(parse_memory_size("512M", "$V"), 512.0 * (1 << 20));
  EXPECT_EQ(parse_memory_size("4g", "$V"), 4.0 * (1 << 30));
  EXPECT_EQ(parse_memory_size("1.5K", "$V"), 1536.0);
  EXPECT_EQ(parse_memory_size("1000", "$V"), 1000.0);
  for (const char* bad : {"", "M", "0", "-1G", "4GB", "4 G", "nan", "inf", "12Q"})
    EXPECT_NE(test::error_of<InputError>([&] { parse_memory_size(bad, "$V"); }).find(fmt::format("$V '{}'", bad)),
              std::string::npos)
        << bad;
}

// Sets an environment variable for one scope and restores what was there.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    ::setenv(name, value, 1);
  }
  ~ScopedEnv() {
    if (old_) ::setenv(name_, old_->c_str(), 1);
    else ::unsetenv(name_);
  }

 private:
  const char* name_;
  std::optional<std::string> old_;
};

// Found by the frame fuzz target: a 2.5 KB file declaring 31748 x 513 with 33 channels
// made the reader allocate 2.1 GB (libFuzzer's memory limit is 2 GB) before its pixels were found
// missing. On the machine that is refused after the allocation; a process with less memory
// (a cgroup limit, $DENOISEBENCH_MEMORY_LIMIT) now refuses it from the header, naming the file.
TEST(ExrIo, FuzzALargeDeclaredImageIsRefusedWithinTheProcesssMemoryLimit) {
  const std::string path = std::string(DNB_TEST_SOURCE_DIR) + "/tests/core/data/fuzz-frame-declares-2gib.exr";
  ASSERT_TRUE(fs::exists(path)) << path;
  {
    ScopedEnv limit("DENOISEBENCH_MEMORY_LIMIT", "512M");
    EXPECT_EQ(memory_budget_bytes(), 512.0 * (1 << 20));
    const std::string msg = test::error_of<InputError>([&] { (void)read_frame(path); });
    EXPECT_NE(msg.find("'" + path + "': decoding 31748x513 with 33 channels needs about 2."), std::string::npos) << msg;
    EXPECT_NE(msg.find("0.5 GiB this process may use"), std::string::npos) << msg;
  }
  {
    ScopedEnv limit("DENOISEBENCH_MEMORY_LIMIT", "lots");
    EXPECT_NE(test::error_of<InputError>([&] { (void)read_frame(path); }).find("$DENOISEBENCH_MEMORY_LIMIT 'lots'"),
              std::string::npos);
  }
  // Without a limit below it, the machine's budget applies (at most its physical memory).
  EXPECT_LE(memory_budget_bytes(), physical_memory_bytes());
}

}  // namespace
}  // namespace dnb
