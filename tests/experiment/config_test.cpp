// The experiment config (experiment/config.h) is checked whole before any cell runs: a value out
// of bounds, or a method parameter a method refuses, is an InputError naming the file, the line
// and the key that wrote it (not a command-line flag, and not an hour into the run).
#include <gtest/gtest.h>

#include <map>

#include <filesystem>
#include <tuple>

#include "core/errors.h"
#include "core/exr_io.h"
#include "core/hash.h"
#include "experiment/config.h"
#include "experiment/input_files.h"
#include "test_util.h"

namespace dnb::experiment {
namespace {

// A small valid config; `extra` is appended (root keys first: callers put tables last).
std::string config_text(const std::string& root_keys, const std::string& tables = "") {
  return "name = \"t\"\nscenes = [\"cornell-box\"]\nmethods = [\"bilateral\"]\n" + root_keys + "\n" + tables;
}

// The message of the InputError that loading the config throws ("" when it loads).
std::string load_error(const test::TempDir& dir, const std::string& text) {
  const std::string path = dir.file("exp.toml");
  test::write(path, text);
  try {
    load_config(path);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

bool names(const std::string& msg, const std::string& what) { return msg.find(what) != std::string::npos; }

TEST(ExperimentConfig, ValidConfigLoads) {
  test::TempDir dir;
  EXPECT_EQ(load_error(dir, config_text("spp = [4, 16]\nwidth = 8\nheight = 6")), "");
}

// Each of these was accepted (or wrapped) by the loader and failed only when work started.
TEST(ExperimentConfig, AScenesReferenceCanHaveItsOwnSpp) {
  test::TempDir dir;
  const std::string path = dir.file("exp.toml");
  test::write(path, "name = \"t\"\nscenes = [\"cornell-box\", \"sponza\"]\nmethods = [\"bilateral\"]\n"
                    "[reference]\nspp = 256\n[reference.scene.sponza]\nspp = 4096\n");
  const ExperimentConfig c = load_config(path);
  EXPECT_EQ(c.reference_spp_for("cornell-box"), 256);
  EXPECT_EQ(c.reference_spp_for("sponza"), 4096);
  EXPECT_EQ(c.recorded().reference_scene_spp, (std::map<std::string, int>{{"sponza", 4096}}));
  // A scene the config does not render, a value that is not a table, an spp out of bounds, an
  // unknown key: each names the file, line and key.
  const std::string head = "name = \"t\"\nscenes = [\"cornell-box\"]\nmethods = [\"bilateral\"]\n[reference]\n";
  std::string msg = load_error(dir, head + "[reference.scene.sponza]\nspp = 4096\n");
  EXPECT_TRUE(names(msg, "exp.toml:5") && names(msg, "'sponza' is not a rendered scene of this config")) << msg;
  msg = load_error(dir, head + "scene = { cornell-box = 7 }\n");
  EXPECT_TRUE(names(msg, "exp.toml:5") && names(msg, "key 'reference.scene.cornell-box': expected a table")) << msg;
  msg = load_error(dir, head + "[reference.scene.cornell-box]\nspp = 0\n");
  EXPECT_TRUE(names(msg, "exp.toml:6") && names(msg, "spp")) << msg;
  msg = load_error(dir, head + "[reference.scene.cornell-box]\nsamples = 64\n");
  EXPECT_TRUE(names(msg, "exp.toml:6") && names(msg, "samples")) << msg;
}

TEST(ExperimentConfig, OutOfBoundsValuesNameFileLineAndKey) {
  test::TempDir dir;
  const std::string file = dir.file("exp.toml");
  struct Case {
    std::string root, tables, where;
  };
  const Case cases[] = {
      {"spp = [1e12]", "", ":4: key 'spp'"},
      {"spp = [16, -1]", "", ":4: key 'spp'"},
      {"width = 0", "", ":4: key 'width'"},
      {"height = 99999999999", "", ":4: key 'height'"},
      {"threads = -1", "", ":4: key 'threads'"},
      {"threads = 100000", "", ":4: key 'threads'"},
      {"max_depth = 0", "", ":4: key 'max_depth'"},
      {"seed = -5", "", ":4: key 'seed'"},
      {"", "[reference]\nblock_spp = 0", ":6: key 'reference.block_spp'"},
      {"", "[reference]\nseed = -1", ":6: key 'reference.seed'"},
      {"", "[timing]\nrepeats = 0", ":6: key 'timing.repeats'"},
      {"", "[speedup]\nspp = [1, 1e12]", ":6: key 'speedup.spp'"},
  };
  for (const Case& c : cases) {
    const std::string msg = load_error(dir, config_text(c.root, c.tables));
    EXPECT_TRUE(names(msg, file + c.where)) << c.root << c.tables << " -> '" << msg << "'";
    EXPECT_FALSE(names(msg, "--")) << "names a command-line flag: " << msg;
  }
}

// A bad method parameter names where it was written: [params.NAME] or a [[variant]]'s set.
TEST(ExperimentConfig, MethodParameterErrorsNameFileLineAndKey) {
  test::TempDir dir;
  const std::string file = dir.file("exp.toml");
  std::string msg = load_error(dir, config_text("", "[params.bilateral]\nsigma_space = -3\n"));
  EXPECT_TRUE(names(msg, file + ":6: key 'params.bilateral.sigma_space'")) << msg;
  msg = load_error(dir, config_text("", "[params.bilateral]\nno_such = 1\n"));
  EXPECT_TRUE(names(msg, file + ":6: key 'params.bilateral.no_such'")) << msg;
  msg = load_error(dir, config_text("", "[[variant]]\nname = \"v\"\nmethod = \"bilateral\"\nset = { no_such = 2 }\n"));
  EXPECT_TRUE(names(msg, file + ":8: key 'variant[0].set.no_such'")) << msg;
  EXPECT_TRUE(names(msg, "no_such")) << msg;
}

// The bounds refuse nothing the repository's own configs use.
TEST(ExperimentConfig, TheRepositorysConfigsLoad) {
  int loaded = 0;
  for (const auto& e : std::filesystem::directory_iterator(test::source_dir() + "/configs"))
    if (e.path().extension() == ".toml") {
      EXPECT_NO_THROW(load_config(e.path().string())) << e.path();
      ++loaded;
    }
  EXPECT_GE(loaded, 3);
}

// [[scene]] frame/reference: files beside the config (frames/in.exr, frames/ref.exr), written here.
void write_test_frame(const std::string& path, int w, int h, int spp, float value = 0.5f) {
  AovFrame f(w, h);
  Image c(w, h, 3);
  for (std::size_t i = 0; i < c.size(); ++i) c.data()[i] = value;
  f.set(layer::kColor, c);
  f.meta.spp = spp;
  write_frame(f, path);
}

const char* kFileScene = "[[scene]]\nframe = \"frames/in.exr\"\nreference = \"frames/ref.exr\"\n";

std::string file_config(const std::string& scene = kFileScene, const std::string& root = "") {
  return "name = \"f\"\nmethods = [\"bilateral\"]\n" + root + scene;
}

TEST(ExperimentConfig, ASceneReadFromFilesHasItsFramesSizeSppAndContentHashes) {
  test::TempDir dir;
  std::filesystem::create_directories(dir.path() / "frames");
  write_test_frame(dir.file("frames/in.exr"), 32, 24, 4);
  write_test_frame(dir.file("frames/ref.exr"), 32, 24, 64);
  test::write(dir.file("exp.toml"), file_config());
  const ExperimentConfig c = load_config(dir.file("exp.toml"));
  ASSERT_EQ(c.scenes.size(), 1u);
  ASSERT_TRUE(c.scenes[0].files);
  const SceneFiles& f = *c.scenes[0].files;
  EXPECT_EQ(c.scenes[0].name, "in");  // the frame's stem when no label is given
  EXPECT_EQ(f.frame, dir.file("frames/in.exr"));
  EXPECT_EQ(f.reference, dir.file("frames/ref.exr"));
  EXPECT_EQ(std::tuple(f.width, f.height, f.spp), std::tuple(32, 24, 4));
  EXPECT_EQ(f.reference_hash, sha256_file(dir.file("frames/ref.exr")));
  EXPECT_TRUE(c.spp.empty()) << "no rendered scene: no rendered spp";
  const RunConfig r = c.recorded();
  EXPECT_EQ(r.spp, std::vector<int>{4});  // the tables are drawn at the file scene's spp
  EXPECT_EQ(r.scenes, std::vector<std::string>{"in"});
  EXPECT_EQ(r.scene_files.at("in").frame, f.frame);
  EXPECT_EQ(std::tuple(r.width, r.height), std::tuple(32, 24));
  // Another frame's bytes: another hash (the cells are keyed by it).
  const std::string before = f.frame_hash;
  write_test_frame(dir.file("frames/in.exr"), 32, 24, 4, 0.25f);
  EXPECT_NE(load_config(dir.file("exp.toml")).scenes[0].files->frame_hash, before);
  // Rendered and file scenes together, with a label; spp given for a frame that records it agrees.
  test::write(dir.file("exp.toml"), "name = \"m\"\nscenes = [\"cornell-box\"]\nspp = [8]\nmethods = [\"bilateral\"]\n" +
                                        std::string(kFileScene) + "label = \"mine\"\nspp = 4\n[[scene]]\nname = \"conference\"\n");
  const ExperimentConfig m = load_config(dir.file("exp.toml"));
  ASSERT_EQ(m.scenes.size(), 3u);
  EXPECT_EQ(m.scenes[1].name, "mine");
  EXPECT_FALSE(m.scenes[2].files);
  EXPECT_EQ(m.recorded().spp, (std::vector<int>{8, 4}));
  EXPECT_EQ(m.recorded().scenes, (std::vector<std::string>{"cornell-box", "mine", "conference"}));
}

// `second`: the same view rendered with another seed becomes the frame's half buffers and gives
// its variance (import --second), so the methods that need them run on a file scene; the spp is
// the two files' sum, the cells are keyed by both files, and the results record the second.
TEST(ExperimentConfig, ASecondSeedMakesAFileScenesHalfBuffers) {
  test::TempDir dir;
  std::filesystem::create_directories(dir.path() / "frames");
  write_test_frame(dir.file("frames/in.exr"), 32, 24, 4, 0.5f);
  write_test_frame(dir.file("frames/in2.exr"), 32, 24, 4, 0.25f);
  write_test_frame(dir.file("frames/ref.exr"), 32, 24, 64);
  test::write(dir.file("one.toml"), file_config());
  test::write(dir.file("two.toml"), file_config(std::string(kFileScene) + "second = \"frames/in2.exr\"\n"));
  const ExperimentConfig one = load_config(dir.file("one.toml")), two = load_config(dir.file("two.toml"));
  const SceneFiles& f = *two.scenes[0].files;
  EXPECT_EQ(f.second, dir.file("frames/in2.exr"));
  EXPECT_EQ(f.spp, 8);
  EXPECT_NE(f.frame_hash, one.scenes[0].files->frame_hash);
  EXPECT_EQ(two.recorded().scene_files.at("in").second, f.second);
  const AovFrame frame = read_input_frame(f.frame, f.input_format, 0, f.second);
  EXPECT_EQ(frame.layer("half0.color").at(3, 2, 0), 0.5f);
  EXPECT_EQ(frame.layer("half1.color").at(3, 2, 0), 0.25f);
  EXPECT_FLOAT_EQ(frame.layer(layer::kColor).at(3, 2, 0), 0.375f);
  EXPECT_FLOAT_EQ(frame.layer(layer::kVariance).at(3, 2, 0), 0.25f * 0.25f / 4);
  // The same file twice is refused, naming the key.
  test::write(dir.file("same.toml"), file_config(std::string(kFileScene) + "second = \"frames/in.exr\"\n"));
  const std::string msg = test::error_of<InputError>([&] { load_config(dir.file("same.toml")); });
  EXPECT_NE(msg.find("same.toml:6: key"), std::string::npos) << msg;  // the `second` line
  EXPECT_NE(msg.find("second"), std::string::npos) << msg;
  EXPECT_NE(msg.find("another seed"), std::string::npos) << msg;
}

TEST(ExperimentConfig, SceneFileErrorsNameTheKeyAndTheFile) {
  test::TempDir dir;
  std::filesystem::create_directories(dir.path() / "frames");
  write_test_frame(dir.file("frames/in.exr"), 32, 24, 4);
  write_test_frame(dir.file("frames/ref.exr"), 32, 24, 64);
  write_test_frame(dir.file("frames/small.exr"), 16, 12, 64);
  write_test_frame(dir.file("frames/nospp.exr"), 32, 24, 0);
  const std::string file = dir.file("exp.toml");
  struct Case {
    std::string text, where, what;
  };
  const Case cases[] = {
      {file_config("[[scene]]\nframe = \"frames/gone.exr\"\nreference = \"frames/ref.exr\"\n"), ":4: key 'scene[0].frame'",
       dir.file("frames/gone.exr") + "' does not exist"},
      {file_config("[[scene]]\nframe = \"frames/in.exr\"\nreference = \"frames/gone.exr\"\n"),
       ":5: key 'scene[0].reference'", dir.file("frames/gone.exr")},
      {file_config("[[scene]]\nname = \"cornell-box\"\nframe = \"frames/in.exr\"\n"), ":5: key 'scene[0].frame'", "not both"},
      {file_config("[[scene]]\nframe = \"frames/in.exr\"\n"), ":4: key 'scene[0].frame'", "reference"},
      {file_config("[[scene]]\nreference = \"frames/ref.exr\"\n"), ":4: key 'scene[0].reference'", "without a frame"},
      {file_config("[[scene]]\nframe = \"frames/in.exr\"\nreference = \"frames/small.exr\"\n"),
       ":5: key 'scene[0].reference'", dir.file("frames/small.exr") + "' is 16x12, its frame '" + dir.file("frames/in.exr") + "' is 32x24"},
      {file_config("[[scene]]\nframe = \"frames/nospp.exr\"\nreference = \"frames/ref.exr\"\n"), ":4: key 'scene[0].frame'",
       "records no sample count"},
      {file_config(std::string(kFileScene) + "spp = 8\n"), ":6: key 'scene[0].spp'", dir.file("frames/in.exr") + "' records 4 spp"},
      {file_config(std::string(kFileScene) + "colour = 1\n"), ":6: unknown key 'scene[0].colour'", "valid keys"},
      {file_config(kFileScene, "width = 64\n"), ":3: key 'width'", "read from files"},
      {file_config(kFileScene, "[speedup]\nspp = [1]\n"), ":3: key 'speedup'", "read from files"},
      {file_config(std::string(kFileScene) + kFileScene), "", "scene 'in' is named twice"},
      {file_config("[[scene]]\nlabel = \"x\"\n"), ":3: key 'scene[0].name'", "expected `name`"},
  };
  for (const Case& c : cases) {
    const std::string msg = load_error(dir, c.text);
    EXPECT_TRUE(names(msg, file + c.where)) << c.text << " -> '" << msg << "'";
    EXPECT_TRUE(names(msg, c.what)) << c.text << " -> '" << msg << "'";
  }
}

}  // namespace
}  // namespace dnb::experiment
