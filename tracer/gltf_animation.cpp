#include "tracer/gltf_animation.h"

#include <algorithm>
#include <cmath>

namespace dnb::rt {
namespace {

std::vector<double> element(const GltfSampler& s, std::size_t key) {
  // CUBICSPLINE keys are (in-tangent, value, out-tangent): the value is the middle one.
  const std::size_t per_key = s.interpolation == GltfInterpolation::kCubicSpline ? 3 : 1;
  const std::size_t at = (key * per_key + (per_key == 3 ? 1 : 0)) * std::size_t(s.width);
  return {s.values.begin() + long(at), s.values.begin() + long(at) + s.width};
}

void normalise(std::vector<double>& q) {
  double n = 0;
  for (double c : q) n += c * c;
  n = std::sqrt(n);
  if (n > 0)
    for (double& c : q) c /= n;
}

// The glTF specification's slerp (Appendix C): the shorter arc, and a normalised lerp where the
// quaternions are nearly equal (the sine of the angle would divide by almost 0).
std::vector<double> slerp(std::vector<double> a, std::vector<double> b, double u) {
  normalise(a);
  normalise(b);
  double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
  if (d < 0) {
    d = -d;
    for (double& c : b) c = -c;
  }
  std::vector<double> out(4);
  if (d > 0.9995) {
    for (int c = 0; c < 4; ++c) out[std::size_t(c)] = a[std::size_t(c)] + (b[std::size_t(c)] - a[std::size_t(c)]) * u;
    normalise(out);
    return out;
  }
  const double angle = std::acos(std::min(d, 1.0));
  const double s = std::sin(angle);
  const double wa = std::sin((1 - u) * angle) / s, wb = std::sin(u * angle) / s;
  for (int c = 0; c < 4; ++c) out[std::size_t(c)] = wa * a[std::size_t(c)] + wb * b[std::size_t(c)];
  return out;
}

}  // namespace

std::vector<double> sample_gltf(const GltfSampler& s, double time) {
  const std::size_t n = s.times.size();
  if (n == 0) return {};
  std::vector<double> out;
  if (n == 1 || !(time > s.times.front())) {
    out = element(s, 0);
  } else if (time >= s.times.back()) {
    out = element(s, n - 1);
  } else {
    // The segment [k, k + 1] with t_k <= time < t_k+1.
    const std::size_t k = std::size_t(std::upper_bound(s.times.begin(), s.times.end(), time) - s.times.begin()) - 1;
    const double td = s.times[k + 1] - s.times[k];
    const double u = (time - s.times[k]) / td;
    if (s.interpolation == GltfInterpolation::kStep) {
      out = element(s, k);
    } else if (s.interpolation == GltfInterpolation::kLinear) {
      const std::vector<double> a = element(s, k), b = element(s, k + 1);
      if (s.rotation) return slerp(a, b, u);
      out.resize(a.size());
      for (std::size_t c = 0; c < a.size(); ++c) out[c] = a[c] + (b[c] - a[c]) * u;
    } else {
      // Hermite basis (glTF 2.0, Appendix C): p = h00 v_k + td h10 b_k + h01 v_k+1 + td h11 a_k+1,
      // b_k key k's out-tangent, a_k+1 key k + 1's in-tangent.
      const std::size_t w = std::size_t(s.width);
      const double* vk = &s.values[(3 * k + 1) * w];
      const double* bk = &s.values[(3 * k + 2) * w];
      const double* ak1 = &s.values[(3 * (k + 1)) * w];
      const double* vk1 = &s.values[(3 * (k + 1) + 1) * w];
      const double u2 = u * u, u3 = u2 * u;
      const double h00 = 2 * u3 - 3 * u2 + 1, h10 = u3 - 2 * u2 + u, h01 = -2 * u3 + 3 * u2, h11 = u3 - u2;
      out.resize(w);
      for (std::size_t c = 0; c < w; ++c) out[c] = h00 * vk[c] + td * h10 * bk[c] + h01 * vk1[c] + td * h11 * ak1[c];
    }
  }
  if (s.rotation) normalise(out);
  return out;
}

}  // namespace dnb::rt
