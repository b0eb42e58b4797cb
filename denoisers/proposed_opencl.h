// proposed's whole filter on an OpenCL device (device = opencl): the frame's layers go up once,
// every step of proposed.cpp runs as kernels (denoisers/proposed.cl and the adaptive-manifold core,
// am/adaptive_manifold.cl) and only the composed image comes back. What stays on the host: the
// scalars it takes from its own copy of the frame (each level's median depth and reflection box,
// the NLM sample's seed and pixels), the 49 x 49 eigen-decomposition of each layer's NLM patch
// covariance (computed on the device and read back: 20 KB, the one wait per filtered layer), and
// enqueueing. docs/opencl-gpu.md says what was measured.
//
// Agreement with the CPU path: the same arithmetic, but in another summation order, the NLM
// sample drawn from a hash of the layer before its firefly cut (the CPU path hashes the cut one)
// and the split vectors seeded from that hash instead of the guide's: within the CPU path's own
// sensitivity to its input's rounding (tests/denoisers/proposed_opencl_test.cpp).
#pragma once

#include <cstdint>

#include "core/aov_frame.h"
#include "denoisers/am/adaptive_manifold.h"
#include "denoisers/method.h"
#include "denoisers/nlm_space.h"

namespace dnb {

// One frame's settings, as proposed.cpp plans them (its Plan and parameters).
struct ProposedDevicePlan {
  AmSettings am;                   // level 0's, with eq. 11's strength for the frame's spp
  AmSettings reflection_am;        // the reflection levels'
  NlmSpaceSettings nlm;
  float sigma_nlm = 0, sigma_direct = 0, sigma_normal = 0, sigma_depth = 0;
  float firefly_ratio = 0;
  int levels = 0;                  // reflection levels filtered
  bool edges = false;              // level 0's edge sub-pixels resolved
  bool reflection_sum = false;     // a reflection level's D + I filtered as one layer
  bool smooth_tints = false;
  int tint_radius = 0;
  float tint_band = 0, tint_normal_distance = 0, tint_depth_distance = 0;
  float detail_guard = 0;
};

// The filtered frame (the layers of the split F = (D + I) T + R + E at every level planned).
// Throws WorkError when OpenCL fails.
Image proposed_opencl(const AovFrame& frame, const ProposedDevicePlan& plan, MethodStats& stats);

// The agreement yardstick's input: the frame with its D and I layers (levels 0 .. levels, those it
// has) multiplied by 1 + eps u, u uniform in [-1, 1] from std::mt19937_64(seed); eps 1e-7 is about
// one float ulp. How far the filter moves on it is its own sensitivity to rounding.
AovFrame with_rounding_noise(const AovFrame& frame, int levels, float eps, std::uint64_t seed);

}  // namespace dnb
