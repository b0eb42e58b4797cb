// Checks of a loaded scene's geometry that no single file's parser can make.
//
// Coplanar overlaps: two faces that lie in one plane (closer than the offset by which a ray
// leaves a surface, SurfaceHit::offset) and overlap with positive area, where it matters which
// one a ray meets: their materials differ, or one of them is transmissive (a ray inside glass
// that meets the glass's face and a floor in one plane leaves through whichever the traversal
// reports first). Which one that is, is the ray tracer's tie-break: it differs between Embree's
// kernels and between renderers, so such a scene renders differently on an AVX2 and an AVX-512
// kernel and disagrees with Mitsuba in a band, and a new tracer version cannot pass
// scripts/tracer_agreement on it (docs/speed.md). load_scene warns about every one it finds; the
// built-in scenes have none (tests/tracer/scene_check_test.cpp).
#pragma once

#include <cstdint>
#include <string>
#include <tuple>
#include <vector>

#include "tracer/scene.h"

namespace dnb {

// The overlapping coplanar faces of one pair of (mesh, material), a < b.
struct CoplanarOverlap {
  unsigned mesh_a = 0, mesh_b = 0;
  unsigned material_a = 0, material_b = 0;
  std::size_t pairs = 0;  // triangle pairs that overlap
  double area = 0;        // their summed overlap area, in scene units squared
  rt::Vec3 where;         // a point of an overlap that a camera ray reaches
  bool at_close = false;  // found with the moving meshes where the shutter closes (ShutterEnd)
  // Which pair of (mesh, material) it is: what the shutter's two ends and a sequence's frames
  // are merged by.
  std::tuple<unsigned, unsigned, unsigned, unsigned> pair() const { return {mesh_a, material_a, mesh_b, material_b}; }
};

// Where moving meshes are checked (a motion-blurred scene's meshes have positions at several
// time steps over the shutter, Mesh::later_positions): at the shutter's open (every mesh's first
// step, time 0) or its close (every mesh's last step, time 1). In between, positions are
// interpolated; an overlap only there is not looked for.
enum class ShutterEnd { kOpen, kClose };

// Work limits. Faces stacked in one place (a quad's `repeat` copies with no offset, two such
// objects of different materials) make the pairs quadratic in their number; the check stops at
// these. The project's largest scene, mcguire-conference (331,000 triangles), needs 4.0 M
// comparisons and 31,000 exact tests (`--log-level debug` prints them), in 0.25 s of its 0.95 s
// `render` at 8x6 (2 cores).
struct CoplanarCheckLimits {
  std::uint64_t comparisons = 50'000'000;  // bounding boxes and materials: a few ns each
  std::size_t exact_tests = 100'000;       // planes and a Boost.Geometry intersection: ~15 us each
  std::size_t probes = 400;                // reachability probes: 65 to about 1,000 ray queries each
};

// Every pair of (mesh, material) with overlapping coplanar faces that a camera ray can reach,
// the largest overlap first, with the geometry at `end` (rays probe at its time). Triangles
// are bucketed by their plane, and only triangles in one bucket whose bounding boxes meet are
// compared: about n log n for n triangles. Past a limit the check stops with what it found and
// sets *complete to false (else true).
std::vector<CoplanarOverlap> find_coplanar_overlaps(const Scene& scene, bool* complete = nullptr,
                                                    CoplanarCheckLimits limits = {},
                                                    ShutterEnd end = ShutterEnd::kOpen);
// Both ends where a mesh moves (the open's findings, then the close's pairs of (mesh, material)
// not found at the open), else the open's alone. *complete: false when either check stopped at
// its limit.
std::vector<CoplanarOverlap> find_coplanar_overlaps_over_shutter(const Scene& scene, bool* complete = nullptr,
                                                                 CoplanarCheckLimits limits = {});

// One line for a user: the meshes, materials, area, a point, and what to do.
std::string describe(const Scene& scene, const CoplanarOverlap& o);

}  // namespace dnb
