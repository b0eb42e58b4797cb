// Animated scenes (docs/sequences.md): keys and their interpolation, frame seeds, per-frame
// content hashes, the motion layer's reprojection, the errors of bad keys, `render --frames`.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>

#include <cstdlib>

#include <OpenImageIO/imageio.h>

#include "core/errors.h"
#include "core/exr_io.h"
#include "reprojection.h"
#include "test_util.h"
#include "tracer/animation.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

using test::frame_of;

using rt::Interpolation;
using rt::KeyTrack;

TEST(Animation, TracksPassThroughTheirKeysAndHoldBeyondThem) {
  KeyTrack k;
  k.frames = {0, 4, 10};
  k.values = {{0.0, 1.0, 5.0}, {2.0, 1.0, 5.0}, {-1.0, 3.0, 5.0}};
  for (auto how : {Interpolation::kLinear, Interpolation::kCatmullRom}) {
    for (std::size_t i = 0; i < k.frames.size(); ++i) EXPECT_EQ(k.at(k.frames[i], how), k.values[i]);
    EXPECT_EQ(k.at(-3, how), k.values.front());
    EXPECT_EQ(k.at(12, how), k.values.back());
  }
  // Linear: halfway between frames 4 and 10 is the mean of the keys.
  EXPECT_DOUBLE_EQ(k.at(7, Interpolation::kLinear)[0], 0.5);
  // Catmull-Rom at u = 1/2 of segment (4, 10): (-p0 + 9 p1 + 9 p2 - p3) / 16 with p0 = 0, p1 = 2,
  // p2 = -1, p3 = -1 (the end key repeated): (0 + 18 - 9 + 1) / 16 = 0.625.
  EXPECT_DOUBLE_EQ(k.at(7, Interpolation::kCatmullRom)[0], 0.625);
  // A constant track stays constant between its keys (the spline reproduces constants).
  EXPECT_DOUBLE_EQ(k.at(2.5, Interpolation::kCatmullRom)[2], 5.0);
}

TEST(Animation, FrameSeedsDifferPerFrameAndSeedAndAreDeterministic) {
  EXPECT_EQ(rt::frame_seed(1, 3), rt::frame_seed(1, 3));
  EXPECT_NE(rt::frame_seed(1, 3), rt::frame_seed(1, 4));
  EXPECT_NE(rt::frame_seed(1, 3), rt::frame_seed(2, 3));
  EXPECT_LT(rt::frame_seed(~0ULL >> 1, 99999), 1ULL << 53);
}

// A textured wall facing the camera, the camera sliding sideways and a little forward, and a
// box sliding in front of the wall: nothing is uncovered at the wall's middle rows away from the
// box (the test reads those).
std::string pan_scene(const std::string& interpolation = "linear") {
  return "[animation]\nframes = 4\ninterpolation = \"" + interpolation +
         "\"\n"
         "[camera]\neye = [0, 0, 4]\nlook_at = [0, 0, 0]\nvfov = 40\n"
         "[[camera.keys]]\nframe = 0\neye = [0, 0, 4]\nlook_at = [0, 0, 0]\n"
         "[[camera.keys]]\nframe = 3\neye = [0.6, 0.1, 3.7]\nlook_at = [0.6, 0.1, 0]\n"
         "[textures.t]\ntype = \"checker\"\nscale = 24\ncolor_a = [0.9, 0.9, 0.9]\ncolor_b = [0.1, 0.2, 0.3]\n"
         "[materials.wall]\ntexture = \"t\"\nalbedo = [1, 1, 1]\n"
         "[materials.box]\nalbedo = [0.7, 0.2, 0.1]\n"
         "[[objects]]\ntype = \"quad\"\nmaterial = \"wall\"\nsize = [8, 8]\nrotate = [90, 0, 0]\n"
         "[[objects]]\ntype = \"box\"\nmaterial = \"box\"\nsize = [0.4, 0.4, 0.4]\ntranslate = [-1, -1.1, 0.5]\n"
         "[[objects.keys]]\nframe = 0\ntranslate = [-1, -1.1, 0.5]\n"
         "[[objects.keys]]\nframe = 3\ntranslate = [-0.4, -1.1, 0.5]\nrotate = [0, 40, 0]\n"
         "[sky]\ncolor = [0.8, 0.8, 0.8]\n";
}

TEST(Sequence, KeysPlaceTheCameraAndObjectsAtEachFrame) {
  test::TempDir dir;
  const std::string path = test::write_text(dir.file("pan.toml"), pan_scene());
  const auto f0 = frame_of(path, 0), f3 = frame_of(path, 3), f1 = frame_of(path, 1);
  EXPECT_EQ(f0->frames, 4);
  EXPECT_EQ(f3->frame, 3);
  EXPECT_FLOAT_EQ(f0->camera.eye.x, 0.0f);
  EXPECT_FLOAT_EQ(f3->camera.eye.x, 0.6f);
  EXPECT_FLOAT_EQ(f1->camera.eye.x, 0.2f);  // linear: a third of the way
  EXPECT_FLOAT_EQ(f1->camera.eye.z, 3.9f);
  EXPECT_FALSE(f1->camera.moving);           // no shutter: the frame's instant only
  // The box (mesh 1) moved by the keys' translation: its centre 0.2 to the right at frame 1 (the
  // rotation turns it about its centre).
  auto centre_x = [](const Scene& s) {
    double x = 0;
    for (const auto& p : s.meshes[1].positions) x += p.x;
    return x / double(s.meshes[1].positions.size());
  };
  EXPECT_NEAR(centre_x(*f1) - centre_x(*f0), 0.2, 1e-5);
  EXPECT_FALSE(f1->meshes[1].moving());
  // Every frame is its own content; the wall's mesh is the same.
  EXPECT_NE(scene_content_hash(*f0), scene_content_hash(*f1));
  for (std::size_t i = 0; i < f0->meshes[0].positions.size(); ++i)
    EXPECT_EQ(length(f0->meshes[0].positions[i] - f3->meshes[0].positions[i]), 0.0f);
}

TEST(Sequence, AShutterBlursEachFrameTowardsTheNext) {
  test::TempDir dir;
  std::string text = pan_scene();
  text.replace(text.find("vfov = 40\n"), 10, "vfov = 40\nshutter = [0, 1]\n");
  const std::string path = test::write_text(dir.file("blur.toml"), text);
  const auto f1 = frame_of(path, 1), f2 = frame_of(path, 2);
  EXPECT_TRUE(f1->camera.moving);
  EXPECT_FLOAT_EQ(f1->camera.eye_end.x, f2->camera.eye.x);
  EXPECT_TRUE(f1->meshes[1].moving());
  const auto last = frame_of(path, 3);  // the keys hold after the last: no motion at the end
  EXPECT_FALSE(last->camera.moving);
}

// The motion layer reprojects the previous frame onto this one: the previous albedo fetched at
// c + motion(c) matches this frame's albedo on the wall, far better than the unwarped image.
TEST(Sequence, MotionVectorsReprojectThePreviousFrameOntoThisOne) {
  test::TempDir dir;
  const std::string path = test::write_text(dir.file("pan.toml"), pan_scene("catmull-rom"));
  const auto f1 = frame_of(path, 1), f2 = frame_of(path, 2);
  const RenderSettings s = test::reprojection_settings();
  const AovFrame a = render_sequence_frame(*f1, nullptr, s), b = render_sequence_frame(*f2, f1.get(), s);
  ASSERT_TRUE(b.has(layer::kMotion));
  const Image& mv = b.layer(layer::kMotion);
  const Image& alb0 = a.layer(layer::kAlbedo);
  const Image& alb1 = b.layer(layer::kAlbedo);
  // Rows 10..40 of 72 see only the wall (the box is near the bottom); columns away from the sides.
  const test::Reprojection r = test::reprojection(alb0, alb1, mv, 12, 84, 10, 40);
  EXPECT_GT(r.max_motion, 2.0) << "the camera moves several pixels per frame";
  // Residual: bilinear resampling of a checker's edges (a sub-pixel shift blurs them) and the
  // spp's anti-aliasing noise. Measured: about 1/15 of the unwarped error; 1/5 is the bound.
  EXPECT_LT(r.warped, r.still / 5) << "warped " << r.warped / r.pixels << " unwarped " << r.still / r.pixels;
  // The sign: the camera moved right, so the wall moved left on screen and a point's previous
  // position is to the right of its current one: motion.X > 0.
  EXPECT_GT(mv.at(48, 20, 0), 0.5f);
  // At frame 0 the layer is zero.
  ASSERT_TRUE(a.has(layer::kMotion));
  EXPECT_EQ(a.layer(layer::kMotion).at(10, 10, 0), 0.0f);
}

TEST(Sequence, FramesAreDeterministicAndTheirNoiseIndependent) {
  test::TempDir dir;
  const std::string path = test::write_text(dir.file("pan.toml"), pan_scene());
  const auto f1 = frame_of(path, 1), f2 = frame_of(path, 2);
  RenderSettings s;
  s.width = 32;
  s.height = 24;
  s.spp = 4;
  s.reflection_levels = 0;
  s.threads = 1;
  const AovFrame one = render_sequence_frame(*f2, f1.get(), s);
  s.threads = 2;
  const AovFrame two = render_sequence_frame(*f2, f1.get(), s);
  for (const char* l : {layer::kColor, layer::kMotion})
    EXPECT_TRUE(one.layer(l) == two.layer(l)) << l;
  EXPECT_EQ(one.meta.extra.at("frame"), "2");
  // Frame 1 and 2 use other samples: their colours differ where the scene does not (the sky's
  // pixels are the same radiance, but the wall's noise is not shared).
  const AovFrame prev = render_sequence_frame(*f1, nullptr, s);
  EXPECT_NE(prev.meta.extra.at("frame"), one.meta.extra.at("frame"));
  EXPECT_FALSE(prev.layer(layer::kColor) == one.layer(layer::kColor));
}

TEST(Sequence, BadKeysAreRefusedNamingFileLineAndKey) {
  const std::string ok = pan_scene();
  auto replaced = [&](const std::string& from, const std::string& to) {
    std::string t = ok;
    t.replace(t.find(from), from.size(), to);
    return t;
  };
  test::expect_scene_refused(replaced("[animation]\nframes = 4\n", ""), "keys need an [animation]");
  test::expect_scene_refused(replaced("frames = 4", "frames = 0"), "frames");
  test::expect_scene_refused(replaced("frames = 4", "frames = 2"), "past the sequence");  // key at frame 3
  test::expect_scene_refused(replaced("interpolation = \"linear\"", "interpolation = \"cubic\""), "interpolation");
  test::expect_scene_refused(replaced("[[camera.keys]]\nframe = 3", "[[camera.keys]]\nframe = 0"), "rise strictly");
  test::expect_scene_refused(replaced("eye = [0.6, 0.1, 3.7]", "eye = [0.6, 0.1]"), "eye");
  test::expect_scene_refused(replaced("eye = [0.6, 0.1, 3.7]", "eye = [0.6, 0.1, 0]"), "coincide");
  test::expect_scene_refused(replaced("[[objects.keys]]\nframe = 0\n", "[[objects.keys]]\n"), "frame");
  test::expect_scene_refused(replaced("rotate = [0, 40, 0]", "scale = -1"), "scale");
  test::expect_scene_refused(replaced("translate = [-1, -1.1, 0.5]\n[[objects.keys]]",
                                      "translate = [-1, -1.1, 0.5]\ntranslate_end = [0, 0, 0]\n[[objects.keys]]"),
                             "translate_end");
  test::expect_scene_refused(replaced("[materials.box]\nalbedo = [0.7, 0.2, 0.1]", "[materials.box]\nemission = [1, 1, 1]"),
                             "cannot emit");
  test::expect_scene_refused(ok + "[[lights]]\ntype = \"quad\"\nsize = [1, 1]\nemission = [1, 1, 1]\n"
                                  "[[lights.keys]]\nframe = 0\ntranslate = [0, 0, 0]\n",
                             "lights do not move");
  // A frame past the end, and a frame of a still.
  test::TempDir dir;
  const std::string path = test::write_text(dir.file("pan.toml"), ok);
  EXPECT_NE(test::error_of<InputError>([&] { frame_of(path, 4); }).find("past the sequence"), std::string::npos);
  EXPECT_NE(test::error_of<InputError>([&] { frame_of("cornell-box", 2); }).find("still scene"), std::string::npos);
}

TEST(Sequence, RenderFramesWritesOneFileAFrameAndRefusesStills) {
  test::TempDir dir;
  const std::string path = test::write_text(dir.file("pan.toml"), pan_scene());
  auto r = test::run_in(dir, "render " + path + " --frames 1:3 --size 24x16 --spp 2 --reflection-levels 0 -o " +
                                 dir.file("out/f.exr"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const AovFrame f1 = read_frame(dir.file("out/f_0001.exr"), {layer::kMotion});
  const AovFrame f2 = read_frame(dir.file("out/f_0002.exr"), {layer::kMotion});
  EXPECT_FALSE(std::filesystem::exists(dir.file("out/f_0000.exr")));
  // Frame 1 of a range that starts there still has its motion against frame 0.
  double moved = 0;
  const Image& m1 = f1.layer(layer::kMotion);
  for (std::size_t i = 0; i < m1.size(); ++i) moved += std::abs(m1.data()[i]);
  EXPECT_EQ(m1.channels(), 2);
  EXPECT_GT(moved, 0.0);
  EXPECT_EQ(f2.meta.extra.at("frame"), "2");
  for (const std::string bad : {"--frames 3:3", "--frames 2:9", "--frames a:b", "--frames 2"}) {
    auto e = test::run_in(dir, "render " + path + " " + bad + " --size 8x8 --spp 1 -o " + dir.file("bad.exr"));
    EXPECT_EQ(e.exit_code, 2) << bad << e.output;
    EXPECT_NE(e.output.find("--frames"), std::string::npos) << e.output;
  }
  auto still = test::run_in(dir, "render cornell-box --frames 0:2 --size 8x8 --spp 1 -o " + dir.file("still.exr"));
  EXPECT_EQ(still.exit_code, 2);
  EXPECT_NE(still.output.find("still"), std::string::npos) << still.output;
}

// The motion layer against Cycles' Vector pass (docs/sequences.md): the same camera motion over a
// plane (tests/data/cycles_vector.py renders it with Blender) gives motion.X = Vector.X and
// motion.Y = -Vector.Y. The motion is a pure translation over a plane facing the camera, the same
// at every pixel, so one pixel compares. Skipped, saying why, without Blender.
TEST(Sequence, MotionMatchesCyclesVectorPass) {
  if (const std::string why = test::blender_missing(); !why.empty()) GTEST_SKIP() << why;
  test::TempDir dir;
  const std::string exr = dir.file("cycles.exr");
  const char* env = std::getenv("DENOISEBENCH_BLENDER");
  const std::string blender = env && *env ? env : "blender";
  auto r = test::run_command("'" + blender + "' -b --python '" + test::source_dir() + "/tests/data/cycles_vector.py' -- '" +
                             exr + "' 2>&1");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto in = OIIO::ImageInput::open(exr);
  ASSERT_TRUE(in) << OIIO::geterror();
  const OIIO::ImageSpec spec = in->spec();
  std::vector<float> px(std::size_t(spec.width) * spec.height * spec.nchannels);
  ASSERT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, px.data()));
  auto channel = [&](const std::string& name) {  // by name: OIIO reorders channels
    const int c = spec.channelindex("ViewLayer.Vector." + name);
    EXPECT_GE(c, 0) << name;
    return px[(std::size_t(24) * spec.width + 32) * spec.nchannels + std::size_t(std::max(c, 0))];
  };
  const float vx = channel("X"), vy = channel("Y");
  // The same in the tracer: Blender's 36 mm sensor across the 64 pixels with a 50 mm lens is a
  // vertical field of view of 2 atan(18 / 50 * 48 / 64) = 30.2 degrees.
  const std::string scene = test::write_text(dir.file("plane.toml"),
                                             "[animation]\nframes = 2\ninterpolation = \"linear\"\n"
                                             "[camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = " +
                                                 std::to_string(2 * std::atan(18.0 / 50 * 48 / 64) * 180 / rt::kPi) +
                                                 "\n[[camera.keys]]\nframe = 0\n[[camera.keys]]\nframe = 1\n"
                                                 "eye = [1, 0.5, 5]\nlook_at = [1, 0.5, 0]\n"
                                                 "[materials.m]\nalbedo = [0.5, 0.5, 0.5]\n"
                                                 "[[objects]]\ntype = \"quad\"\nmaterial = \"m\"\nsize = [20, 20]\n"
                                                 "rotate = [90, 0, 0]\n");
  const Image m = motion_layer(*frame_of(scene, 1), *frame_of(scene, 0), 64, 48);
  // Cycles: the surface was 17.8 pixels right and 8.9 up in frame 1 (1 and 0.5 units at 17.78
  // pixels a unit); the tracer says the same with y down. 0.01 pixels: float rounding of both.
  EXPECT_NEAR(vx, 17.78f, 0.05f);
  EXPECT_NEAR(vy, 8.89f, 0.05f);
  EXPECT_NEAR(m.at(32, 24, 0), vx, 0.01f);
  EXPECT_NEAR(m.at(32, 24, 1), -vy, 0.01f);
}

}  // namespace
}  // namespace dnb
