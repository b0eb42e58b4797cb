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

Image smooth_tint(const Image& tint, const Image& normal, const Image& depth, int radius, float max_relative_deviation,
                  float max_normal_distance, float max_depth_distance, const std::vector<char>* keep) {
  const int w = tint.width(), h = tint.height();
  if (radius <= 0 || max_relative_deviation <= 0 || tint.empty()) return tint;
  const float n2 = max_normal_distance * max_normal_distance;
  auto sum3 = [](const Image& im, std::size_t p) {
    const float* t = im.data() + 3 * p;
    return t[0] + t[1] + t[2];
  };
  // One pass of a sigma filter (Lee 1983) whose neighbourhood is chosen per pixel by a
  // same-surface test on two guide images (written by hand: no OpenCV filter takes such a
  // rule): the mean of the raw tints within the band around `centre`'s value.
  auto pass = [&](const Image& centre) {
    Image out = tint;
    tbb::parallel_for(0, h, [&](int y) {
      for (int x = 0; x < w; ++x) {
        const std::size_t p = std::size_t(y) * w + x;
        if (sum3(tint, p) == 0.0f || (keep && (*keep)[p])) continue;
        const float cp = sum3(centre, p);
        const float* np = normal.data() + 3 * p;
        const float zp = depth.data()[p], band = max_relative_deviation * cp;
        double sum[3] = {0, 0, 0};
        int n = 0;
        bool border = false;
        for (int yy = std::max(0, y - radius); yy <= std::min(h - 1, y + radius) && !border; ++yy)
          for (int xx = std::max(0, x - radius); xx <= std::min(w - 1, x + radius); ++xx) {
            const std::size_t q = std::size_t(yy) * w + xx;
            if (keep && (*keep)[q]) continue;
            const float* nq = normal.data() + 3 * q;
            const float a = np[0] - nq[0], b = np[1] - nq[1], c = np[2] - nq[2];
            if (a * a + b * b + c * c > n2 || std::abs(depth.data()[q] - zp) > max_depth_distance) continue;
            const float tq = sum3(tint, q);
            if (tq == 0.0f) {
              border = true;  // the reflective part of this surface ends here
              break;
            }
            if (std::abs(tq - cp) > band) continue;
            const float* t = tint.data() + 3 * q;
            for (int k = 0; k < 3; ++k) sum[k] += t[k];
            ++n;
          }
        // Near the end of the surface's reflective part (a mirror's border on a coplanar wall:
        // partly covered pixels, a step not noise) and where no raw tint lies near the centre
        // value, the pixel keeps its own tint.
        if (border || n == 0) continue;
        for (int k = 0; k < 3; ++k) out.data()[3 * p + k] = float(sum[k] / n);
      }
    });
    return out;
  };
  // Centred on the pixel's own (noisy) tint, the band takes more neighbours on its side of the
  // expectation than on the other, which pulls the mean towards the pixel's noise; the second
  // pass centres the band on the first pass's estimate instead (RMS error against the
  // expectation: 0.28x of the raw tint's after one pass, see tests/denoisers/tint_test.cpp).
  return pass(pass(tint));
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
