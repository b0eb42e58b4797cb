// Small scene files written by the tracer tests into a temporary folder.
#pragma once

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "core/errors.h"
#include "test_util.h"
#include "tracer/scene_loader.h"

namespace dnb::test {

inline std::string write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

// A closed sphere (flat-shaded so that the furnace identity is exact) of albedo `a` emitting
// `le` from its inside, the camera at its centre.
inline std::string furnace_scene(double a, double le) {
  return "[camera]\neye = [0, 0, 0]\nlook_at = [0, 0, -1]\nvfov = 70\n"
         "[materials.wall]\nalbedo = [" + std::to_string(a) + ", " + std::to_string(a) + ", " + std::to_string(a) +
         "]\nemission = [" + std::to_string(le) + ", " + std::to_string(le) + ", " + std::to_string(le) +
         "]\n[[objects]]\ntype = \"sphere\"\nmaterial = \"wall\"\nradius = 1.0\ninward = true\nsmooth = false\n"
         "segments = 24\n";
}

// A 20 x 20 plane of albedo 0.5 at y = 0 under a square light of side `side` at height `h`
// facing down, emitting `le`; no sky. The camera looks at the point under the light's centre
// from the side, below the light's plane.
inline std::string lit_plane_scene(double side, double h, double le) {
  return "[camera]\neye = [0.6, 0.25, 0.0]\nlook_at = [0.0, 0.0, 0.0]\nvfov = 2.0\n"
         "[materials.plane]\nalbedo = [0.5, 0.5, 0.5]\n"
         "[[objects]]\ntype = \"quad\"\nmaterial = \"plane\"\nsize = [20.0, 20.0]\n"
         "[[lights]]\ntype = \"quad\"\nsize = [" + std::to_string(side) + ", " + std::to_string(side) +
         "]\nrotate = [180.0, 0.0, 0.0]\ntranslate = [0.0, " + std::to_string(h) + ", 0.0]\nemission = [" +
         std::to_string(le) + ", " + std::to_string(le) + ", " + std::to_string(le) + "]\n";
}

// Frame `frame` of the animated scene at `path` (docs/sequences.md).
inline std::shared_ptr<const Scene> frame_of(const std::string& path, int frame) {
  SceneLoadOptions o;
  o.frame = frame;
  return load_scene(path, o);
}

// A scene file of `text` is refused by load_scene with an InputError naming the file's line
// ("bad.toml:") and saying `says` (the key, or the reason).
inline void expect_scene_refused(const std::string& text, const std::string& says) {
  TempDir dir;
  const std::string path = write_text(dir.file("bad.toml"), text);
  const std::string msg = error_of<InputError>([&] { load_scene(path); });
  EXPECT_NE(msg.find("bad.toml:"), std::string::npos) << msg;
  EXPECT_NE(msg.find(says), std::string::npos) << msg;
}

}  // namespace dnb::test
