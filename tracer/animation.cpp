#include "tracer/animation.h"

#include <algorithm>
#include <cmath>

namespace dnb::rt {

std::vector<double> KeyTrack::at(double frame, Interpolation interpolation) const {
  const std::size_t n = frames.size();
  if (n == 0) return {};
  if (frame <= frames.front()) return values.front();
  if (frame >= frames.back()) return values.back();
  // The segment [i, i + 1] that holds the frame.
  std::size_t i = std::size_t(std::upper_bound(frames.begin(), frames.end(), frame) - frames.begin()) - 1;
  const double u = (frame - frames[i]) / double(frames[i + 1] - frames[i]);
  const auto& p1 = values[i];
  const auto& p2 = values[i + 1];
  std::vector<double> out(p1.size());
  if (interpolation == Interpolation::kLinear) {
    for (std::size_t c = 0; c < out.size(); ++c) out[c] = p1[c] + (p2[c] - p1[c]) * u;
    return out;
  }
  // Uniform Catmull-Rom through p0, p1, p2, p3 (end keys repeated), evaluated at u in [0, 1]:
  // passes through p1 at u = 0 and p2 at u = 1 with tangents (p2 - p0) / 2 and (p3 - p1) / 2.
  const auto& p0 = values[i == 0 ? 0 : i - 1];
  const auto& p3 = values[std::min(i + 2, n - 1)];
  const double u2 = u * u, u3 = u2 * u;
  for (std::size_t c = 0; c < out.size(); ++c)
    out[c] = 0.5 * (2 * p1[c] + (-p0[c] + p2[c]) * u + (2 * p0[c] - 5 * p1[c] + 4 * p2[c] - p3[c]) * u2 +
                    (-p0[c] + 3 * p1[c] - 3 * p2[c] + p3[c]) * u3);
  return out;
}

std::uint64_t frame_seed(std::uint64_t seed, int frame) {
  std::uint64_t z = seed * 0x9e3779b97f4a7c15ULL + std::uint64_t(std::uint32_t(frame)) + 0x632be59bd9b4e019ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  return z >> 11;  // 53 bits
}

}  // namespace dnb::rt
