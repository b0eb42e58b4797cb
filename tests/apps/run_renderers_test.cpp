// `denoisebench run` on scenes a renderer back-end renders (docs/renderers.md): a fake back-end
// the test writes (failures stay in their scene's cells), and the real Mitsuba 3 back-end of
// renderers/mitsuba on a tiny Cornell box (inputs of three seeds as two halves, the reference,
// the curve and every method, then a second run that renders nothing).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <set>

#include <nlohmann/json.hpp>

#include "core/exr_io.h"
#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;
using test::run_in;
using test::slurp;
using test::write;

// Colour: a seed-dependent grey with per-pixel noise (numpy's generator of the request's seed),
// so that two halves differ; the scene file says what to do: "ok", "error" (a message naming
// the file), "die" (exit without answering on 1-spp renders: the input halves of a 2-spp input).
const char* kFake = R"PY(import os
import numpy as np
from denoisebench_renderer import run, write_layers

def render(req, state):
    what = open(req["scene"]).read().strip()
    if what == "error":
        raise ValueError(f"{req['scene']}: line 1: unknown element <sceen>")
    if what == "die" and req["spp"] == 1:
        os._exit(3)
    h, w = req["height"], req["width"]
    rng = np.random.default_rng(req["seed"])
    c = (0.5 + 0.1 * rng.standard_normal((h, w, 3))).astype(np.float32)
    z = np.zeros((h, w, 3), np.float32)
    n = np.dstack([z[:, :, 0], z[:, :, 0], z[:, :, 0] + 1])
    write_layers(req["output"], {"color": c, "direct": c, "indirect": z, "albedo": z + 1, "reflection": z,
                                 "emission": z, "normal": n, "depth": z[:, :, :1] + 2})
    return {"render_seconds": 0.01}

run(render, version=lambda: "fake 1")
)PY";

const char* kFakeManifest = R"([renderer]
name = "fake"
command = ["/usr/bin/python3", "fake.py"]
version = ["/usr/bin/python3", "fake.py", "--version"]
layers = ["color", "direct", "indirect", "albedo", "reflection", "emission", "normal", "depth"]
timeout_seconds = 60
)";

TEST(RunRenderers, ABackendThatFailsOrDiesFailsOnlyItsScenesCells) {
  test::TempDir dir;
  write(dir.path() / "backends/fake/fake.py", kFake);
  write(dir.path() / "backends/fake/fake.toml", kFakeManifest);
  for (const char* s : {"ok", "error", "die"}) write(dir.path() / (std::string(s) + ".scene"), std::string(s) + "\n");
  write(dir.path() / "c.toml", R"(name = "fake"
width = 8
height = 6
seeds = [1, 2]
spp = [2]
methods = ["bilateral", "nfor", "svgf"]
renderers = ["backends"]
[reference]
spp = 4
block_spp = 2
[speedup]
spp = [2]
[[scene]]
renderer = "fake"
file = "ok.scene"
[[scene]]
renderer = "fake"
file = "error.scene"
[[scene]]
renderer = "fake"
file = "die.scene"
)");
  const auto r = run_in(dir, "run " + dir.file("c.toml") + " -o " + dir.file("out"));
  EXPECT_EQ(r.exit_code, 1) << r.output;  // failed cells: exit 1, every other cell kept
  const auto res = nlohmann::json::parse(slurp(dir.file("out/results.json")));
  std::map<std::string, int> records, failures;
  for (const auto& rec : res["records"]) ++records[rec["scene"].get<std::string>()];
  for (const auto& f : res["failures"]) ++failures[f["scene"].get<std::string>()];
  // ok: the curve's point, then per seed the input and three methods.
  EXPECT_EQ(records["ok"], 1 + 2 * 4) << r.output;
  EXPECT_EQ(failures["ok"], 0);
  // error: its reference fails, and with it every cell, each with the back-end's message.
  EXPECT_EQ(records["error"], 0);
  EXPECT_EQ(failures["error"], 1 + 2 * 4);
  // die: the curve and the reference render; the worker dies on the inputs' halves.
  EXPECT_EQ(records["die"], 1);
  EXPECT_EQ(failures["die"], 2 * 4);
  for (const auto& f : res["failures"]) {
    const std::string reason = f["reason"].get<std::string>();
    EXPECT_THAT(reason, HasSubstr("renderer 'fake'"));
    if (f["scene"] == "error") {
      EXPECT_THAT(reason, HasSubstr(dir.file("error.scene") + ": line 1: unknown element <sceen>"));
    } else if (f["scene"] == "die") {
      EXPECT_THAT(reason, ::testing::AnyOf(HasSubstr("ended before answering"), HasSubstr("died twice")));
    }
  }
  EXPECT_EQ(res["config"]["scene_renderers"]["ok"]["renderer"], "fake");
  EXPECT_EQ(res["config"]["scene_renderers"]["ok"]["file"], dir.file("ok.scene"));
}

TEST(RunRenderers, ConfigErrorsNameTheKey) {
  test::TempDir dir;
  write(dir.path() / "box.xml", "<scene/>\n");
  const std::string head = "width = 8\nheight = 6\nspp = [2]\nmethods = [\"bilateral\"]\n";
  write(dir.path() / "a.toml", head + "[[scene]]\nrenderer = \"nosuch\"\nfile = \"box.xml\"\n");
  auto r = run_in(dir, "run " + dir.file("a.toml") + " -o " + dir.file("out"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.output, HasSubstr("renderer 'nosuch' is not a back-end found in"));
  EXPECT_THAT(r.output, HasSubstr("mitsuba"));  // the repository's back-ends are listed
  write(dir.path() / "b.toml", head + "[[scene]]\nrenderer = \"mitsuba\"\nfile = \"nothere.xml\"\n");
  r = run_in(dir, "run " + dir.file("b.toml") + " -o " + dir.file("out"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.output, HasSubstr("b.toml:7: key 'scene[0].file': file '" + dir.file("nothere.xml") + "' does not exist"));
  write(dir.path() / "c.toml", head + "[[scene]]\nfile = \"box.xml\"\n");
  r = run_in(dir, "run " + dir.file("c.toml") + " -o " + dir.file("out"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.output, HasSubstr("needs `renderer = \"NAME\"`"));
  write(dir.path() / "d.toml", "width = 8\nheight = 6\nspp = [3]\n[[scene]]\nrenderer = \"mitsuba\"\nfile = \"box.xml\"\n");
  r = run_in(dir, "run " + dir.file("d.toml") + " -o " + dir.file("out"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.output, HasSubstr("takes an even spp"));
  // `scene` (one of the tracer's scenes, exported by the run) or `file`, one of the two; a scene
  // that does not load is named at its key.
  write(dir.path() / "e.toml", head + "[[scene]]\nrenderer = \"mitsuba\"\nfile = \"box.xml\"\nscene = \"cornell-box\"\n");
  r = run_in(dir, "run " + dir.file("e.toml") + " -o " + dir.file("out"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.output, HasSubstr("give one of the two"));
  write(dir.path() / "f.toml", head + "[[scene]]\nrenderer = \"mitsuba\"\nscene = \"no-such-scene\"\n");
  r = run_in(dir, "run " + dir.file("f.toml") + " -o " + dir.file("out"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.output, HasSubstr("f.toml:7: key 'scene[0].scene': scene 'no-such-scene'"));
}

// ---- the Mitsuba 3 back-end ----

// A Cornell-like box in Mitsuba 3's XML: diffuse walls, a diffuse block, a rough gold block (its
// light in the reflection layer), an area light.
const char* kBoxXml = R"(<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="39.3"/>
    <transform name="to_world"><lookat origin="0, 0, 3.9" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"/>
    <film type="hdrfilm"/>
  </sensor>
  <bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.75, 0.75, 0.75"/></bsdf>
  <bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.63, 0.07, 0.05"/></bsdf>
  <bsdf type="diffuse" id="green"><rgb name="reflectance" value="0.14, 0.45, 0.09"/></bsdf>
  <bsdf type="roughconductor" id="gold"><string name="material" value="Au"/><float name="alpha" value="0.2"/></bsdf>
  <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="-90"/><translate y="-1"/></transform><ref id="white"/></shape>
  <shape type="rectangle"><transform name="to_world"><rotate x="1" angle="90"/><translate y="1"/></transform><ref id="white"/></shape>
  <shape type="rectangle"><transform name="to_world"><translate z="-1"/></transform><ref id="white"/></shape>
  <shape type="rectangle"><transform name="to_world"><rotate y="1" angle="90"/><translate x="-1"/></transform><ref id="red"/></shape>
  <shape type="rectangle"><transform name="to_world"><rotate y="1" angle="-90"/><translate x="1"/></transform><ref id="green"/></shape>
  <shape type="cube"><transform name="to_world"><scale x="0.3" y="0.6" z="0.3"/><rotate y="1" angle="20"/><translate x="-0.35" y="-0.4" z="-0.3"/></transform><ref id="white"/></shape>
  <shape type="cube"><transform name="to_world"><scale value="0.3"/><rotate y="1" angle="-18"/><translate x="0.35" y="-0.7" z="0.25"/></transform><ref id="gold"/></shape>
  <shape type="rectangle">
    <transform name="to_world"><scale x="0.25" y="0.25"/><rotate x="1" angle="90"/><translate y="0.99"/></transform>
    <emitter type="area"><rgb name="radiance" value="17, 12, 4"/></emitter>
  </shape>
</scene>
)";

// Every method of the registry that is not an OpenCL one (am_opencv compiles kernels for
// minutes on a cold PoCL cache); irradiance_cache is listed to check that it is skipped.
const char* kMitsubaConfig = R"(name = "mitsuba"
width = 32
height = 24
seeds = [1, 2, 3]
spp = [4]
max_depth = 6
methods = ["am", "atrous", "bilateral", "guided", "nlmeans", "proposed", "svgf", "nfor", "kpcn", "unet", "oidn", "irradiance_cache"]
[reference]
spp = 16
block_spp = 8
[speedup]
spp = [2, 4]
[timing]
repeats = 1
[[scene]]
renderer = "mitsuba"
file = "box.xml"
)";

// Why the Mitsuba test cannot run here, or "" when it can.
std::string mitsuba_missing() {
  const std::string py = test::source_dir() + "/.venv/bin/python";
  if (!fs::exists(py)) return "no " + py + " (scripts/setup makes .venv with Mitsuba 3)";
  const auto r = test::run_command("'" + py + "' -c 'import mitsuba; mitsuba.set_variant(\"scalar_rgb\")'");
  if (r.exit_code != 0) return "Mitsuba 3 is not importable from .venv (run scripts/setup): " + r.output;
  return "";
}

std::size_t entries(const fs::path& cache) {
  std::size_t n = 0;
  if (fs::exists(cache))
    for (const auto& kind : fs::directory_iterator(cache))
      if (kind.is_directory())
        for (const auto& e : fs::directory_iterator(kind.path())) n += e.is_directory() && e.path().filename().string()[0] != '.';
  return n;
}

TEST(RunRenderers, MitsubaRendersInputsReferenceCurveAndEveryMethodThenReusesTheCache) {
  if (const std::string why = mitsuba_missing(); !why.empty()) GTEST_SKIP() << why;
  test::TempDir dir;
  write(dir.path() / "box.xml", kBoxXml);
  write(dir.path() / "m.toml", kMitsubaConfig);
  auto r = run_in(dir, "run " + dir.file("m.toml") + " -o " + dir.file("first"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto first = nlohmann::json::parse(slurp(dir.file("first/results.json")));
  EXPECT_TRUE(first["failures"].empty()) << first["failures"].dump(1);
  // irradiance_cache renders with the tracer: skipped, once per seed, with the reason.
  ASSERT_EQ(first["skipped"].size(), 3u);
  EXPECT_THAT(first["skipped"][0]["reason"].get<std::string>(), HasSubstr("rendered by renderer 'mitsuba'"));
  std::set<std::pair<std::string, std::uint64_t>> cells;  // (method, seed), plain points by spp
  std::set<int> curve;
  for (const auto& rec : first["records"]) {
    EXPECT_EQ(rec["reference"]["spp"], 16);
    EXPECT_FALSE(rec["reference"]["cache_hit"].get<bool>());
    EXPECT_FALSE(rec["input_cache_hit"].get<bool>()) << rec["method"];
    ASSERT_TRUE(rec["metrics"]["mse"].is_number()) << rec.dump();
    if (rec["role"] == "plain") {
      curve.insert(rec["spp"].get<int>());
      continue;
    }
    cells.emplace(rec["method"].get<std::string>(), rec["seed"].get<std::uint64_t>());
  }
  EXPECT_EQ(curve, (std::set<int>{2, 4}));
  for (const char* m : {"input", "am", "atrous", "bilateral", "guided", "nlmeans", "proposed", "svgf", "nfor", "kpcn", "unet", "oidn"})
    for (std::uint64_t seed : {1, 2, 3}) EXPECT_TRUE(cells.count({m, seed})) << m << " seed " << seed;
  // An input frame is two halves (half buffers) with the variances they give.
  const ExrChannels frame = read_exr_channels(dir.file("first/frames/box/input_4_s2.exr"), false);
  for (const char* c : {"half0.color.R", "half1.color.R", "half0.albedo.R", "variance.R", "direct_variance.R", "direct.R",
                        "indirect.R", "reflection.R", "normal.X", "depth.Z"})
    EXPECT_TRUE(frame.has(c)) << c;
  EXPECT_TRUE(fs::exists(dir.file("first/images/box/reference.exr")));

  // A second run into another folder: every render comes from the cache, nothing new is stored.
  const std::size_t cached = entries(dir.path() / "cache");
  r = run_in(dir, "run " + dir.file("m.toml") + " -o " + dir.file("second"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(entries(dir.path() / "cache"), cached);
  EXPECT_THAT(r.output, ::testing::Not(HasSubstr("reference block")));  // no block rendered
  const auto second = nlohmann::json::parse(slurp(dir.file("second/results.json")));
  ASSERT_EQ(second["records"].size(), first["records"].size());
  for (std::size_t i = 0; i < second["records"].size(); ++i) {
    const auto& a = first["records"][i];
    const auto& b = second["records"][i];
    EXPECT_TRUE(b["input_cache_hit"].get<bool>()) << b["method"] << " " << b["spp"];
    EXPECT_TRUE(b["reference"]["cache_hit"].get<bool>());
    // The same pixels: the renders it read are the first run's.
    if (b["role"] != "method") {
      EXPECT_EQ(b["metrics"]["mse_hdr"], a["metrics"]["mse_hdr"]) << b["method"];
    }
  }
}

}  // namespace
}  // namespace dnb
