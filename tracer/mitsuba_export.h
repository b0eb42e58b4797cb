// A loaded scene (tracer/scene_loader.h) as a Mitsuba 3 scene, so that a real renderer can render
// what the tracer renders: the agreement test (tests/tracer/mitsuba_agreement_test.cpp) and the
// speed comparison render the same folder.
//
//   auto scene = load_scene("my/room.toml");
//   export_mitsuba(*scene, {.width = 64, .height = 48, .spp = 256, .max_depth = 6}, "out/room");
//   // out/room/scene.xml and out/room/meshes/*.ply; render with python/mitsuba_render.py
//
// The folder holds a Mitsuba 3 XML scene (version 3.0.0) and one binary little-endian PLY per
// (mesh, material) pair (a Mitsuba shape has one BSDF), 3 vertices per triangle as the tracer
// stores corners, in the tracer's world coordinates (no transform). Normals are written only
// where the mesh has them (flat meshes get `face_normals`: Mitsuba's face normal from the same
// counter-clockwise winding as the tracer's front); texture coordinates where the mesh has them.
//
// The mapping, and why each one is exact:
//   camera          perspective (fov_axis y, lookat) or thinlens (aperture_radius,
//                   focus_distance: both put the sharp plane at that distance along the view
//                   axis and sample the lens by the concentric map); box pixel filter, an
//                   independent sampler with the seed, hdrfilm rgb; near_clip far below any
//                   surface the tracer would hit
//   diffuse         twosided(diffuse): the tracer's diffuse, mirror, conductor and plastic
//                   surfaces reflect on both sides, Mitsuba's on the front only without twosided
//   mirror          twosided(conductor, material none, specular_reflectance = tint)
//   conductor       twosided(conductor | roughconductor ggx alpha_u/alpha_v), eta/k rgb,
//                   specular_reflectance = tint
//   dielectric      dielectric | roughdielectric ggx | thindielectric, int_ior = ior, ext_ior 1,
//                   specular_reflectance = tint, specular_transmittance = transmittance
//                   (one-sided in both: the side is the winding's)
//   plastic         twosided(plastic | roughplastic ggx), diffuse_reflectance = albedo,
//                   specular_reflectance = tint, int_ior = ior, nonlinear = true: the tracer's
//                   base is (1 - F_i)(1 - F_o) albedo / (eta^2 pi (1 - albedo Fdr)), which is
//                   Mitsuba's plastic with nonlinear = true (src/bsdfs/plastic.cpp); false
//                   would divide by (1 - Fdr) instead
//   emitter         an `area` emitter on the shape (front face only, as the tracer's)
//   constant sky    a `constant` emitter
//   integrator      path with the same max_depth (segments, camera ray included: both count
//                   the same way) and rr_depth = the tracer's (PathTracer::Options::rr_depth, 3):
//                   both then play Russian roulette first on the way to vertex 4, with the same
//                   probability min(0.95, max component of the path's throughput); Mitsuba
//                   decides before tracing that segment, the tracer after (it traces the
//                   segment and counts its emission, then stops before the vertex's light sample
//                   and bounce), so the tracer does a little more work per path, never less.
//                   (Mitsuba multiplies that probability by eta^2 after refractions, the
//                   tracer does not: both unbiased). With Mitsuba's default rr_depth (5) it
//                   traced more of each path than the tracer, and the speed case
//                   (bench/mitsuba_bench.cpp) flattered the tracer: Mitsuba renders it 8%
//                   faster at 3 than at 5 (2026-12-07, 512x384, 64 spp)
//
// Known model differences (not refused; tests/tracer/mitsuba_agreement_test.cpp bounds each one
// by quadrature and adds the bound to its tolerance):
//   - Mitsuba's microfacet masking is the separable G1(wi) G1(wo) (include/mitsuba/render/
//     microfacet.h, G()); the tracer's is the height-correlated Smith G2, never smaller.
//   - roughplastic's base uses the rough coat's transmittance t(cos) (1 - its rough specular
//     albedo, tabulated) and a rough internal reflectance; the tracer's rough plastic keeps the
//     smooth coat's (1 - F(cos)) and Fdr. Equal at alpha -> 0, apart by a few percent at 0.3.
//   - plastic's Fdr is a fitted polynomial in Mitsuba (fresnel_diffuse_reflectance, within 0.1 %
//     for ior 1-1.5), a quadrature in the tracer.
//
// Refused with an InputError naming the scene, the material or feature and why (what Mitsuba 3
// cannot represent exactly; nothing is approximated silently): the `coated` material (Schlick-
// weighted mirror and base lobes), Schlick conductors, the sun (a finite disc of constant
// radiance: Mitsuba's `directional` is a delta), the gradient sky, absorption inside glass (would
// need volpath and a medium), two-sided emitters (Mitsuba's area emitter is one-sided, and a
// reversed coincident copy would occlude it at random), textures (not exported: image textures'
// v orientation and texel centres are not checked against Mitsuba's bitmap yet; procedural ones
// would need baking), anisotropic roughness on plastic (roughplastic is isotropic), and
// anisotropic roughness where the tracer's tangent frame cannot be Mitsuba's (interpolated
// normals, or a face whose back-side frame Frame(-n) has other axes than Frame(n)).
// Not a representation limit but Mitsuba 3.5.2's: scalar_rgb renders emitters black at
// max_depth 1 (shared/interop/RENDERERS.md), so compare at max_depth >= 2.
#pragma once

#include <cstdint>
#include <string>

namespace dnb {

class Scene;  // tracer/scene.h

struct MitsubaExportSettings {
  int width = 256;          // film size in pixels
  int height = 192;
  int spp = 64;             // the sampler's sample_count
  int max_depth = 8;        // path length in segments (the tracer's RenderSettings::max_depth)
  std::uint64_t seed = 1;   // the sampler's seed (Mitsuba takes 32 bits)
};

// InputError "scene 'NAME': FEATURE: why" for the first thing of the scene that Mitsuba 3 cannot
// represent exactly (see the top). Only materials that some triangle uses are checked.
void check_mitsuba_exportable(const Scene& scene);

// Writes DIR/scene.xml and DIR/meshes/*.ply. The folder appears whole or not at all: everything
// is written into a temporary folder beside DIR, which is then renamed to DIR. DIR must not exist
// or be an empty folder (InputError otherwise: an export never mixes with other files). Returns
// DIR/scene.xml. InputError as check_mitsuba_exportable, or for settings out of range; WorkError
// when a file cannot be written.
std::string export_mitsuba(const Scene& scene, const MitsubaExportSettings& settings, const std::string& dir);

}  // namespace dnb
