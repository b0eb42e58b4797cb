// Keyframed animation of a scene (docs/sequences.md): keys at integer frame indices, interpolated
// linearly or by a uniform Catmull-Rom spline per component, and the sample seed of a frame.
// The scene loader (tracer/scene_loader.cpp) evaluates the camera's and objects' keys at the frame
// it loads; the result is an ordinary (static, or motion-blurred) scene.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace dnb::rt {

enum class Interpolation { kLinear, kCatmullRom };

// One animated quantity: keys (frame, values) with strictly rising frames, every key the same
// number of values.
struct KeyTrack {
  std::vector<int> frames;
  std::vector<std::vector<double>> values;
  bool empty() const { return frames.empty(); }
  // The values at `frame` (a real number: a motion-blurred frame's end is frame + 1): the first
  // key's before it, the last key's after, between keys as `interpolation` says.
  std::vector<double> at(double frame, Interpolation interpolation) const;
};

// The sample seed of frame `frame` of a sequence rendered with seed `seed`: a hash of both
// (SplitMix64's finaliser over the pair), so that consecutive frames' noise is independent, as an
// animated seed makes it in production renderers, and bounded like any seed (below 2^53, so that
// it survives a JSON number).
std::uint64_t frame_seed(std::uint64_t seed, int frame);

}  // namespace dnb::rt
