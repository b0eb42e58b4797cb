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

// Found by a hostile-user pass: `denoise am f.exr -o f.exr` replaced the frame with its
// denoised colour (exit 0), and -o f.edges.exr its edge file. An output that is an input, by
// name, through a symbolic link or a hard link, is bad usage (exit 2) and the input is kept.
TEST(OutputMessages, AnOutputThatIsAnInputIsRefusedAndTheInputKept) {
  test::TempDir dir;
  const std::string frame = dir.file("f.exr"), edges = dir.file("f.edges.exr");
  ASSERT_EQ(test::run_denoisebench("render cornell-box --size 8x6 --spp 2 -o " + frame).exit_code, 0);
  const std::string frame_bytes = test::slurp(frame), edge_bytes = test::slurp(edges);
  fs::create_symlink(frame, dir.file("sym.exr"));
  fs::create_hard_link(frame, dir.file("hard.exr"));
  const struct {
    std::string args, names;
  } cases[] = {
      {"denoise am " + frame + " -o " + frame, "frame"},
      {"denoise am " + frame + " -o " + edges, "frame's edge file"},
      {"denoise am " + frame + " -o " + dir.file("sym.exr"), "frame"},
      {"denoise am " + frame + " -o " + dir.file("hard.exr"), "frame"},
      {"import cycles " + frame + " -o " + frame, "input"},
      // The import writes OUT and OUT's edge file: here the edge file would be the input.
      {"import native " + edges + " -o " + frame, "input"},
  };
  for (const auto& c : cases) {
    auto r = test::run_denoisebench(c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find("is the " + c.names + " '"), std::string::npos) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find("would replace the input"), std::string::npos) << r.output;
  }
  EXPECT_EQ(test::slurp(frame), frame_bytes) << "the frame was changed";
  EXPECT_EQ(test::slurp(edges), edge_bytes) << "the edge file was changed";
  for (const auto& e : fs::directory_iterator(dir.path()))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << "left behind: " << e.path();
}

// A results folder or an error-map folder whose name is taken by a file: exit 1 naming the
// folder and the system's reason (it was a raw "filesystem error: cannot create directories").
TEST(OutputMessages, AFolderThatCannotBeCreatedIsNamedWithTheSystemsReason) {
  test::TempDir dir;
  test::write(dir.file("taken"), "a file, not a folder\n");
  test::write(dir.file("c.toml"), "name = \"c\"\nwidth = 8\nheight = 6\nscenes = [\"cornell-box\"]\nspp = [2]\n"
                                  "methods = [\"bilateral\"]\n");
  auto r = test::run_in(dir, "run " + dir.file("c.toml") + " -o " + dir.file("taken"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("cannot create folder '" + dir.file("taken") + "/images': Not a directory"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("filesystem error"), std::string::npos) << r.output;
  EXPECT_EQ(test::slurp(dir.file("taken")), "a file, not a folder\n");
}

}  // namespace
}  // namespace dnb
