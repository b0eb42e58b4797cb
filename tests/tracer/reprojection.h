// Checks of motion layers (docs/sequences.md): the previous frame fetched where a pixel's motion
// points should match this frame where nothing is uncovered (sequence_test.cpp,
// gltf_animation_test.cpp).
#pragma once

#include <algorithm>
#include <cmath>

#include "core/image.h"
#include "tracer/render.h"

namespace dnb::test {

// The frames the reprojection checks render: 96x72, no reflection levels or edge data, and 64
// samples, since the albedo they compare is noise-free but anti-aliased over the pixel.
inline RenderSettings reprojection_settings() {
  RenderSettings s;
  s.width = 96;
  s.height = 72;
  s.spp = 64;
  s.reflection_levels = 0;
  s.edge_subpixels = false;
  return s;
}

// Bilinear fetch of `img` channel c at film position (fx, fy) (pixel centres at + 0.5).
inline float fetch(const Image& img, float fx, float fy, int c) {
  const float x = fx - 0.5f, y = fy - 0.5f;
  const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
  const float ax = x - float(x0), ay = y - float(y0);
  auto at = [&](int xx, int yy) { return img.at(std::clamp(xx, 0, img.width() - 1), std::clamp(yy, 0, img.height() - 1), c); };
  return (at(x0, y0) * (1 - ax) + at(x0 + 1, y0) * ax) * (1 - ay) + (at(x0, y0 + 1) * (1 - ax) + at(x0 + 1, y0 + 1) * ax) * ay;
}

// Over the pixels [x0, x1) x [y0, y1) and the first three channels: the squared error of the
// previous image warped by the motion layer (fetched at c + motion(c)) against this one, the
// same of the unwarped previous image, and the largest motion (pixels).
struct Reprojection {
  double warped = 0, still = 0, max_motion = 0;
  int pixels = 0;
};
inline Reprojection reprojection(const Image& previous, const Image& current, const Image& motion, int x0, int x1, int y0,
                                 int y1) {
  Reprojection r;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      const float mx = motion.at(x, y, 0), my = motion.at(x, y, 1);
      r.max_motion = std::max(r.max_motion, double(std::hypot(mx, my)));
      for (int c = 0; c < 3; ++c) {
        const double w = fetch(previous, float(x) + 0.5f + mx, float(y) + 0.5f + my, c) - current.at(x, y, c);
        const double u = previous.at(x, y, c) - current.at(x, y, c);
        r.warped += w * w;
        r.still += u * u;
      }
      ++r.pixels;
    }
  return r;
}

}  // namespace dnb::test
