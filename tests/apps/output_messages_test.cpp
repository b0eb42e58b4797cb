// What a user reads when an output cannot be written: an unsupported extension is bad usage
// (exit 2) naming the path as typed and what is accepted, checked before the render; a system
// failure is exit 1 naming the destination (never the temporary file) and the system's reason.
#include <gtest/gtest.h>

#include <filesystem>

#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;

TEST(OutputMessages, UnsupportedExtensionNamesThePathAndTheAcceptedOne) {
  test::TempDir dir;
  for (const std::string name : {"out.png", "out.xyz", "out"}) {
    for (const std::string cmd : {"render", "reference"}) {
      const std::string out = dir.file(name);
      auto r = test::run_denoisebench(cmd + " cornell-box --size 8x6 --spp 2 -o " + out);
      EXPECT_EQ(r.exit_code, 2) << cmd << " " << name << "\n" << r.output;
      EXPECT_NE(r.output.find("'" + out + "'"), std::string::npos) << r.output;
      EXPECT_NE(r.output.find(".exr"), std::string::npos) << r.output;
      EXPECT_EQ(r.output.find(".tmp-"), std::string::npos) << "names the temporary file: " << r.output;
      EXPECT_EQ(r.output.find("render cornell-box 8x6"), std::string::npos) << "rendered first: " << r.output;
    }
  }
  for (const auto& e : fs::directory_iterator(dir.path())) ADD_FAILURE() << "left behind: " << e.path();
}

// The destination is a folder, or its folder is a regular file: the system's reason is given.
TEST(OutputMessages, CannotWriteCarriesTheSystemsReason) {
  test::TempDir dir;
  fs::create_directory(dir.file("taken.exr"));
  test::write(dir.file("plain"), "a file, not a folder\n");
  const struct {
    std::string out, reason;
  } cases[] = {{dir.file("taken.exr"), "Is a directory"}, {dir.file("plain") + "/f.exr", "Not a directory"}};
  for (const auto& c : cases) {
    auto r = test::run_denoisebench("render cornell-box --size 8x6 --spp 2 -o " + c.out);
    EXPECT_EQ(r.exit_code, 1) << c.out << "\n" << r.output;
    EXPECT_NE(r.output.find("cannot write"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(c.reason), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find(".tmp-"), std::string::npos) << "names the temporary file: " << r.output;
  }
  // Nothing but what the test made is left.
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir.path())) ++entries, (void)e;
  EXPECT_EQ(entries, 2);
  EXPECT_TRUE(fs::is_empty(dir.file("taken.exr")));
}

}  // namespace
}  // namespace dnb
