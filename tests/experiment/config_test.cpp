// The experiment config (experiment/config.h) is checked whole before any cell runs: a value out
// of bounds, or a method parameter a method refuses, is an InputError naming the file, the line
// and the key that wrote it (not a command-line flag, and not an hour into the run).
#include <gtest/gtest.h>

#include <filesystem>

#include "core/errors.h"
#include "experiment/config.h"
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

}  // namespace
}  // namespace dnb::experiment
