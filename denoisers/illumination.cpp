#include "denoisers/illumination.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <tbb/parallel_for.h>

namespace dnb {

std::vector<std::string> illumination_layers() {
  return {layer::kDirect, layer::kIndirect, layer::kAlbedo, layer::kReflection, layer::kEmission};
}

Image illumination(const AovFrame& frame) {
  const Image& d = frame.layer(layer::kDirect);
  const Image& i = frame.layer(layer::kIndirect);
  Image out(frame.width(), frame.height(), 3);
  tbb::parallel_for(std::size_t(0), out.size(), [&](std::size_t k) { out.data()[k] = d.data()[k] + i.data()[k]; });
  return out;
}

std::vector<std::string> reflection_guide_layers() {
  return {layer::at_level(1, layer::kAlbedo), layer::at_level(1, layer::kNormal), layer::at_level(1, layer::kDepth)};
}

Image compose(const Image& l, const AovFrame& frame) { return compose(l, frame, frame.layer(layer::kReflection)); }

Image compose(const Image& l, const AovFrame& frame, const Image& r) {
  const Image& t = frame.layer(layer::kAlbedo);
  const Image& e = frame.layer(layer::kEmission);
  Image out(frame.width(), frame.height(), 3);
  tbb::parallel_for(std::size_t(0), out.size(),
                    [&](std::size_t k) { out.data()[k] = l.data()[k] * t.data()[k] + r.data()[k] + e.data()[k]; });
  return out;
}

Image normalized_depth(const AovFrame& frame, int level) {
  const Image& z = frame.layer(layer::at_level(level, layer::kDepth));
  std::vector<float> valid;
  valid.reserve(z.size());
  for (std::size_t k = 0; k < z.size(); ++k)
    if (std::isfinite(z.data()[k]) && z.data()[k] > 0) valid.push_back(z.data()[k]);
  float median = 1.0f;
  if (!valid.empty()) {
    auto mid = valid.begin() + valid.size() / 2;
    std::nth_element(valid.begin(), mid, valid.end());
    median = *mid;
  }
  Image out(frame.width(), frame.height(), 1);
  for (std::size_t k = 0; k < z.size(); ++k) {
    const float v = z.data()[k];
    out.data()[k] = (std::isfinite(v) && v > 0) ? v / median : 0.0f;
  }
  return out;
}

void clamp_luminance(float rgb[3], float bound) {
  const float l = luminance(rgb);
  if (!(l > bound)) return;
  const float s = bound / l;
  for (int c = 0; c < 3; ++c) rgb[c] *= s;
}

FireflySplit split_fireflies(Image layer, float ratio) {
  const int w = layer.width(), h = layer.height();
  FireflySplit r;
  r.kept = std::move(layer);
  if (ratio <= 0) return r;  // excess and bound stay empty
  r.excess = Image(w, h, 3);
  r.bound.assign(std::size_t(w) * h, INFINITY);
  std::vector<float> lum(std::size_t(w) * h);
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t k = std::size_t(y) * w + x;
      lum[k] = luminance(r.kept.data() + k * 3);
    }
  });
  std::vector<std::size_t> cut_rows(std::size_t(h), 0);
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      float m = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if ((dx || dy) && xx >= 0 && yy >= 0 && xx < w && yy < h) m = std::max(m, lum[std::size_t(yy) * w + xx]);
        }
      const std::size_t k = std::size_t(y) * w + x;
      const float b = ratio * m;
      r.bound[k] = b;
      if (!(lum[k] > b)) continue;
      float* kept = r.kept.data() + k * 3;
      float* ex = r.excess.data() + k * 3;
      for (int c = 0; c < 3; ++c) ex[c] = kept[c];
      clamp_luminance(kept, b);
      for (int c = 0; c < 3; ++c) ex[c] -= kept[c];
      ++cut_rows[std::size_t(y)];
    }
  });
  for (std::size_t c : cut_rows) r.cut += c;
  return r;
}

}  // namespace dnb
