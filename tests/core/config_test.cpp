// Strict TOML configs: unknown keys and wrong types are errors naming file, line and key.
#include <gtest/gtest.h>

#include "core/config.h"
#include "core/errors.h"
#include "test_util.h"

namespace dnb {
namespace {

std::string error_of(const std::function<void()>& f) { return test::error_of<InputError>(f); }

TEST(Config, ReadsTypedValuesWithDefaults) {
  auto cfg = ConfigFile::parse("spp = 64\nsigma = 2\nname = \"x\"\n[render]\nsize = [1, 2, 3]\n", "t.toml");
  auto root = cfg.root();
  EXPECT_EQ(root.get("spp", 256), 64);
  EXPECT_DOUBLE_EQ(root.get("sigma", 1.0), 2.0);
  EXPECT_EQ(root.get("name", "y"), "x");
  EXPECT_EQ(root.get("absent", 7), 7);
  auto r = root.table("render");
  ASSERT_TRUE(r);
  auto v = r->get("size", std::array<double, 3>{0, 0, 0});
  EXPECT_EQ(v[2], 3.0);
  EXPECT_NO_THROW(r->finish());
  EXPECT_NO_THROW(root.finish());
}

TEST(Config, UnknownKeyNamesFileLineKeyAndValidKeys) {
  auto cfg = ConfigFile::parse("spp = 64\nspd = 3\n", "exp.toml");
  auto root = cfg.root();
  root.get("spp", 256);
  root.get("seed", 1);
  std::string msg = error_of([&] { root.finish(); });
  EXPECT_NE(msg.find("exp.toml:2"), std::string::npos) << msg;
  EXPECT_NE(msg.find("'spd'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("seed"), std::string::npos) << msg;
  EXPECT_NE(msg.find("spp"), std::string::npos) << msg;
}

TEST(Config, UnknownKeyInSubTableNamesItsPath) {
  auto cfg = ConfigFile::parse("[camera]\neye = [0, 1, 2]\nfovv = 40\n", "scene.toml");
  auto root = cfg.root();
  auto cam = root.table("camera");
  cam->get("eye", std::array<double, 3>{0, 0, 0});
  cam->get("fov", 39.0);
  std::string msg = error_of([&] { cam->finish(); });
  EXPECT_NE(msg.find("camera.fovv"), std::string::npos) << msg;
}

TEST(Config, WrongTypeIsAnError) {
  auto cfg = ConfigFile::parse("spp = \"many\"\n", "c.toml");
  auto root = cfg.root();
  std::string msg = error_of([&] { root.get("spp", 1); });
  EXPECT_NE(msg.find("c.toml:1"), std::string::npos) << msg;
  EXPECT_NE(msg.find("integer"), std::string::npos) << msg;
}

TEST(Config, SyntaxErrorNamesLine) {
  std::string msg = error_of([] { ConfigFile::parse("a = 1\nb = = 2\n", "bad.toml"); });
  EXPECT_NE(msg.find("bad.toml:2"), std::string::npos) << msg;
}

TEST(Config, MissingFileIsAnInputError) {
  std::string msg = error_of([] { ConfigFile::load("/nonexistent/x.toml"); });
  EXPECT_NE(msg.find("/nonexistent/x.toml"), std::string::npos);
}

// A folder or a device is not a config: it read as an empty file, and the error then blamed a
// missing key on line 1 of a folder (found by a hostile-user pass).
TEST(Config, AFolderOrADeviceIsNotAConfigFile) {
  test::TempDir dir;
  for (const std::string& path : {dir.path().string(), std::string("/dev/null")}) {
    std::string msg = error_of([&] { ConfigFile::load(path); });
    EXPECT_NE(msg.find("'" + path + "': not a regular file"), std::string::npos) << msg;
  }
  EXPECT_NE(error_of([] { ConfigFile::load(std::string(5000, 'c') + ".toml"); }).find("no such file"), std::string::npos);
}

// An integer too large for the type read is an error, never a wrapped value.
TEST(Config, IntegerOutOfIntRangeIsAnErrorNotAWrap) {
  auto cfg = ConfigFile::parse("a = 1\nsegments = 99999999999\n", "s.toml");
  auto root = cfg.root();
  std::string msg = error_of([&] { root.get("segments", 48); });
  EXPECT_NE(msg.find("s.toml:2: key 'segments'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("99999999999"), std::string::npos) << msg;
}

// Bounded reads name file, line and key, the bound and its reason, and what was written.
TEST(Config, BoundedReadsNameTheKeyTheBoundAndWhy) {
  auto cfg = ConfigFile::parse("spp = [16, 1e12]\nseed = -3\nthreads = 4\nr = nan\nc = [1, inf, 0]\n", "b.toml");
  auto root = cfg.root();
  std::string msg = error_of([&] { root.get("spp", std::vector<int>{}, bounds::kSpp); });
  EXPECT_NE(msg.find("b.toml:1: key 'spp'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("1000000000000"), std::string::npos) << msg;
  EXPECT_NE(msg.find(bounds::kSpp.why), std::string::npos) << msg;
  msg = error_of([&] { root.get("seed", std::int64_t(1), bounds::kSeed); });
  EXPECT_NE(msg.find("b.toml:2: key 'seed'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("-3"), std::string::npos) << msg;
  EXPECT_EQ(root.get("threads", 0, bounds::kThreads), 4);
  EXPECT_EQ(root.get("absent", 7, bounds::kThreads), 7);
  msg = error_of([&] { root.get("r", 1.0, bounds::kLength); });
  EXPECT_NE(msg.find("b.toml:4: key 'r'"), std::string::npos) << msg;
  msg = error_of([&] { root.get("c", std::array<double, 3>{0, 0, 0}, bounds::kRadiance); });
  EXPECT_NE(msg.find("b.toml:5: key 'c'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("inf"), std::string::npos) << msg;
}

}  // namespace
}  // namespace dnb
