// Wavefront OBJ meshes and their MTL materials (read by tinyobjloader) appended to a Scene: an
// [[objects]] entry of type "obj" in a scene file (configs/scenes/README.md). The scene schema
// (tracer/scene_loader.cpp) finds the file and the override material; this file maps the OBJ's
// content onto the tracer's meshes, materials and textures.
//
// Material mapping (MTL -> tracer/scene.h):
//  - albedo = Kd clamped to 1, emission = Ke; map_Kd is an image texture (and a black Kd
//    becomes white, which is what most exporters mean by it);
//  - specular when illum is 3, 5 or 7, or Ks > 0 with Ns >= 200: a mirror of tint Ks when Kd is
//    (almost) black, else a coated diffuse of index Ni (1.5 when Ni <= 1);
//  - faces without a material get "<stem>/(no material)", a default diffuse.
// File names in the MTL file are found ignoring letter case (find_file_ignoring_case).
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "tracer/shapes.h"

namespace dnb {
class Scene;
}

namespace dnb::rt {

// Appends the OBJ file at `path` to `scene`: one material per MTL material plus the fallback,
// the textures they name, one mesh of the file's triangles (transformed by x; degenerate ones
// dropped; normals flat where a face has none) named after the file's stem. `material`: when
// set, every face gets this scene material instead of its own. The OBJ file, its mtllib files and
// its textures are appended to scene.files, in that order (scene_content_hash reads them).
// InputError naming the file when it cannot be read, has no triangles, indexes out of range or
// names a missing texture.
void import_obj(Scene& scene, const std::filesystem::path& path, const Transform& x,
                std::optional<unsigned> material);

// A file name as written in an MTL file, found on disk: the exact name first, else the one file
// of that folder whose name matches ignoring letter case (sponza.mtl says SP_LUK.JPG for
// sp_luk.JPG). Backslashes are taken as folder separators. Empty when there is none.
std::filesystem::path find_file_ignoring_case(const std::filesystem::path& dir, std::string name);

}  // namespace dnb::rt
