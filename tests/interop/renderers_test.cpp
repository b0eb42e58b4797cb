// The renderer back-end protocol (interop/renderers.h, docs/renderers.md) against a fake back-end
// the test writes: a Python worker on the harness's helper (renderers/denoisebench_renderer.py)
// that logs every request and answers by what the scene file says ("ok", "error", "size", "die").
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>

#include <nlohmann/json.hpp>

#include "core/errors.h"
#include "core/line_worker.h"
#include "interop/renderers.h"
#include "test_util.h"

namespace dnb::interop {
namespace {
namespace fs = std::filesystem;
using ::testing::HasSubstr;
using test::write;

// Renders a frame whose colour is seed / 1000 + spp everywhere (so the test can tell which
// request made it), the other layers constants; logs the request beside the scene file.
const char* kFakeBackend = R"PY(import json, os, sys
import numpy as np
from denoisebench_renderer import run, write_layers

def render(req, state):
    with open(req["scene"] + ".requests", "a") as log:
        log.write(json.dumps(req) + "\n")
    what = open(req["scene"]).read().strip()
    if what == "error":
        raise ValueError(f"{req['scene']}: line 1: not a scene this back-end reads")
    if what == "die":
        os._exit(3)
    w, h = (2, 2) if what == "size" else (req["width"], req["height"])
    c = np.full((h, w, 3), req["seed"] / 1000.0 + req["spp"], np.float32)
    layers = {"color": c, "albedo": np.full((h, w, 3), 0.5, np.float32), "direct": c, "indirect": 0 * c,
              "reflection": 0 * c, "emission": 0 * c, "normal": np.dstack([0 * c[:, :, 0], 0 * c[:, :, 0], 1 + 0 * c[:, :, 0]]),
              "depth": np.ones((h, w, 1), np.float32)}
    write_layers(req["output"], {k: v for k, v in layers.items() if k in req["layers"] or k == "color"})
    return {"render_seconds": 0.25}

run(render, version=lambda: open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "VERSION")).read().strip())
)PY";

const char* kFakeManifest = R"([renderer]
name = "fake"
description = "the test's fake back-end"
command = ["/usr/bin/python3", "fake.py"]
version = ["/usr/bin/python3", "fake.py", "--version"]
layers = ["color", "direct", "indirect", "albedo", "reflection", "emission", "normal", "depth"]
timeout_seconds = 60
)";

struct FakeBackend {
  test::TempDir dir;
  fs::path folder = dir.path() / "backends" / "fake";
  FakeBackend() {
    write(folder / "fake.py", kFakeBackend);
    write(folder / "fake.toml", kFakeManifest);
    write(folder / "VERSION", "fake 1.0\n");
  }
  std::string scene(const std::string& name, const std::string& what) const {
    write(dir.path() / name, what + "\n");
    return dir.file(name);
  }
  std::vector<std::string> dirs() const { return {(dir.path() / "backends").string()}; }
  RendererBackend backend() const { return RendererBackend(find_renderers(dirs()).at("fake")); }
};

RenderRequest request(const std::string& scene) {
  RenderRequest r;
  r.scene = scene;
  r.width = 4;
  r.height = 3;
  r.spp = 8;
  r.seed = 123;
  r.max_depth = 5;
  r.threads = 2;
  r.layers = {"color", "albedo", "normal"};
  return r;
}

TEST(RendererBackend, SendsEveryFieldOfTheRequestAndReadsTheFrameBack) {
  FakeBackend f;
  RendererBackend b = f.backend();
  const std::string scene = f.scene("box.scene", "ok");
  const AovFrame frame = b.render(request(scene));
  const auto req = nlohmann::json::parse(test::slurp(scene + ".requests"));
  EXPECT_EQ(req["scene"], scene);
  EXPECT_EQ(req["width"], 4);
  EXPECT_EQ(req["height"], 3);
  EXPECT_EQ(req["spp"], 8);
  EXPECT_EQ(req["seed"], 123);
  EXPECT_EQ(req["max_depth"], 5);
  EXPECT_EQ(req["threads"], 2);
  EXPECT_EQ(req["layers"], nlohmann::json({"color", "albedo", "normal"}));
  EXPECT_THAT(req["output"].get<std::string>(), ::testing::EndsWith(".exr"));
  ASSERT_EQ(frame.width(), 4);
  ASSERT_EQ(frame.height(), 3);
  EXPECT_FLOAT_EQ(frame.layer(layer::kColor).data()[0], 8.123f);
  EXPECT_FLOAT_EQ(frame.layer(layer::kNormal).data()[2], 1.0f);
  EXPECT_EQ(frame.meta.spp, 8);
  EXPECT_EQ(frame.meta.seed, 123u);
  EXPECT_DOUBLE_EQ(frame.meta.render_seconds, 0.25);  // the back-end's own time, not the round trip
  EXPECT_EQ(frame.meta.tracer_version, "fake: fake 1.0");
}

TEST(RendererBackend, OneWorkerServesEveryRender) {
  FakeBackend f;
  RendererBackend b = f.backend();
  const std::string scene = f.scene("box.scene", "ok");
  RenderRequest r = request(scene);
  b.render(r);
  const double setup = b.setup_seconds();
  r.seed = 7;
  EXPECT_FLOAT_EQ(b.render(r).layer(layer::kColor).data()[0], 8.007f);
  EXPECT_EQ(b.setup_seconds(), setup);  // not started again
}

TEST(RendererBackend, TheBackendsErrorNamesTheSceneFileAndTheWorkerGoesOn) {
  FakeBackend f;
  RendererBackend b = f.backend();
  const std::string bad = f.scene("broken.scene", "error");
  const std::string msg = test::error_of<WorkError>([&] { b.render(request(bad)); });
  EXPECT_THAT(msg, HasSubstr("renderer 'fake'"));
  EXPECT_THAT(msg, HasSubstr(bad + ": line 1: not a scene this back-end reads"));
  // One bad scene fails its render only.
  EXPECT_EQ(b.render(request(f.scene("box.scene", "ok"))).width(), 4);
}

TEST(RendererBackend, AnOutputOfTheWrongSizeIsRefused) {
  FakeBackend f;
  RendererBackend b = f.backend();
  const std::string scene = f.scene("small.scene", "size");
  EXPECT_THAT(test::error_of<WorkError>([&] { b.render(request(scene)); }),
              HasSubstr("on '" + scene + "': wrote a 2x2 image, 4x3 was asked for"));
}

TEST(RendererBackend, AWorkerThatDiesIsRestartedOnceThenEveryRenderFails) {
  FakeBackend f;
  RendererBackend b = f.backend();
  const std::string die = f.scene("die.scene", "die"), ok = f.scene("box.scene", "ok");
  EXPECT_THAT(test::error_of<WorkerError>([&] { b.render(request(die)); }), HasSubstr("restarted for the next request"));
  EXPECT_EQ(b.render(request(ok)).width(), 4);  // the restarted worker
  EXPECT_THAT(test::error_of<WorkerError>([&] { b.render(request(die)); }), HasSubstr("ended before answering"));
  EXPECT_THAT(test::error_of<WorkerError>([&] { b.render(request(ok)); }), HasSubstr("died twice"));
}

TEST(RendererBackend, AnUnavailableBackendFailsEveryRenderWithItsReason) {
  FakeBackend f;
  write(f.folder / "fake.py",
        "from denoisebench_renderer import run, Unavailable\n"
        "def setup():\n    raise Unavailable('no renderer installed here (run scripts/setup)')\n"
        "run(lambda r, s: None, version=lambda: 'x', setup=setup)\n");
  RendererBackend b = f.backend();
  const std::string scene = f.scene("box.scene", "ok");
  for (int i = 0; i < 2; ++i)
    EXPECT_THAT(test::error_of<WorkError>([&] { b.render(request(scene)); }),
                HasSubstr("renderer 'fake' is not available on this machine: no renderer installed here (run scripts/setup)"));
}

TEST(RendererBackend, TheIdentityFollowsTheVersionLine) {
  FakeBackend f;
  const std::string before = f.backend().identity();
  EXPECT_EQ(f.backend().identity(), before);
  write(f.folder / "VERSION", "fake 1.1\n");
  EXPECT_NE(f.backend().identity(), before);
  write(f.folder / "fake.py", "import sys\nsys.exit('no version here')\n");
  EXPECT_THAT(test::error_of<WorkError>([&] { f.backend().version(); }), HasSubstr("its version command"));
}

TEST(RendererManifest, UnknownKeysLayersAndProtocolsAreErrorsNamingTheFile) {
  FakeBackend f;
  const fs::path m = f.folder / "fake.toml";
  write(m, std::string(kFakeManifest) + "colour = 1\n");
  EXPECT_THAT(test::error_of<InputError>([&] { load_renderer_manifest(m.string()); }), HasSubstr("colour"));
  write(m, std::string(kFakeManifest).replace(std::string(kFakeManifest).find("\"depth\""), 7, "\"dpeth\""));
  EXPECT_THAT(test::error_of<InputError>([&] { load_renderer_manifest(m.string()); }), HasSubstr("unknown layer 'dpeth'"));
  write(m, std::string(kFakeManifest) + "protocol = \"frame\"\n");
  EXPECT_THAT(test::error_of<InputError>([&] { load_renderer_manifest(m.string()); }), HasSubstr("expected \"worker\""));
}

TEST(RendererManifest, AnUnknownBackendListsTheOnesFound) {
  FakeBackend f;
  const std::string msg = test::error_of<InputError>([&] { renderer_backend("cycles", f.dirs()); });
  EXPECT_THAT(msg, HasSubstr("renderer 'cycles' is not a back-end"));
  EXPECT_THAT(msg, HasSubstr("fake"));
}

}  // namespace
}  // namespace dnb::interop
