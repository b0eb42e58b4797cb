// A vectorisable exp for the edge-stopping weights of the a-trous filters (atrous, svgf).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace dnb {

// exp(x) for x <= 0, to 1.1e-5 relative (measured over [-80, 0]; below -87 it returns
// exp(-87)): 2^t split into integer and fraction, the fraction's power by its degree-6 Taylor
// polynomial. Written here because glibc's expf does not vectorise without
// -ffast-math, and the edge-stopping weights need nothing better; it is a plain function of
// its argument, so results do not depend on vector width or threads.
inline float exp_nonpositive(float x) {
  const float t = std::max(x, -87.0f) * 1.44269504089f;  // log2(e)
  const float n = std::floor(t);
  const float f = t - n;  // [0, 1)
  // Taylor series of 2^f = e^(f ln 2), evaluated by Horner's rule.
  float p = 1.5403530e-4f;
  p = p * f + 1.3333558e-3f;
  p = p * f + 9.6181291e-3f;
  p = p * f + 5.5504109e-2f;
  p = p * f + 2.4022651e-1f;
  p = p * f + 6.9314718e-1f;
  p = p * f + 1.0f;
  const std::int32_t bits = (std::int32_t(n) + 127) << 23;
  float scale;
  std::memcpy(&scale, &bits, sizeof scale);
  return p * scale;
}

}  // namespace dnb
