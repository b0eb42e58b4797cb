// The go/no-go experiment of docs/speed.md ("The next step, and in what order"): a path tracer
// vectorised across paths, to learn whether the tracer's speed goal against Mitsuba 3's LLVM
// back-end (issue 52: 1.3x, with the harness's AOVs on) is within reach of a vectorised
// integrator before one is written for every material. Not a tracer version and not used by any
// command: BM_ColourCore (bench/mitsuba_bench.cpp) times it, tests/tracer/colour_core_test.cpp
// checks that it traces the tracer's paths. In the tracer's library, beside the integrator it
// is the first step of, so that those tests keep it true as the tracer changes.
//
// What it computes: the tracer's estimator for a scene of diffuse and emissive triangles
// (PathTracer::decompose and trace): a path of at most `max_depth` vertices, next-event
// estimation at every vertex with one light sample (emissive triangles chosen as Scene::commit
// chooses them), the emission a path meets weighted by the power heuristic against that light
// sample, Russian roulette on the path's throughput after `rr_depth` vertices with
// q = min(0.95, max component), and the level-0 split of each sample (E, T, D and I for a white
// surface, the normal and depth of the first hit). Random numbers are either independent (a hash
// of each path's 64-bit key per number, as Mitsuba's `independent` sampler) or the tracer's own
// (rt::Sampler's scrambled Sobol' points, in the same slots as PathTracer reads them: the same
// paths as the tracer's up to rounding). Geometric normals (the McGuire box's faces are flat),
// no textures.
//
// How: N paths at once (N = 8 for AVX2, 16 for AVX-512), their state in structure-of-arrays
// vectors (std::experimental::simd from libstdc++, so that the arithmetic is written once for
// either width); each vertex traces the N rays as one Embree packet (rtcIntersect8/16) and the N
// shadow rays as another (rtcOccluded8/16). A lane whose path ends starts the next path of its
// rows or pixels at once (path regeneration), so that packets stay full until the work runs
// out. The work is split into fixed blocks, each traced by one task in a fixed order: the same
// seed gives the same image at every thread count.
//
// It covers scenes of diffuse triangles and emissive triangles and nothing else; supported()
// says why a scene is refused.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "tracer/render.h"
#include "tracer/scene.h"

namespace dnb {

// As a PixelSampler (tracer/render.h), it traces render_frame's main pass in its stead: each
// sample's level-0 layers as the tracer's decomposition defines them for a diffuse first hit
// (PathTracer::decompose: D and I for a white surface, T, E, the normal and depth), so that the
// accumulation of every layer, the variances, the half buffers and the edge set are the tracer's
// own code and their cost is in the measurement.
class ColourCore : public PixelSampler {
 public:
  enum class Trace { kPackets, kSingleRays };
  // kIndependent: a hash of each path's key per number (draw() in colour_core.cpp), as Mitsuba's
  // `independent` sampler. kTracer: the tracer's own (rt::Sampler's scrambled Sobol' points, the
  // same numbers for the same purposes as PathTracer's): trace_pixels only, spp <= 256.
  enum class Numbers { kIndependent, kTracer };
  struct Options {
    int width = 1024, height = 768, spp = 64, max_depth = 8, rr_depth = 3;
    int lanes = 8;                        // 8 or 16
    Trace trace = Trace::kPackets;        // kSingleRays: the same lanes, each ray traced alone
    const char* embree_config = "max_isa=avx2";  // the tracer's (Scene::kEmbreeConfig) by default
    Numbers numbers = Numbers::kIndependent;
    std::uint64_t seed = 1;               // kTracer: RenderSettings::seed gives the tracer's numbers
  };
  // Empty when the scene is one the core renders; else why not.
  static std::string supported(const Scene& scene);
  // Builds its own Embree scene from `scene`'s meshes (with options.embree_config).
  ColourCore(const Scene& scene, const Options& options);
  ~ColourCore() override;
  ColourCore(const ColourCore&) = delete;
  ColourCore& operator=(const ColourCore&) = delete;

  // Renders the colour alone: width x height x 3 floats (linear RGB, row-major, the mean of spp
  // paths per pixel), on every core. `rays`, when given, receives the rays traced (camera,
  // bounce, shadow).
  std::vector<float> render(double* rays = nullptr) const;

  // PixelSampler: samples of Options::width x height pixels (Options::spp is not used).
  std::uint64_t trace_pixels(int x0, int y, int count, int spp, rt::SampleResult* out) const override;

  struct Data;  // what the lanes gather (colour_core.cpp)

 private:
  const Scene& scene_;
  Options opt_;
  std::unique_ptr<Data> data_;
};

}  // namespace dnb
