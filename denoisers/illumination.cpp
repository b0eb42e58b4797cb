#include "denoisers/illumination.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
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

std::vector<std::string> illumination_filter_layers(bool filter_reflection) {
  auto layers = illumination_layers();
  layers.push_back(layer::kNormal);
  layers.push_back(layer::kDepth);
  if (filter_reflection)
    for (const auto& l : reflection_guide_layers()) layers.push_back(l);
  return layers;
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

float median_depth(const Image& z, const PixelBox& b) {
  std::vector<float> valid;
  valid.reserve(std::size_t(b.w) * b.h);
  for (int y = b.y; y < b.y + b.h; ++y)
    for (int x = b.x; x < b.x + b.w; ++x) {
      const float v = z.at(x, y, 0);
      if (std::isfinite(v) && v > 0) valid.push_back(v);
    }
  if (valid.empty()) return 1.0f;
  auto mid = valid.begin() + std::ptrdiff_t(valid.size() / 2);
  std::nth_element(valid.begin(), mid, valid.end());
  return *mid;
}

Image normalized_depth(const AovFrame& frame, int level) {
  const Image& z = frame.layer(layer::at_level(level, layer::kDepth));
  const float median = median_depth(z, PixelBox{0, 0, z.width(), z.height()});
  Image out(frame.width(), frame.height(), 1);
  for (std::size_t k = 0; k < z.size(); ++k) {
    const float v = z.data()[k];
    out.data()[k] = (std::isfinite(v) && v > 0) ? v / median : 0.0f;
  }
  return out;
}

PixelBox nonzero_box(const Image& image, int margin) {
  const int w = image.width(), h = image.height(), ch = image.channels();
  std::vector<int> row_lo(std::size_t(h), w), row_hi(std::size_t(h), -1);
  tbb::parallel_for(0, h, [&](int y) {
    const float* p = image.pixel(0, y);
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < ch; ++c)
        if (p[std::size_t(x) * ch + c] != 0.0f) {
          row_lo[std::size_t(y)] = std::min(row_lo[std::size_t(y)], x), row_hi[std::size_t(y)] = x;
          break;
        }
  });
  int x0 = w, y0 = h, x1 = -1, y1 = -1;
  for (int y = 0; y < h; ++y)
    if (row_hi[std::size_t(y)] >= 0) {
      x0 = std::min(x0, row_lo[std::size_t(y)]), x1 = std::max(x1, row_hi[std::size_t(y)]);
      y0 = std::min(y0, y), y1 = y;
    }
  if (x1 < 0) return {};
  x0 = std::max(0, x0 - margin), y0 = std::max(0, y0 - margin);
  x1 = std::min(w - 1, x1 + margin), y1 = std::min(h - 1, y1 + margin);
  return {x0, y0, x1 - x0 + 1, y1 - y0 + 1};
}

Image smooth_tint(const Image& tint, const Image& normal, const Image& depth, int radius, float max_relative_deviation,
                  float max_normal_distance, float max_depth_distance, const std::vector<char>* keep) {
  const int W = tint.width();
  Image out = tint;
  if (radius <= 0 || max_relative_deviation <= 0 || tint.empty()) return out;
  // Only the bounding box of the non-zero tints (plus the window's reach) is read or written.
  const PixelBox box = nonzero_box(tint, radius);
  if (box.empty()) return out;
  const int bx0 = box.x, by0 = box.y, w = box.w, h = box.h;
  const std::size_t n = std::size_t(w) * h;
  const float n2 = max_normal_distance * max_normal_distance;
  // Planes of the box (one float per pixel each, not zero-filled: every element is written
  // next), so that the loops below run along rows with unit stride and vectorise: the tint's
  // channels and their sum, the normal, the depth, and 1 for the pixels that take part (0 for
  // the kept ones).
  std::unique_ptr<float[]> planes(new float[9 * n]);
  float* const tr = planes.get();
  float* const tg = tr + n;
  float* const tb = tg + n;
  float* const ts = tb + n;
  float* const nx = ts + n;
  float* const ny = nx + n;
  float* const nz = ny + n;
  float* const z = nz + n;
  float* const part = z + n;
  const float* centre = ts;  // the pass's centre values: first the raw tints' sums
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      const std::size_t p = std::size_t(y) * w + x;
      const float* t = tint.pixel(bx0 + x, by0 + y);
      const float* nn = normal.pixel(bx0 + x, by0 + y);
      tr[p] = t[0], tg[p] = t[1], tb[p] = t[2], ts[p] = t[0] + t[1] + t[2];
      nx[p] = nn[0], ny[p] = nn[1], nz[p] = nn[2], z[p] = depth.at(bx0 + x, by0 + y, 0);
      part[p] = keep && (*keep)[std::size_t(by0 + y) * W + std::size_t(bx0 + x)] ? 0.0f : 1.0f;
    }
  });
  // Each row's first and last pixel with a non-zero tint: the only ones a pass changes.
  std::vector<int> row_lo(std::size_t(h), w), row_hi(std::size_t(h), -1);
  tbb::parallel_for(0, h, [&](int y) {
    for (int x = 0; x < w; ++x)
      if (ts[std::size_t(y) * w + std::size_t(x)] != 0.0f)
        row_lo[std::size_t(y)] = std::min(row_lo[std::size_t(y)], x), row_hi[std::size_t(y)] = x;
  });
  // One pass of a sigma filter (Lee 1983) whose neighbourhood is chosen per pixel by a
  // same-surface test on two guide images (written by hand: no OpenCV filter takes such a
  // rule): the mean of the raw tints within the band around the centre value. The window is
  // walked offset by offset, each offset along a row (the sums' order is fixed: the result
  // does not depend on the thread count). Writes the new means into `out` and their sums into
  // `next_centre`.
  auto pass = [&](float* next_centre) {
    tbb::parallel_for(0, h, [&](int y) {
      const std::size_t row = std::size_t(y) * w;
      const int lo = row_lo[std::size_t(y)], hi = row_hi[std::size_t(y)];
      if (next_centre) std::copy(centre + row, centre + row + w, next_centre + row);
      if (hi < 0) return;
      const int len = hi - lo + 1;
      // Sums of the differences to the pixel's own tint (a constant region's mean is then its
      // value to the bit, and float sums lose nothing that matters).
      std::vector<float> sr(std::size_t(len), 0.0f), sg(std::size_t(len), 0.0f), sb(std::size_t(len), 0.0f);
      std::vector<float> cnt(std::size_t(len), 0.0f), border(std::size_t(len), 0.0f);
      float* const psr = sr.data();
      float* const psg = sg.data();
      float* const psb = sb.data();
      float* const pcnt = cnt.data();
      float* const pborder = border.data();
      for (int yy = std::max(0, y - radius); yy <= std::min(h - 1, y + radius); ++yy)
        for (int dx = -radius; dx <= radius; ++dx) {
          const int x0 = std::max(lo, -dx), x1 = std::min(hi + 1, w - dx);
          const std::ptrdiff_t dq = std::ptrdiff_t(yy - y) * w + dx;  // neighbour = pixel + dq
          // Branch-free (0/1 factors instead of conditions), so that it vectorises; the sums
          // do not alias the planes (ivdep spares the run-time checks GCC gives up on; clang, which
          // builds only the fuzz targets, does without it).
#if !defined(__clang__)
#pragma GCC ivdep
#endif
          for (int x = x0; x < x1; ++x) {
            const std::ptrdiff_t p = std::ptrdiff_t(row) + x, q = p + dq;
            const int i = x - lo;
            const float a = nx[p] - nx[q], b = ny[p] - ny[q], c = nz[p] - nz[q];
            const float same = part[q] * (a * a + b * b + c * c <= n2 ? 1.0f : 0.0f) *
                               (std::abs(z[q] - z[p]) <= max_depth_distance ? 1.0f : 0.0f);
            const float nonzero = ts[q] != 0.0f ? 1.0f : 0.0f;
            const float in = same * nonzero *
                             (std::abs(ts[q] - centre[p]) <= max_relative_deviation * centre[p] ? 1.0f : 0.0f);
            pborder[i] += same * (1.0f - nonzero);
            psr[i] += in * (tr[q] - tr[p]);
            psg[i] += in * (tg[q] - tg[p]);
            psb[i] += in * (tb[q] - tb[p]);
            pcnt[i] += in;
          }
        }
      // Kept: zero tints, kept pixels, the border of a reflective region (a same-surface
      // neighbour with a zero tint: a mirror's partly covered pixels on a coplanar wall are a
      // step, not noise), and pixels with no raw tint near the centre value.
      for (int x = lo; x <= hi; ++x) {
        const std::size_t p = row + std::size_t(x), i = std::size_t(x - lo);
        if (ts[p] == 0.0f || part[p] == 0.0f || border[i] > 0.0f || cnt[i] == 0.0f) continue;
        float* o = out.pixel(bx0 + x, by0 + int(y));
        o[0] = tr[p] + sr[i] / cnt[i], o[1] = tg[p] + sg[i] / cnt[i], o[2] = tb[p] + sb[i] / cnt[i];
        if (next_centre) next_centre[p] = o[0] + o[1] + o[2];
      }
    });
  };
  // Centred on the pixel's own (noisy) tint, the band takes more neighbours on its side of the
  // expectation than on the other, which pulls the mean towards the pixel's noise; the second
  // pass centres the band on the first pass's estimate instead (RMS error against the
  // expectation: 0.28x of the raw tint's after one pass, see tests/denoisers/tint_test.cpp).
  std::unique_ptr<float[]> first(new float[n]);
  pass(first.get());
  centre = first.get();
  pass(nullptr);
  return out;
}

void clamp_luminance(float rgb[3], float bound) {
  const float l = luminance(rgb);
  if (!(l > bound)) return;
  const float s = bound / l;
  for (int c = 0; c < 3; ++c) rgb[c] *= s;
}

ParamSpec firefly_ratio_param() {
  return {"firefly_ratio", ParamType::Float, "3",
          "cut pixels of L brighter than this times their brightest neighbour first (as proposed does); 0: off", 0.0, 1e6};
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
      bool any = false;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = x + dx, yy = y + dy;
          if ((dx || dy) && xx >= 0 && yy >= 0 && xx < w && yy < h) {
            m = std::max(m, lum[std::size_t(yy) * w + xx]);
            any = true;
          }
        }
      // A pixel without neighbours (a 1x1 image) has nothing to be a firefly against: no bound
      // (a bound of 0 would cut it to black).
      return any ? ratio * m : std::numeric_limits<float>::infinity();
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
