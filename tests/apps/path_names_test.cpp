// Every value of a config, scene or plug-in manifest that becomes part of a path stays inside the
// folder it is written into (core/file_names.h): a name the user wrote as a name is refused unless
// it is a file name (exit 2, file, line and key, nothing written), a name derived from a path or a
// file's stem is mapped to one. Each run goes from a nested working folder without -o, the way a
// config's `name = "../../x"` once wrote its results two levels above results/.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;

const char* kBody = R"(width = 32
height = 24
spp = [2]
methods = ["bilateral"]
[reference]
spp = 8
block_spp = 8
)";

// Every file under `root`, as paths relative to it.
std::set<std::string> files_under(const fs::path& root) {
  std::set<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(root))
    if (!e.is_directory()) out.insert(fs::relative(e.path(), root).string());
  return out;
}

// Runs `run CONFIG` (and ARGS) from DIR/work/nested, with the render cache in DIR/cache.
test::CommandResult run_nested(const test::TempDir& dir, const std::string& config, const std::string& args = "") {
  const fs::path cwd = dir.path() / "work" / "nested";
  fs::create_directories(cwd);
  return test::run_command("cd '" + cwd.string() + "' && DENOISEBENCH_CACHE='" + dir.file("cache") + "' '" +
                           test::binary().string() + "' run '" + config + "' " + args);
}

// The files a command wrote under DIR, outside the cache, that were not there before.
std::set<std::string> new_files(const std::set<std::string>& before, const fs::path& dir) {
  std::set<std::string> out;
  for (const auto& f : files_under(dir))
    if (!before.count(f) && f.rfind("cache/", 0) != 0) out.insert(f);
  return out;
}

TEST(PathNames, ANameTheUserWroteThatIsNoFileNameIsRefusedNamingTheKeyAndNothingIsWritten) {
  struct Case {
    std::string what, config, key;
  };
  const std::string scene_files = "[[scene]]\nframe = \"in/f.exr\"\nreference = \"in/r.exr\"\n";
  const Case cases[] = {
      {"config name", "name = \"../../x\"\nscenes = [\"cornell-box\"]\n" + std::string(kBody), "c.toml:1: key 'name'"},
      {"config name with a slash", "name = \"a/b\"\nscenes = [\"cornell-box\"]\n" + std::string(kBody), "c.toml:1: key 'name'"},
      {"variant name", "name = \"v\"\nscenes = [\"cornell-box\"]\n" + std::string(kBody) +
                           "[[variant]]\nname = \"../v\"\nmethod = \"bilateral\"\n",
       "c.toml:11: key 'variant[0].name'"},
      {"dot-dot variant name", "name = \"v\"\nscenes = [\"cornell-box\"]\n" + std::string(kBody) +
                                   "[[variant]]\nname = \"..\"\nmethod = \"bilateral\"\n",
       "c.toml:11: key 'variant[0].name'"},
      {"scene label", "name = \"l\"\nmethods = [\"bilateral\"]\n" + scene_files + "label = \"../../l\"\n",
       "c.toml:6: key 'scene[0].label'"},
      {"plug-in name", "name = \"p\"\nplugins = [\"plug\"]\nscenes = [\"cornell-box\"]\n" + std::string(kBody),
       "p.toml:2: key 'plugin.name'"},
  };
  for (const auto& c : cases) {
    test::TempDir dir;
    test::write(dir.path() / "c.toml", c.config);
    test::write(dir.path() / "in" / "f.exr", "not read: the label is refused first");
    test::write(dir.path() / "in" / "r.exr", "not read");
    test::write(dir.path() / "plug" / "p" / "p.toml",
                "[plugin]\nname = \"../p\"\ncommand = [\"/bin/true\"]\nprotocol = \"frame\"\nlayers = [\"color\"]\n");
    fs::create_directories(dir.path() / "work" / "nested");
    const auto before = files_under(dir.path());
    const auto r = run_nested(dir, dir.file("c.toml"));
    EXPECT_EQ(r.exit_code, 2) << c.what << ": " << r.output;
    EXPECT_THAT(r.output, HasSubstr(c.key)) << c.what;
    EXPECT_THAT(r.output, HasSubstr("expected 1 to 120 letters, digits")) << c.what;
    EXPECT_EQ(new_files(before, dir.path()), std::set<std::string>{}) << c.what;
    EXPECT_EQ(files_under(dir.path() / "work"), std::set<std::string>{}) << c.what << ": wrote under the working folder";
  }
}

// A name that is derived, not written as a name, is mapped: a config file named "..toml" (its
// stem "." would make the default folder results/ itself), a scene given as a path with ".."
// in it, and a frame file "..exr" read without a label (its stem "." would make the scene's
// image folder images/ itself). Every file the runs write lies inside their results folder.
TEST(PathNames, ANameDerivedFromAPathIsMappedAndEveryFileLandsInsideTheResultsFolder) {
  test::TempDir dir;
  const fs::path scene = dir.path() / "scenes" / "box.toml";
  fs::create_directories(scene.parent_path());
  fs::copy_file(fs::path(test::source_dir()) / "configs" / "scenes" / "cornell-box.toml", scene);
  const std::string scene_by_path = (dir.path() / "scenes" / ".." / "scenes" / "box.toml").string();
  test::write(dir.path() / "..toml", "scenes = [\"" + scene_by_path + "\"]\n" + std::string(kBody));
  auto before = files_under(dir.path());
  auto r = run_nested(dir, dir.file("..toml"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto wrote = new_files(before, dir.path());
  ASSERT_FALSE(wrote.empty());
  for (const auto& f : wrote) EXPECT_EQ(f.rfind("work/nested/results/_/", 0), 0u) << f << " is outside results/_";
  const fs::path out = dir.path() / "work" / "nested" / "results" / "_";
  const auto res = nlohmann::json::parse(test::slurp(out / "results.json"));
  EXPECT_EQ(res["config"]["name"], "_");
  nlohmann::json input;
  for (const auto& rec : res["records"]) {
    EXPECT_EQ(rec["scene"], scene_by_path) << "the record keeps the scene's own name";
    if (rec["method"] == "input") input = rec;
  }
  ASSERT_TRUE(input["files"].contains("frame")) << input.dump();
  const std::string image_dir = fs::path(input["reference"]["image"].get<std::string>()).parent_path().string();
  EXPECT_EQ(fs::path(image_dir).parent_path(), "images") << image_dir << ": the scene's folder is one component";

  // The frame (with its edge file) and reference again, as files: "..exr" without a label.
  fs::create_directories(dir.path() / "in");
  const fs::path frame = out / input["files"]["frame"].get<std::string>();
  fs::copy_file(frame, dir.path() / "in" / "..exr");
  fs::copy_file(fs::path(frame).replace_extension(".edges.exr"), dir.path() / "in" / "..edges.exr");
  fs::copy_file(out / input["reference"]["image"].get<std::string>(), dir.path() / "in" / "ref.exr");
  test::write(dir.path() / "files.toml",
              "methods = [\"bilateral\"]\n[[scene]]\nframe = \"in/..exr\"\nreference = \"in/ref.exr\"\n");
  before = files_under(dir.path());
  r = run_nested(dir, dir.file("files.toml"), "-o ../files-out");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  wrote = new_files(before, dir.path());
  ASSERT_FALSE(wrote.empty());
  for (const auto& f : wrote) {
    const std::string folder = fs::path(f).parent_path().string();
    EXPECT_TRUE(folder == "work/files-out" || folder == "work/files-out/images/_" || folder == "work/files-out/frames/_")
        << f << " is outside the results folder's own files and the scene's folders";
  }
  const auto again = nlohmann::json::parse(test::slurp(dir.path() / "work" / "files-out" / "results.json"));
  ASSERT_FALSE(again["records"].empty());
  for (const auto& rec : again["records"]) EXPECT_EQ(rec["scene"], "_");
}

// Two scenes whose folder names would coincide once mapped are refused, naming both.
TEST(PathNames, TwoScenesThatWouldShareAFolderAreRefused) {
  test::TempDir dir;
  for (const char* sub : {"a b", "a_b"}) {
    fs::create_directories(dir.path() / sub);
    fs::copy_file(fs::path(test::source_dir()) / "configs" / "scenes" / "cornell-box.toml", dir.path() / sub / "s.toml");
  }
  test::write(dir.path() / "c.toml", "name = \"two\"\nscenes = [\"" + dir.file("a b/s.toml") + "\", \"" +
                                         dir.file("a_b/s.toml") + "\"]\n" + std::string(kBody));
  const auto r = run_nested(dir, dir.file("c.toml"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_THAT(r.output, HasSubstr("would share the folder name"));
  EXPECT_THAT(r.output, HasSubstr("c.toml:2: key 'scenes'"));
  EXPECT_FALSE(fs::exists(dir.path() / "work" / "nested" / "results"));
}

}  // namespace
}  // namespace dnb
