// Checks of a loaded scene's geometry that no single file's parser can make.
//
// Coplanar overlaps: two faces that lie in one plane (closer than the offset by which a ray
// leaves a surface, SurfaceHit::offset) and overlap with positive area, where it matters which
// one a ray meets: their materials differ, or one of them is transmissive (a ray inside glass
// that meets the glass's face and a floor in one plane leaves through whichever the traversal
// reports first). Which one that is, is the ray tracer's tie-break: it differs between Embree's
// kernels and between renderers, so such a scene renders differently on an AVX2 and an AVX-512
// kernel and disagrees with Mitsuba in a band (the plant's sill and the Mitsuba test's glass box
// were both this, docs/speed.md). load_scene warns about every one it finds; the built-in scenes
// have none (tests/tracer/scene_check_test.cpp).
#pragma once

#include <string>
#include <vector>

#include "tracer/scene.h"

namespace dnb {

// The overlapping coplanar faces of one pair of (mesh, material), a < b.
struct CoplanarOverlap {
  unsigned mesh_a = 0, mesh_b = 0;
  unsigned material_a = 0, material_b = 0;
  std::size_t pairs = 0;  // triangle pairs that overlap
  double area = 0;        // their summed overlap area, in scene units squared
  rt::Vec3 where;         // a point inside the largest overlap
};

// Every pair of (mesh, material) with overlapping coplanar faces, the largest overlap first.
// Static geometry at time 0 (a moving mesh's first time step). Runs in O(n log n) for n
// triangles: triangles are bucketed by their plane, and only triangles in one bucket whose
// bounding boxes meet are compared.
std::vector<CoplanarOverlap> find_coplanar_overlaps(const Scene& scene);

// One line for a user: the meshes, materials, area, a point, and what to do.
std::string describe(const Scene& scene, const CoplanarOverlap& o);

}  // namespace dnb
