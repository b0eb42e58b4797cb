// glTF 2.0 animation samplers evaluated at a time (docs/gltf.md, "Animations"). tinygltf parses
// a file's animations but does not evaluate them, and no Debian library does: this is the
// evaluation the glTF 2.0 specification defines (section 3.11 and Appendix C), for the node
// properties the import reads (translation, rotation, scale). tracer/gltf_import.cpp reads and
// checks the samplers' accessors, then places each animated node where its channels put it.
#pragma once

#include <vector>

namespace dnb::rt {

enum class GltfInterpolation { kLinear, kStep, kCubicSpline };

// One sampler's keys, checked by the import: times finite, non-negative and strictly rising;
// `width` values per element (3 for translation and scale, 4 for a rotation quaternion x, y, z,
// w); `values` holds one element per key, or three (in-tangent, value, out-tangent) for
// CUBICSPLINE.
struct GltfSampler {
  std::vector<double> times;
  std::vector<double> values;
  int width = 3;
  GltfInterpolation interpolation = GltfInterpolation::kLinear;
  bool rotation = false;  // quaternions: slerp for LINEAR, normalised after CUBICSPLINE
};

// The sampler's value at `time` seconds: the first key's before the first key, the last key's
// after the last; between keys k and k + 1, with u = (time - t_k) / (t_k+1 - t_k):
//  - STEP: key k's value;
//  - LINEAR: lerp, or for rotations the shortest-arc slerp of the unit quaternions;
//  - CUBICSPLINE: the cubic Hermite spline through the values with key k's out-tangent and key
//    k + 1's in-tangent, tangents scaled by the key interval t_k+1 - t_k; rotations normalised.
std::vector<double> sample_gltf(const GltfSampler& s, double time);

}  // namespace dnb::rt
