// The learned baselines' training corpus (python/training_corpus.py) holds no evaluation or
// generalisation scene: checked on the manifests of the committed weights (what the networks
// were actually trained on), and on the generator itself.
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
using nlohmann::json;

// Runs Python `code` (one statement per line; no single quotes) with the repository's python/
// folder importable; its standard output is the result's.
test::CommandResult python(const std::string& code) {
  return test::run_command_stdout("/usr/bin/python3 -c 'import sys; sys.path.insert(0, \"" + test::source_dir() +
                                  "/python\")\n" + code + "'");
}

// Every scene of configs/scenes/ (the evaluation scenes of quick.toml, paper.toml and
// mcguire.toml, and generalisation.toml's): name -> the tracer's content hash of the loaded
// scene, rendered at 1 spp on 8x8 pixels. A McGuire scene needs the scenes folder; without it
// its hash is missing from the map (its meshes are still checked by name below).
std::map<std::string, std::string> evaluation_hashes(const test::TempDir& dir, std::vector<std::string>* missing) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::directory_iterator(test::source_dir() + "/configs/scenes")) {
    if (e.path().extension() != ".toml") continue;
    const std::string name = e.path().stem().string();
    const std::string exr = dir.file(name + ".exr");
    auto r = test::run_denoisebench("render " + name + " --spp 1 --size 8x8 -o " + exr + " 2>&1");
    if (r.exit_code != 0) {
      EXPECT_EQ(name.rfind("mcguire-", 0), 0u) << name << " does not render: " << r.output;
      missing->push_back(name);
      continue;
    }
    out[name] = read_frame(exr).meta.extra.at("scene_hash");
  }
  return out;
}

TEST(Corpus, CommittedWeightsWereTrainedOnNoEvaluationScene) {
  test::TempDir dir;
  std::vector<std::string> missing;
  const auto eval = evaluation_hashes(dir, &missing);
  ASSERT_GE(eval.size(), 8u) << "the built-in evaluation scenes must all render";
  std::set<std::string> eval_files;  // SHA-256 of the evaluation scene files
  std::set<std::string> eval_meshes;  // meshes they read, relative to the scenes folder
  auto py = python("import json, training_corpus as c; f, m = c.evaluation_scene_files(); "
      "print(json.dumps({\"files\": [c.sha256_file(p) for p in f], \"meshes\": sorted(m), \"pool\": c.MESH_POOL}))");
  ASSERT_EQ(py.exit_code, 0) << py.output << py.errors;
  const json ev = json::parse(py.output);
  for (const auto& h : ev["files"]) eval_files.insert(h.get<std::string>());
  for (const auto& m : ev["meshes"]) eval_meshes.insert(m.get<std::string>());
  ASSERT_GE(eval_files.size(), eval.size());
  ASSERT_FALSE(eval_meshes.empty()) << "the McGuire scenes' meshes are read from configs/scenes/";
  // The generator's mesh pool itself.
  for (const auto& m : ev["pool"]) EXPECT_FALSE(eval_meshes.count(m.get<std::string>())) << m;

  int manifests = 0;
  for (const char* m : {"plugins/kpcn/weights/kpcn.json", "plugins/unet/weights/unet.json"}) {
    const fs::path p = fs::path(test::source_dir()) / m;
    if (!fs::exists(p)) continue;
    ++manifests;
    const json doc = json::parse(test::slurp(p));
    ASSERT_TRUE(doc.contains("scenes")) << m;
    ASSERT_GE(doc["scenes"].size(), 2u) << m;
    for (const auto& s : doc["scenes"]) {
      const std::string name = s.at("name");
      EXPECT_FALSE(eval_files.count(s.at("sha256").get<std::string>())) << m << ": " << name << " is an evaluation scene's file";
      for (const auto& [ename, hash] : eval)
        EXPECT_NE(s.at("content_hash").get<std::string>(), hash) << m << ": " << name << " is evaluation scene " << ename;
      for (const auto& mesh : s.at("meshes"))
        EXPECT_FALSE(eval_meshes.count(mesh.get<std::string>())) << m << ": " << name << " reads " << mesh;
    }
  }
  EXPECT_GE(manifests, 1) << "no committed weights' manifest to check";
  if (!missing.empty())
    std::printf("(without the scenes folder: %zu McGuire scenes checked by their meshes only)\n", missing.size());
}

// The generator: a scene is a function of (seed, index) only, two seeds give other scenes, and
// over 30 scenes every material type and light kind of the tracer appears (the corpus is to hold
// them all: docs/method-defaults.md, "The training corpus").
TEST(Corpus, ScenesAreFunctionsOfTheSeedAndCoverEveryMaterial) {
  test::TempDir dir;
  auto r = python("import numpy as np, training_corpus as c\n"
      "def scenes(seed):\n"
      "    rng = np.random.default_rng(seed)\n"
      "    return [c.procedural_scene(rng, i, \"" + dir.file("") + "\", \"/scenes\")[0] for i in range(30)]\n"
      "a, b, d = scenes(1), scenes(1), scenes(2)\n"
      "print(a == b, a[0] != d[0])\n"
      "text = \"\".join(a)\n"
      "kinds = [f\"type = \\\"{k}\\\"\" for k in (\"mirror\", \"coated\", \"conductor\", \"plastic\", \"dielectric\", \"image\", "
      "\"leaf\", \"obj\", \"arch\")] + [\"[sun]\", \"material = \\\"e0\\\"\", \"roughness = \", \"name = \\\"lamp0\\\"\"]\n"
      "print(\" \".join(k for k in kinds if k not in text) or \"all\")");
  ASSERT_EQ(r.exit_code, 0) << r.output << r.errors;
  EXPECT_EQ(r.output, "True True\nall\n");
}

// The corpus cache (training_corpus.build): a second build renders nothing it has; a kept frame
// of another tracer version (as after a tracer change) is rendered again, and only that frame.
TEST(Corpus, ABuildKeepsItsFramesButRendersThoseOfAnotherTracerAgain) {
  test::TempDir dir;
  const std::string code = "import training_corpus as c\n"
                           "m = c.build(\"" + test::binary().string() + "\", \"" + dir.file("work") +
                           "\", 7, 1, \"8x6\", [1], 4, log=lambda s: print(\"LOG\", s))\n"
                           "print(\"VERSION\", m[\"tracer_version\"])";
  auto r = python(code);
  ASSERT_EQ(r.exit_code, 0) << r.output << r.errors;
  EXPECT_THAT(r.output, ::testing::HasSubstr("reference (4 spp, 8x6)"));
  EXPECT_THAT(r.output, ::testing::HasSubstr("input (1 spp)"));
  EXPECT_THAT(r.output, ::testing::HasSubstr("VERSION dnb-tracer-"));
  r = python(code);
  ASSERT_EQ(r.exit_code, 0) << r.output << r.errors;
  EXPECT_EQ(r.output.find("LOG"), std::string::npos) << "a second build rendered again:\n" << r.output;
  std::string input;
  for (const auto& e : fs::directory_iterator(dir.file("work/frames")))
    if (e.path().filename().string().ends_with("-s1-8x6-seed7.exr")) input = e.path().string();
  ASSERT_FALSE(input.empty());
  AovFrame f = read_frame(input);
  const std::string current = f.meta.tracer_version;
  f.meta.tracer_version = "dnb-tracer-0";  // what an older tracer wrote
  write_frame(f, input);
  r = python(code);
  ASSERT_EQ(r.exit_code, 0) << r.output << r.errors;
  EXPECT_THAT(r.output, ::testing::HasSubstr("input (1 spp)"));
  EXPECT_EQ(r.output.find("reference ("), std::string::npos) << "the reference was current:\n" << r.output;
  EXPECT_EQ(read_frame(input).meta.tracer_version, current);
}

// The relative loss: 1 (up to its epsilon) for an output equal to the noisy input, 0 for the
// reference itself, above 1 for an output worse than the input.
TEST(Corpus, RelativeLossIsTheErrorOverTheInputs) {
  if (test::run_command("/usr/bin/python3 -c 'import torch' 2>&1").exit_code != 0)
    GTEST_SKIP() << "PyTorch is not importable by /usr/bin/python3 (scripts/setup installs Debian's python3-torch)";
  auto r = python("import torch, training_corpus as c\n"
      "torch.manual_seed(1)\n"
      "ref = torch.rand(2, 3, 8, 8) * 0.8\n"
      "noisy = (ref + 0.2 * torch.randn(2, 3, 8, 8)).clamp_min(0)\n"
      "same = float(c.relative_display_loss(noisy, ref, noisy))\n"
      "exact = float(c.relative_display_loss(ref, ref, noisy))\n"
      "worse = float(c.relative_display_loss(noisy * 2, ref, noisy))\n"
      "print(0.98 < same < 1.0, exact == 0.0, worse > 1.0)");
  ASSERT_EQ(r.exit_code, 0) << r.output << r.errors;
  // same: l / (l + 2e-3) with l ~ 0.1 (noise of 0.2 in display space): 0.98 .. 1.
  EXPECT_EQ(r.output, "True True True\n");
}

// The learned plug-ins' noise clamp (python/denoisebench_plugin.py, noise_clamp): a pixel whose
// 3x3 neighbourhood has no variance keeps its input; elsewhere the change is cut to c standard
// deviations of the 3x3-averaged variance; c = 0 returns the network's output.
TEST(LearnedPlugins, NoiseClampBoundsTheChangeByTheNoise) {
  auto r = python("import numpy as np, denoisebench_plugin as p\n"
      "x = np.full((4, 4, 3), 0.5, np.float32); v = np.zeros((4, 4, 3), np.float32); y = x + 0.3\n"
      "print(np.array_equal(p.noise_clamp(x, v, y, 3.0), x))\n"  // converged: the input
      "v[:] = 0.01\n"  // s = 0.1: c = 2 allows 0.2 of the 0.3 change
      "print(np.allclose(p.noise_clamp(x, v, y, 2.0), x + 0.2), np.allclose(p.noise_clamp(x, v, y, 5.0), y))\n"
      "print(p.noise_clamp(x, v, y, 0.0) is y)");
  ASSERT_EQ(r.exit_code, 0) << r.output << r.errors;
  EXPECT_EQ(r.output, "True\nTrue True\nTrue\n");
}

// The guards' scene with a known answer, in Python: the truth mu (thin bright lines every 4
// columns on grey), the noise's standard deviation s, and the display-space mse against mu.
const std::string kThinLines =
    "import numpy as np, denoisebench_plugin as p\n"
    "rng = np.random.default_rng(7)\n"
    "mu = np.full((64, 64, 3), 0.2); mu[:, ::4] = 0.6; s = 0.03\n"
    "def mse(x): return float(np.mean((p.display(x) - p.display(mu)) ** 2))\n";

// The guard's promise on a scene with a known answer: thin bright lines every 4 columns, two
// halves with independent Gaussian noise. A denoiser that returns the truth is kept (w ~ 1); one
// that erases the lines (their local mean, 40x the input's error) is dropped (w ~ 0), so the
// output is no worse than the input. Bounds: over seeds 0..9 the kept one measured 0.004-0.006
// of the input's display mse (the weight's estimate is off by ~1/sqrt(147 values) per window),
// the dropped one 0.979-1.0007 (the weight of a harmful change is estimated about 0, with noise).
TEST(LearnedPlugins, CrossValidationKeepsWhatHelpsAndDropsWhatHarms) {
  auto r = python(kThinLines +
      "A = mu + rng.normal(0, s, mu.shape); B = mu + rng.normal(0, s, mu.shape)\n"
      "F = (A + B) / 2; var = np.full(mu.shape, s * s / 2)\n"
      "blur = np.full(mu.shape, 0.3)\n"
      "good = p.cross_validated(F, mu, [A, B], [mu, mu], var, 3)\n"
      "bad = p.cross_validated(F, blur, [A, B], [blur, blur], var, 3)\n"
      "print(mse(good) < 0.05 * mse(F), mse(bad) < 1.02 * mse(F), mse(blur) > 10 * mse(F))\n"
      "print(p.cross_validated(F, blur, [A, B], [blur, blur], var, 0) is blur)\n"
      "odd = mu.copy(); odd[5, 5, 0] = np.nan\n"  // a NaN on one half's output stays local
      "x = p.cross_validated(F, mu, [A, B], [odd, mu], var, 3)\n"
      "print(np.isfinite(x).all(), mse(x) < 0.05 * mse(F))");
  ASSERT_EQ(r.exit_code, 0) << r.output << r.errors;
  EXPECT_EQ(r.output, "True True True\nTrue\nTrue True\n");
}

// SURE's promise on the same scene, judged on the frame alone (no halves): a denoiser that
// returns the truth is kept, one that erases the lines is dropped, and one that doubles the
// noise (2 F - mu: its output looks as plausible as the input, only its dependence on the
// input's noise gives it away) gets weight 0 exactly: Stein's divergence term is 2 s^2 per
// pixel there, so the estimated gain is -s^2 per pixel, not the +s^2 a weight from the output
// alone would see (the output would then carry 4x the input's error). Bounds as above: over
// seeds 0..9 the kept one measured 0.006-0.011 of the input's display mse, the dropped one
// 0.93-0.94 (SURE weighs a wrong constant by about s^2 / (s^2 + bias^2): a small gain, not a
// loss), the doubled noise 4.4-4.5x the input's.
TEST(LearnedPlugins, SureKeepsWhatHelpsAndDropsWhatHarmsOnTheFrameAlone) {
  auto r = python(kThinLines +
      "F = mu + rng.normal(0, s, mu.shape); var = np.full(mu.shape, s * s)\n"
      "frame = {\"color\": F, \"variance\": var}\n"
      "def guard(net): return p.guarded(frame, net(F), lambda f: net(f[\"color\"]), [\"color\"], 0, 0.0, sure=3)\n"
      "good = guard(lambda c: mu); bad = guard(lambda c: np.full(mu.shape, 0.3))\n"
      "print(mse(good) < 0.05 * mse(F), mse(bad) < 1.02 * mse(F), mse(np.full(mu.shape, 0.3)) > 10 * mse(F))\n"
      "amp = guard(lambda c: 2 * np.asarray(c, np.float64) - mu)\n"
      "print(np.array_equal(amp, F.astype(np.float32)), mse(2 * F - mu) > 3 * mse(F))\n"
      "a, sa = p.sure_perturbation(F, var); b, sb = p.sure_perturbation(F, var)\n"  // a function of the frame
      "print(np.array_equal(a, b), np.array_equal(sa, sb), abs(float(np.mean(sa))) < 0.05)\n"
      // A firefly clamped at 1 in display: at the colour its slope is 0 (no noise to remove there),
      // at the output (the truth here) it is not, so removing the firefly gets more weight.
      "fire = F.copy(); fire[10, 10] = 30.0; vf = var.copy(); vf[10, 10] = 100.0\n"
      "w0 = p.sure_weight(fire, vf, mu, mu, sa, 3); w1 = p.sure_weight(fire, vf, mu, mu, sa, 3, slope_at_output=True)\n"
      "print(w1[10, 10, 0] > 2 * w0[10, 10, 0])");
  ASSERT_EQ(r.exit_code, 0) << r.output << r.errors;
  EXPECT_EQ(r.output, "True True True\nTrue True\nTrue True True\nTrue\n");
}

// A half of a tracer frame for a network that reads the split: the half's own layers, twice the
// variance, the frame's emission, and the reflection that closes F_h = (D_h + I_h) T_h + R_h + E;
// no half at all where the frame lacks a layer that needs (an imported frame).
TEST(LearnedPlugins, HalfFramesCloseTheSplitAndNeedTheirLayers) {
  auto r = python("import numpy as np, denoisebench_plugin as p\n"
      "rng = np.random.default_rng(1)\n"
      "f = {k: rng.random((3, 5, 3)).astype(np.float32) for k in (\"color\", \"variance\", \"emission\", \"reflection\")}\n"
      "for h in (0, 1):\n"
      "    for k in (\"color\", \"direct\", \"indirect\", \"albedo\", \"normal\"): f[f\"half{h}.{k}\"] = rng.random((3, 5, 3)).astype(np.float32)\n"
      "    f[f\"half{h}.depth\"] = rng.random((3, 5, 1)).astype(np.float32)\n"
      "layers = [\"color\", \"albedo\", \"reflection\", \"emission\", \"normal\", \"depth\", \"variance\"]\n"
      "x = p.half_frame(f, 1, layers)\n"
      "back = (f[\"half1.direct\"] + f[\"half1.indirect\"]) * f[\"half1.albedo\"] + x[\"reflection\"] + f[\"emission\"]\n"
      "print(np.allclose(back, f[\"half1.color\"], atol=1e-6), np.array_equal(x[\"variance\"], 2 * f[\"variance\"]),"
      " x[\"depth\"] is f[\"half1.depth\"], sorted(x) == sorted(layers))\n"
      "del f[\"half0.indirect\"]\n"
      "print(p.half_frame(f, 0, layers), p.half_frame(f, 0, [\"color\", \"albedo\", \"variance\"]) is not None)\n"
      "print(*p.half_layers([\"color\", \"variance\"]))");
  ASSERT_EQ(r.exit_code, 0) << r.output << r.errors;
  EXPECT_EQ(r.output, "True True True True\nNone True\nhalf0.color half1.color\n");
}

}  // namespace
}  // namespace dnb
