// glTF animations (docs/gltf.md, "Animations"; docs/sequences.md, "glTF animations"): the
// samplers' interpolation as the glTF 2.0 specification defines it, nodes and the camera placed
// where their channels put them at each frame's time, a scene TOML's fps, a glTF file rendered
// alone as a sequence whose motion layer reprojects the previous frame, and the refusals of
// malformed or unsupported animations, each naming the file, the animation and the channel.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "core/errors.h"
#include "core/exr_io.h"
#include "gltf_builder.h"
#include "reprojection.h"
#include "test_util.h"
#include "tracer/gltf_animation.h"
#include "tracer/gltf_import.h"
#include "tracer/render.h"
#include "tracer/scene.h"
#include "tracer/scene_loader.h"
#include "tracer_scenes.h"

namespace dnb {
namespace {

using test::frame_of;

using json = nlohmann::json;
using rt::GltfInterpolation;
using rt::GltfSampler;
using rt::Vec3;
using test::Gltf;

constexpr double kPi = 3.14159265358979323846;

// A unit quaternion (x, y, z, w) turning `degrees` about y.
std::vector<float> about_y(double degrees) {
  const double h = degrees * kPi / 360;
  return {0, float(std::sin(h)), 0, float(std::cos(h))};
}

TEST(GltfAnimation, SamplersInterpolateAsTheSpecificationSays) {
  GltfSampler lin;
  lin.times = {1, 3};
  lin.values = {0, 0, 0, 2, 4, 6};
  EXPECT_EQ(rt::sample_gltf(lin, 0), (std::vector<double>{0, 0, 0}));  // before the first key: the first
  EXPECT_EQ(rt::sample_gltf(lin, 2), (std::vector<double>{1, 2, 3}));  // half-way: the mean
  EXPECT_EQ(rt::sample_gltf(lin, 9), (std::vector<double>{2, 4, 6}));  // after the last: the last

  GltfSampler step = lin;
  step.interpolation = GltfInterpolation::kStep;
  EXPECT_EQ(rt::sample_gltf(step, 2.99)[0], 0);
  EXPECT_EQ(rt::sample_gltf(step, 3)[0], 2);

  // CUBICSPLINE keys are (in-tangent, value, out-tangent). With zero tangents from 0 to 1 over
  // [0, 1] the spline is smoothstep 3u^2 - 2u^3.
  GltfSampler cubic;
  cubic.interpolation = GltfInterpolation::kCubicSpline;
  cubic.width = 1;
  cubic.times = {0, 1};
  cubic.values = {0, 0, 0, 0, 1, 0};
  EXPECT_NEAR(rt::sample_gltf(cubic, 0.25)[0], 3 * 0.0625 - 2 * 0.015625, 1e-12);
  EXPECT_NEAR(rt::sample_gltf(cubic, 0.5)[0], 0.5, 1e-12);
  // Tangents are per second: scaled by the key interval (2 s here). Out-tangent 1 from value 0
  // back to 0: p(u) = 2 (u^3 - 2u^2 + u), at u = 1/4: 0.28125 (0.140625 unscaled).
  cubic.times = {0, 2};
  cubic.values = {0, 0, 1, 0, 0, 0};
  EXPECT_NEAR(rt::sample_gltf(cubic, 0.5)[0], 0.28125, 1e-12);

  // Rotations: slerp turns at a constant rate (a quarter of 120 degrees is 30; a normalised lerp
  // would give 27.8), along the shorter arc (the second key's sign does not matter).
  GltfSampler rot;
  rot.rotation = true;
  rot.width = 4;
  rot.times = {0, 1};
  for (float sign : {1.0f, -1.0f}) {
    const std::vector<float> end = about_y(120);
    rot.values = {0, 0, 0, 1, sign * end[0], sign * end[1], sign * end[2], sign * end[3]};
    const std::vector<double> q = rt::sample_gltf(rot, 0.25);
    EXPECT_NEAR(2 * std::atan2(q[1], q[3]) * 180 / kPi, 30, 1e-5) << "sign " << sign;  // float keys
  }
  // A cubic spline of quaternions is normalised.
  rot.interpolation = GltfInterpolation::kCubicSpline;
  const std::vector<float> e = about_y(120);
  rot.values = {0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, e[0], e[1], e[2], e[3], 0, 0, 0, 0};
  const std::vector<double> q = rt::sample_gltf(rot, 0.5);
  EXPECT_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1, 1e-12);
}

// One triangle with corners (1, 0, 0), (0, 1, 0) and the origin; the nodes below each show one,
// and the import merges them into one mesh in depth-first order: triangle i is node i's.
const std::vector<float> kTriangle = {1, 0, 0, 0, 1, 0, 0, 0, 0};

// Nodes, in the order of their triangles:
//   0 "slide": translation LINEAR (0,0,0) at 0 s to (2,0,0) at 1 s;
//   1 its child, at (0, 1, 0) from it;
//   2 "turn": rotation LINEAR 0 to 120 degrees about y over [0, 1] s;
//   3 "grow": scale STEP 1 at 0 s, 2 at 0.5 s;
//   4 "rise": translation CUBICSPLINE y 0 at 0 s to 1 at 1 s, zero tangents;
//   5 "kick": translation CUBICSPLINE x 0 to 0 over [0, 2] s, out-tangent 1 at 0 s;
//   6 "late": translation LINEAR (5,0,0) at 0.5 s to (6,0,0) at 1 s.
// The camera node moves from (0, 1, 5) to (1, 1, 5) over [0, 1] s and turns 90 degrees about y
// over it. The channels are split over two animations (both play). Duration 2 s: 49 frames.
Gltf moving_nodes() {
  Gltf g;
  auto node = [&](const json& extra) {
    json n = extra;
    g.doc["meshes"].push_back({{"primitives", {{{"attributes", {{"POSITION", g.floats(kTriangle, "VEC3")}}}}}}});
    n["mesh"] = g.doc["meshes"].size() - 1;
    g.doc["nodes"].push_back(n);
    return int(g.doc["nodes"].size() - 1);
  };
  auto root = [&](int n) { g.doc["scenes"][0]["nodes"].push_back(n); };
  const int slide = node(json::object());
  const int child = node({{"translation", {0, 1, 0}}});
  g.doc["nodes"][std::size_t(slide)]["children"] = {child};
  root(slide);
  const int turn = node(json::object()), grow = node(json::object()), rise = node(json::object()), kick = node(json::object()),
            late = node(json::object());
  for (int n : {turn, grow, rise, kick, late}) root(n);
  g.doc["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 0.7}, {"znear", 0.01}}}}};
  g.root({{"camera", 0}, {"translation", {0, 1, 5}}});
  const int camera = int(g.doc["nodes"].size() - 1);
  g.channel(0, slide, "translation", {0, 1}, {0, 0, 0, 2, 0, 0});
  std::vector<float> turn_keys = about_y(0);
  for (float c : about_y(120)) turn_keys.push_back(c);
  g.channel(0, turn, "rotation", {0, 1}, turn_keys);
  g.channel(0, grow, "scale", {0, 0.5f}, {1, 1, 1, 2, 2, 2}, "STEP");
  g.channel(1, rise, "translation", {0, 1}, {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0}, "CUBICSPLINE");
  g.channel(1, kick, "translation", {0, 2}, {0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}, "CUBICSPLINE");
  g.channel(1, late, "translation", {0.5f, 1}, {5, 0, 0, 6, 0, 0});
  g.channel(1, camera, "translation", {0, 1}, {0, 1, 5, 1, 1, 5});
  std::vector<float> cam_keys = about_y(0);
  for (float c : about_y(90)) cam_keys.push_back(c);
  g.channel(1, camera, "rotation", {0, 1}, cam_keys);
  g.doc["animations"][0]["name"] = "first";
  g.doc["animations"][1]["name"] = "second";
  return g;
}

// Corner k of node i's triangle (see moving_nodes).
Vec3 corner(const Scene& s, int node, int k) { return s.meshes[0].positions[std::size_t(3 * node + k)]; }

void expect_near(const Vec3& a, const Vec3& b, const std::string& what) {
  EXPECT_NEAR(a.x, b.x, 1e-5) << what;
  EXPECT_NEAR(a.y, b.y, 1e-5) << what;
  EXPECT_NEAR(a.z, b.z, 1e-5) << what;
}

TEST(GltfAnimation, NodesAndTheCameraAreWhereTheirChannelsPutThemAtEachFramesTime) {
  test::TempDir dir;
  const std::string path = moving_nodes().write(dir, "moving.gltf");
  // Frame t is at t / 24 s; the last key is at 2 s: frames 0 .. 48.
  const auto f0 = frame_of(path, 0), f6 = frame_of(path, 6), f11 = frame_of(path, 11), f12 = frame_of(path, 12),
             f18 = frame_of(path, 18), f30 = frame_of(path, 30), f48 = frame_of(path, 48);
  EXPECT_EQ(f0->frames, 49);
  EXPECT_EQ(f12->frame, 12);
  const Vec3 origin(0.0f);
  // LINEAR translation: a quarter and half-way between its keys; its last value after them.
  expect_near(corner(*f0, 0, 2), origin, "slide at 0 s");
  expect_near(corner(*f6, 0, 2), Vec3(0.5f, 0, 0), "slide at 0.25 s");
  expect_near(corner(*f12, 0, 2), Vec3(1, 0, 0), "slide at 0.5 s");
  expect_near(corner(*f48, 0, 2), Vec3(2, 0, 0), "slide at 2 s");
  // The child moves with its parent.
  expect_near(corner(*f12, 1, 2), Vec3(1, 1, 0), "the child at 0.5 s");
  // Slerp: 30 and 60 degrees about y; corner (1, 0, 0) turns to (cos a, 0, -sin a).
  const double a30 = kPi / 6, a60 = kPi / 3;
  expect_near(corner(*f6, 2, 0), Vec3(float(std::cos(a30)), 0, float(-std::sin(a30))), "turn at 0.25 s");
  expect_near(corner(*f12, 2, 0), Vec3(float(std::cos(a60)), 0, float(-std::sin(a60))), "turn at 0.5 s");
  // STEP holds its key until the next.
  EXPECT_NEAR(corner(*f6, 3, 0).x, 1, 1e-6);
  EXPECT_NEAR(corner(*f11, 3, 0).x, 1, 1e-6);
  EXPECT_NEAR(corner(*f12, 3, 0).x, 2, 1e-6);
  // CUBICSPLINE: smoothstep with zero tangents; a tangent scaled by its 2 s interval.
  EXPECT_NEAR(corner(*f6, 4, 2).y, 0.15625, 1e-6);
  EXPECT_NEAR(corner(*f12, 4, 2).y, 0.5, 1e-6);
  EXPECT_NEAR(corner(*f12, 5, 2).x, 0.28125, 1e-6);
  // Before its first key (0.5 s) a channel holds its first value.
  EXPECT_NEAR(corner(*f0, 6, 2).x, 5, 1e-6);
  EXPECT_NEAR(corner(*f6, 6, 2).x, 5, 1e-6);
  EXPECT_NEAR(corner(*f18, 6, 2).x, 5.5, 1e-6);
  EXPECT_NEAR(corner(*f30, 6, 2).x, 6, 1e-6);
  // The camera: half-way at 0.5 s, turned 45 degrees about y (looking along (-sin, 0, -cos)).
  expect_near(f12->camera.eye, Vec3(0.5f, 1, 5), "the camera's eye at 0.5 s");
  const Vec3 d = normalize(f12->camera.look_at - f12->camera.eye);
  expect_near(d, Vec3(float(-std::sqrt(0.5)), 0, float(-std::sqrt(0.5))), "the camera's direction at 0.5 s");
  expect_near(f0->camera.eye, Vec3(0, 1, 5), "the camera at 0 s");
  // Every frame is its own content; a frame past the last is refused.
  EXPECT_NE(f0->content_hash, f6->content_hash);
  EXPECT_EQ(frame_of(path, 6)->content_hash, f6->content_hash);
  const std::string past = test::error_of<InputError>([&] { frame_of(path, 49); });
  EXPECT_NE(past.find("frame 49 is past the sequence's 49 frames"), std::string::npos) << past;
  // Loaded without a frame it is frame 0 of the sequence.
  EXPECT_EQ(load_scene(path)->frames, 49);
  EXPECT_EQ(load_scene(path)->content_hash, f0->content_hash);
}

TEST(GltfAnimation, AStillGltfRefusesFramesAndWeightsAloneDoNotAnimate) {
  test::TempDir dir;
  Gltf g;
  const int quad = g.mesh(test::quad_positions({-2, 0, 2, 2, 0, 2, 2, 0, -2, -2, 0, -2}), test::kQuad, -1);
  g.doc["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 0.7}, {"znear", 0.01}}}}};
  g.root({{"camera", 0}, {"translation", {0, 2, 4}}});
  const std::string still = g.write(dir, "still.gltf");
  EXPECT_FALSE(load_scene(still)->animated());
  const std::string e = test::error_of<InputError>([&] { frame_of(still, 1); });
  EXPECT_EQ(e.rfind(still, 0), 0u) << e;
  EXPECT_NE(e.find("still glTF"), std::string::npos) << e;
  // Morph target weights are not read: an animation of weights alone leaves the file a still,
  // with a warning.
  g.channel(0, quad, "weights", {0, 1}, {0, 1});
  Scene s;
  const rt::GltfImport imp = rt::import_gltf(s, g.write(dir, "weights.gltf"), {}, std::nullopt, 0.5);
  EXPECT_FALSE(imp.animated);
  ASSERT_EQ(imp.warnings.size(), 1u);
  EXPECT_NE(imp.warnings[0].find("morph target weights are not animated"), std::string::npos) << imp.warnings[0];
}

TEST(GltfAnimation, AnimationsPlayTogetherAndAClipOnTheSamePropertyIsLeftOut) {
  test::TempDir dir;
  Gltf g = moving_nodes();
  // A third animation on node 0's translation (which "first" drives): an alternative clip.
  g.channel(2, 0, "translation", {0, 1}, {0, 9, 0, 0, 9, 0});
  Scene s;
  const rt::GltfImport imp = rt::import_gltf(s, g.write(dir, "clips.gltf"), {}, std::nullopt, 0.5);
  EXPECT_TRUE(imp.animated);
  EXPECT_DOUBLE_EQ(imp.duration, 2);
  ASSERT_EQ(imp.warnings.size(), 1u);
  EXPECT_NE(imp.warnings[0].find("/animations/2: animation 2 targets node 0's translation"), std::string::npos)
      << imp.warnings[0];
  expect_near(corner(s, 0, 2), Vec3(1, 0, 0), "slide at 0.5 s, by 'first'");
  expect_near(corner(s, 4, 2), Vec3(0, 0.5f, 0), "rise at 0.5 s, by 'second'");
}

TEST(GltfAnimation, ASceneTomlClocksItsGltfObjectsByFpsUnderItsOwnKeys) {
  test::TempDir dir;
  moving_nodes().write(dir, "moving.gltf");
  // 2 frames a second: frame 1 is at 0.5 s. The object's own keys move it along z on top.
  const std::string toml = "[animation]\nframes = 5\ninterpolation = \"linear\"\nfps = 2\n"
                           "[[objects]]\ntype = \"gltf\"\nfile = \"moving.gltf\"\n"
                           "[[objects.keys]]\nframe = 0\ntranslate = [0, 0, 0]\n"
                           "[[objects.keys]]\nframe = 4\ntranslate = [0, 0, 4]\n";
  const std::string path = test::write_text(dir.file("s.toml"), toml);
  const auto f1 = frame_of(path, 1);
  expect_near(corner(*f1, 0, 2), Vec3(1, 0, 1), "slide at 0.5 s, moved 1 along z by the keys");
  expect_near(f1->camera.eye, Vec3(0.5f, 1, 6), "the glTF's camera, at 0.5 s, under the object's transform");
  // The default is 24 frames a second: frame 1 is at 1/24 s.
  std::string at24 = toml;
  at24.replace(at24.find("fps = 2\n"), 8, "");
  const auto g1 = frame_of(test::write_text(dir.file("d.toml"), at24), 1);
  EXPECT_NEAR(corner(*g1, 0, 2).x, 2.0 / 24, 1e-6);
  // A still scene sees the file at 0 s.
  const auto still = load_scene(test::write_text(dir.file("still.toml"), "[[objects]]\ntype = \"gltf\"\nfile = \"moving.gltf\"\n"));
  EXPECT_FALSE(still->animated());
  expect_near(corner(*still, 0, 2), Vec3(0, 0, 0), "slide in a still");
  for (const char* bad : {"fps = 0", "fps = -24", "fps = 1e9", "fps = \"fast\""}) {
    std::string t = toml;
    t.replace(t.find("fps = 2"), 7, bad);
    test::expect_scene_refused(t, "fps");
  }
}

// A textured wall, the glTF's camera sliding sideways and a little forward over [0, 0.125] s
// (frames 0 .. 3 at 24 fps), as sequence_test.cpp's pan scene does with scene keys.
Gltf panning_wall(const std::string& png_bytes) {
  Gltf g;
  g.doc["images"] = {{{"uri", "data:image/png;base64," + test::base64(png_bytes)}}};
  g.doc["textures"] = {{{"source", 0}}};
  const int wall = g.material({{"pbrMetallicRoughness", {{"baseColorTexture", {{"index", 0}}}, {"metallicFactor", 0}}},
                               {"extensions", {{"KHR_materials_specular", {{"specularFactor", 0}}}}}});
  g.doc["extensionsUsed"] = {"KHR_materials_specular"};
  // An 8 x 8 wall in the plane z = 0 facing +z, the checker repeated 6 times across.
  g.mesh({-4, -4, 0, 4, -4, 0, 4, 4, 0, -4, 4, 0}, test::kQuad, wall, {0, 6, 6, 6, 6, 0, 0, 0});
  g.doc["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 40 * kPi / 180}, {"znear", 0.01}}}}};
  const int camera = g.root({{"camera", 0}, {"translation", {0, 0, 4}}});
  g.channel(0, camera, "translation", {0, 0.125f}, {0, 0, 4, 0.6f, 0.1f, 3.7f});
  return g;
}

TEST(GltfAnimation, AGltfSequenceRendersFrameFilesWhoseMotionReprojectsThePreviousFrame) {
  test::TempDir dir;
  const std::string path = panning_wall(test::read_bytes(test::write_checker_png(dir))).write(dir, "pan.gltf");
  const auto f0 = frame_of(path, 0), f1 = frame_of(path, 1);
  ASSERT_EQ(f0->frames, 4);
  const RenderSettings s = test::reprojection_settings();
  const AovFrame a = render_sequence_frame(*f0, nullptr, s), b = render_sequence_frame(*f1, f0.get(), s);
  // The wall fills the view; columns and rows away from the sides (what the motion uncovers).
  const test::Reprojection r =
      test::reprojection(a.layer(layer::kAlbedo), b.layer(layer::kAlbedo), b.layer(layer::kMotion), 12, 84, 8, 64);
  EXPECT_GT(r.max_motion, 2.0) << "the camera moves several pixels per frame";
  // The magnified 4 x 4 texture is smooth, so bilinear resampling loses little: measured about
  // 1/1600 of the unwarped error; 1/20 is the bound.
  EXPECT_LT(r.warped, r.still / 20) << "warped " << r.warped / r.pixels << " unwarped " << r.still / r.pixels;
  EXPECT_GT(b.layer(layer::kMotion).at(48, 36, 0), 0.5f) << "the camera moved right: the wall's points were to the right";

  // `render x.gltf --frames 0:3`: one file a frame, with its motion layer and its frame number.
  auto run = test::run_in(dir, "render " + path + " --frames 0:3 --size 24x16 --spp 2 --reflection-levels 0 -o " +
                                   dir.file("out/f.exr"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  for (int t = 0; t < 3; ++t) {
    const AovFrame f = read_frame(dir.file(fmt::format("out/f_{:04d}.exr", t)), {layer::kMotion});
    EXPECT_EQ(f.meta.extra.at("frame"), std::to_string(t));
    EXPECT_EQ(f.meta.extra.at("frames"), "4");
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("out/f_0003.exr")));
  auto past = test::run_in(dir, "render " + path + " --frames 2:5 --size 8x8 --spp 1 -o " + dir.file("past.exr"));
  EXPECT_EQ(past.exit_code, 2) << past.output;
  EXPECT_NE(past.output.find("has 4 frames"), std::string::npos) << past.output;
}

// The motion layer finds a hit's triangle by index in the previous frame: a node that an
// animation shrinks to nothing keeps its (flattened) triangles, and a point light's sphere, sized
// by the file's extent, keeps its size while other nodes move.
TEST(GltfAnimation, AnAnimatedNodeKeepsItsTrianglesAndALightItsSizeInEveryFrame) {
  test::TempDir dir;
  Gltf g;
  const int quad = g.mesh(test::quad_positions({-2, 0, 2, 2, 0, 2, 2, 0, -2, -2, 0, -2}), test::kQuad, -1);
  g.doc["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 0.7}, {"znear", 0.01}}}}};
  g.root({{"camera", 0}, {"translation", {0, 2, 4}}});
  g.doc["extensions"] = {{"KHR_lights_punctual", {{"lights", {{{"type", "point"}, {"intensity", 3}}}}}}};
  g.root({{"translation", {0, 3, 0}}, {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
  g.channel(0, quad, "scale", {0, 1}, {1, 1, 1, 0, 0, 0});
  const std::string path = g.write(dir, "shrink.gltf");
  const auto f0 = frame_of(path, 0), f12 = frame_of(path, 12), f24 = frame_of(path, 24);
  EXPECT_EQ(f24->meshes[0].triangles(), f0->meshes[0].triangles());
  EXPECT_EQ(f24->meshes[0].positions[0].x, 0.0f) << "scaled to nothing";
  EXPECT_NEAR(f12->meshes[0].positions[0].x, -1, 1e-6) << "half its size";
  ASSERT_EQ(f24->sphere_lights.size(), 1u);
  EXPECT_EQ(f24->sphere_lights[0].radius, f0->sphere_lights[0].radius);
  RenderSettings s;
  s.width = 8;
  s.height = 6;
  s.spp = 1;
  const AovFrame f = render_sequence_frame(*f24, f12.get(), s);
  EXPECT_TRUE(f.has(layer::kMotion));
}

// One malformed or refused animation per kind: each an InputError that starts with the file's
// path and says where and what.
TEST(GltfAnimation, MalformedAnimationsAndMovingLightsAreRefusedNamingTheAnimationAndChannel) {
  test::TempDir dir;
  Gltf good;
  const int quad = good.mesh(test::quad_positions({-2, 0, 2, 2, 0, 2, 2, 0, -2, -2, 0, -2}), test::kQuad, -1);
  good.doc["cameras"] = {{{"type", "perspective"}, {"perspective", {{"yfov", 0.7}, {"znear", 0.01}}}}};
  good.root({{"camera", 0}, {"translation", {0, 2, 4}}});
  good.channel(0, quad, "translation", {0, 1}, {0, 0, 0, 1, 0, 0});
  good.doc["animations"][0]["name"] = "slide";
  ASSERT_NO_THROW(load_scene(good.write(dir, "good.gltf")));
  // Accessors: 0 positions, 1 indices, 2 the sampler's times, 3 its values.
  const std::string channel = "/animations/0/channels/0: animation 'slide' channel 0, node 0 translation";
  const std::string moved = "/animations/0/channels/0 (animation 'slide' channel 0, node 0 translation)";
  const json point_light = {{"KHR_lights_punctual", {{"lights", {{{"type", "point"}, {"intensity", 3}}}}}}};
  struct Case {
    const char* name;
    std::function<void(Gltf&)> edit;
    std::vector<std::string> expected;
  };
  const std::vector<Case> cases = {
      {"count", [](Gltf& g) { g.doc["accessors"][3]["count"] = 1; }, {channel, "has 2 key times and its output /accessors/3 1 values"}},
      {"cubic-count", [](Gltf& g) { g.doc["animations"][0]["samplers"][0]["interpolation"] = "CUBICSPLINE"; },
       {channel, "(expected 6: in-tangent, value and out-tangent a key for CUBICSPLINE)"}},
      {"non-float-times", [](Gltf& g) { g.doc["accessors"][2]["componentType"] = 5123; }, {channel, "key times are SCALAR floats"}},
      {"vec2-values", [](Gltf& g) { g.doc["accessors"][3]["type"] = "VEC2"; }, {channel, "a translation is VEC3 floats"}},
      {"not-rising",
       [](Gltf& g) {
         const float t[2] = {1, 1};
         std::memcpy(&g.bin[std::size_t(g.doc["bufferViews"][2]["byteOffset"].get<int>())], t, 8);
       },
       {channel, "key times must rise strictly: 1 s after 1 s"}},
      {"negative-time",
       [](Gltf& g) {
         const float t = -1;
         std::memcpy(&g.bin[std::size_t(g.doc["bufferViews"][2]["byteOffset"].get<int>())], &t, 4);
       },
       {channel, "first key time is -1 s"}},
      {"nan-value",
       [](Gltf& g) {
         const float nan = std::nanf("");
         std::memcpy(&g.bin[std::size_t(g.doc["bufferViews"][3]["byteOffset"].get<int>())], &nan, 4);
       },
       {channel, "/accessors/3: element 0 component 0 is nan"}},
      {"interpolation", [](Gltf& g) { g.doc["animations"][0]["samplers"][0]["interpolation"] = "SMOOTH"; },
       {"/animations/0/samplers/0/interpolation: 'SMOOTH': expected LINEAR, STEP or CUBICSPLINE"}},
      {"sampler-index", [](Gltf& g) { g.doc["animations"][0]["channels"][0]["sampler"] = 4; },
       {"/animations/0/channels/0/sampler: animations/0/samplers 4 does not exist"}},
      {"no-target", [](Gltf& g) { g.doc["animations"][0]["channels"][0].erase("target"); }, {"/animations/0/channels/0/target: missing"}},
      {"no-channels", [](Gltf& g) { g.doc["animations"][0]["channels"] = json::array(); }, {"/animations/0/channels: missing or empty"}},
      {"twice",
       [](Gltf& g) { g.doc["animations"][0]["channels"].push_back(g.doc["animations"][0]["channels"][0]); },
       {"/animations/0/channels/1/target: a second channel of the animation targets node 0's translation"}},
      {"matrix",
       [](Gltf& g) { g.doc["nodes"][0]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1}; },
       {"/animations/0/channels/0/target/node: node 0 is animated but has a matrix"}},
      {"light",
       [&](Gltf& g) {
         g.doc["extensions"] = point_light;
         g.doc["nodes"][0]["extensions"] = {{"KHR_lights_punctual", {{"light", 0}}}};
       },
       {"/nodes/0/extensions/KHR_lights_punctual: light 0 moves with " + moved, "lights do not move"}},
      {"light-of-a-child",
       [&](Gltf& g) {
         g.doc["extensions"] = point_light;
         g.doc["nodes"].push_back({{"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
         g.doc["nodes"][0]["children"] = {g.doc["nodes"].size() - 1};
       },
       {"/nodes/2/extensions/KHR_lights_punctual: light 0 moves with " + moved}},
      {"emitter",
       [](Gltf& g) {
         g.doc["materials"] = {{{"emissiveFactor", {1, 1, 1}}}};
         g.doc["meshes"][0]["primitives"][0]["material"] = 0;
       },
       {"/nodes/0: mesh 0 moves with " + moved, "a moving object cannot emit"}},
  };
  for (const Case& c : cases) {
    Gltf g = good;
    c.edit(g);
    const std::string path = g.write(dir, std::string(c.name) + ".gltf");
    try {
      frame_of(path, 1);
      ADD_FAILURE() << c.name << ": accepted";
    } catch (const InputError& e) {
      const std::string what = e.what();
      EXPECT_EQ(what.rfind(path + ": ", 0), 0u) << c.name << ": " << what;
      for (const std::string& x : c.expected) EXPECT_NE(what.find(x), std::string::npos) << c.name << ": " << x << " in " << what;
    }
  }
}

}  // namespace
}  // namespace dnb
