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

FireflySplit split_fireflies(Image layer, float ratio, bool with_excess) {
  const int w = layer.width(), h = layer.height();
  FireflySplit r;
  r.kept = std::move(layer);
  if (ratio <= 0) return r;  // excess and bound stay empty
  if (with_excess) r.excess = Image(w, h, 3);
  r.bound.resize(std::size_t(w) * h);
  std::vector<float> lum(std::size_t(w) * h);
  tbb::parallel_for(0, h, [&](int y) {
    const float* p = r.kept.pixel(0, y);
    float* l = lum.data() + std::size_t(y) * w;
    for (int x = 0; x < w; ++x) l[x] = luminance(p + std::size_t(x) * 3);
  });
  std::vector<std::size_t> cut_rows(std::size_t(h), 0);
  tbb::parallel_for(0, h, [&](int y) {
    // Each pixel's bound: ratio times the largest luminance of its 8 neighbours (those inside
    // the image). The interior without bounds tests, so that it vectorises.
    const float* cur = lum.data() + std::size_t(y) * w;
    const float* up = y > 0 ? cur - w : nullptr;
    const float* dn = y + 1 < h ? cur + w : nullptr;
    float* b = r.bound.data() + std::size_t(y) * w;
    auto at = [&](int x) {
      float m = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if ((dx || dy) && xx >= 0 && yy >= 0 && xx < w && yy < h) m = std::max(m, lum[std::size_t(yy) * w + xx]);
        }
      return ratio * m;
    };
    if (up && dn && w > 2) {
      b[0] = at(0);
      for (int x = 1; x + 1 < w; ++x) {
        const float m = std::max(std::max(std::max(up[x - 1], up[x]), std::max(up[x + 1], cur[x - 1])),
                                 std::max(std::max(cur[x + 1], dn[x - 1]), std::max(dn[x], dn[x + 1])));
        b[x] = ratio * std::max(0.0f, m);
      }
      b[w - 1] = at(w - 1);
    } else {
      for (int x = 0; x < w; ++x) b[x] = at(x);
    }
    for (int x = 0; x < w; ++x) {
      if (!(cur[x] > b[x])) continue;
      float* kept = r.kept.pixel(x, y);
      float before[3] = {kept[0], kept[1], kept[2]};
      clamp_luminance(kept, b[x]);
      if (with_excess)
        for (int c = 0; c < 3; ++c) r.excess.pixel(x, y)[c] = before[c] - kept[c];
      ++cut_rows[std::size_t(y)];
    }
  });
  for (std::size_t c : cut_rows) r.cut += c;
  return r;
}

}  // namespace dnb
