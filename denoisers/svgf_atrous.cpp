#include "denoisers/svgf_atrous.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <tbb/parallel_for.h>

#include "denoisers/fast_exp.h"
#include "denoisers/illumination.h"

namespace dnb::svgf {
namespace {

constexpr float kB3[5] = {1.0f / 16, 1.0f / 4, 3.0f / 8, 1.0f / 4, 1.0f / 16};

}  // namespace

Guides make_guides(const AovFrame& f, float sigma_z) {
  const int w = f.width(), h = f.height();
  Guides g;
  g.n = Planes(w, h, 4);
  g.z = Planes(w, h, 1);
  g.inv_fw = Planes(w, h, 1);
  const Image& normal = f.layer(layer::kNormal);
  const Image depth = normalized_depth(f);
  std::vector<char> hit(std::size_t(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float* n = normal.pixel(x, y);
      const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      const std::size_t k = std::size_t(y) * w + x;
      hit[k] = len > 1e-3f && depth.at(x, y, 0) > 0;
      for (int c = 0; c < 3; ++c) g.n.plane(c)[k] = hit[k] ? n[c] / len : 0.0f;
      g.n.plane(3)[k] = hit[k] ? 0.0f : 1.0f;
      g.z.data[k] = depth.at(x, y, 0);
    }
  // fwidth: per axis the one-sided difference (to a neighbour that hit something) of smaller
  // magnitude.
  auto one_sided = [&](int x, int y, int dx, int dy) {
    float best = -1;
    for (int s : {-1, 1}) {
      const int xx = x + s * dx, yy = y + s * dy;
      if (xx < 0 || yy < 0 || xx >= w || yy >= h || !hit[std::size_t(yy) * w + xx]) continue;
      const float d = std::fabs(g.z.data[std::size_t(yy) * w + xx] - g.z.data[std::size_t(y) * w + x]);
      best = best < 0 ? d : std::min(best, d);
    }
    return std::max(best, 0.0f);
  };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t k = std::size_t(y) * w + x;
      const float fw = hit[k] ? one_sided(x, y, 1, 0) + one_sided(x, y, 0, 1) : 0.0f;
      g.inv_fw.data[k] = 1.0f / (sigma_z * std::max(fw, 1e-8f));
    }
  return g;
}

// The 3x3 Gaussian (1/4 centre, 1/8 edge, 1/16 corner) of a variance plane, renormalised where
// taps fall outside the image.
Planes prefilter_variance(const Planes& var) {
  static constexpr float k[3] = {0.5f, 1.0f, 0.5f};  // outer product / 4: 1/4, 1/8, 1/16
  Planes out(var.w, var.h, 1);
  tbb::parallel_for(0, var.h, [&](int y) {
    for (int x = 0; x < var.w; ++x) {
      float s = 0, ws = 0;
      for (int j = -1; j <= 1; ++j)
        for (int i = -1; i <= 1; ++i) {
          const int xx = x + i, yy = y + j;
          if (xx < 0 || yy < 0 || xx >= var.w || yy >= var.h) continue;
          const float wk = k[i + 1] * k[j + 1];
          s += wk * var.row(0, yy)[xx];
          ws += wk;
        }
      out.row(0, y)[x] = s / ws;
    }
  });
  return out;
}

Signal pass(const Signal& in, const Guides& g, int step, const PassSettings& s) {
  const int w = in.var.w, h = in.var.h;
  const Planes var_f = s.variance_prefilter ? prefilter_variance(in.var) : Planes(in.var);
  Signal out;
  out.c = Planes(w, h, 3);
  out.var = Planes(w, h, 1);
  tbb::parallel_for(0, h, [&](int y) {
    // Per row: the sums over the taps (fixed order: rows j, then columns i) and per-tap scratch.
    std::vector<float> buf(std::size_t(w) * 10, 0.0f);
    float *sr = buf.data(), *sg = sr + w, *sb = sg + w, *sv = sb + w, *ws = sv + w;
    float *lum = ws + w, *inv_l = lum + w, *wn = inv_l + w, *base = wn + w, *qlum = base + w;
    const float *pr = in.c.row(0, y), *pg = in.c.row(1, y), *pb = in.c.row(2, y);
    for (int x = 0; x < w; ++x) {
      lum[x] = kLumW[0] * pr[x] + kLumW[1] * pg[x] + kLumW[2] * pb[x];
      inv_l[x] = 1.0f / (s.sigma_luminance * std::sqrt(std::max(0.0f, var_f.row(0, y)[x]) + 1e-10f));
    }
    const float *nx = g.n.row(0, y), *ny = g.n.row(1, y), *nz = g.n.row(2, y), *nw = g.n.row(3, y);
    const float *zp = g.z.row(0, y), *ifw = g.inv_fw.row(0, y);
    for (int j = 0; j < 5; ++j) {
      const int yy = y + (j - 2) * step;
      if (yy < 0 || yy >= h) continue;
      for (int i = 0; i < 5; ++i) {
        const int dx = (i - 2) * step;
        const int x0 = std::max(0, -dx), x1 = std::min(w, w - dx);
        if (x0 >= x1) continue;
        const bool centre = i == 2 && j == 2;
        const float hk = kB3[i] * kB3[j];
        // 1 / (2^i |q - p| in taps): the depth term's scale (0 for the centre, whose difference is 0).
        const float inv_len = centre ? 0.0f : 1.0f / (float(step) * std::sqrt(float((i - 2) * (i - 2) + (j - 2) * (j - 2))));
        const float *qr = in.c.row(0, yy) + dx, *qg = in.c.row(1, yy) + dx, *qb = in.c.row(2, yy) + dx;
        const float* qv = in.var.row(0, yy) + dx;
        const float *qnx = g.n.row(0, yy) + dx, *qny = g.n.row(1, yy) + dx, *qnz = g.n.row(2, yy) + dx,
                    *qnw = g.n.row(3, yy) + dx, *qz = g.z.row(0, yy) + dx;
        for (int x = x0; x < x1; ++x) {
          qlum[x] = kLumW[0] * qr[x] + kLumW[1] * qg[x] + kLumW[2] * qb[x];
          wn[x] = std::max(0.0f, nx[x] * qnx[x] + ny[x] * qny[x] + nz[x] * qnz[x] + nw[x] * qnw[x]);
          base[x] = 1.0f;
        }
        if (centre) {
          for (int x = x0; x < x1; ++x) wn[x] = 1.0f;  // n . n = 1 up to the normal's rounding
        } else {
          for (int e = s.sigma_normal; e > 0; e >>= 1) {  // wn^sigma_n by binary powering
            if (e & 1)
              for (int x = x0; x < x1; ++x) base[x] *= wn[x];
            for (int x = x0; x < x1; ++x) wn[x] *= wn[x];
          }
          for (int x = x0; x < x1; ++x) wn[x] = base[x];
        }
        for (int x = x0; x < x1; ++x) {
          const float ez = std::fabs(zp[x] - qz[x]) * ifw[x] * inv_len;
          const float el = std::fabs(lum[x] - qlum[x]) * inv_l[x];
          const float wq = hk * wn[x] * exp_nonpositive(-(ez + el));
          sr[x] += wq * qr[x];
          sg[x] += wq * qg[x];
          sb[x] += wq * qb[x];
          sv[x] += wq * wq * qv[x];
          ws[x] += wq;
        }
      }
    }
    // The centre tap's weight is h(0)^2 > 0, so ws > 0.
    for (int x = 0; x < w; ++x) {
      const float inv = 1.0f / ws[x];
      out.c.row(0, y)[x] = sr[x] * inv;
      out.c.row(1, y)[x] = sg[x] * inv;
      out.c.row(2, y)[x] = sb[x] * inv;
      out.var.row(0, y)[x] = sv[x] * inv * inv;
    }
  });
  return out;
}

Planes to_planes(const Image& rgb) {
  Planes p(rgb.width(), rgb.height(), 3, Planes::Overwritten{});
  for (std::size_t k = 0; k < rgb.pixel_count(); ++k)
    for (int c = 0; c < 3; ++c) p.plane(c)[k] = rgb.data()[k * 3 + c];
  return p;
}

Image to_image(const Planes& rgb) {
  Image out(rgb.w, rgb.h, 3, Image::NoFill{});
  for (std::size_t k = 0; k < out.pixel_count(); ++k)
    for (int c = 0; c < 3; ++c) out.data()[k * 3 + c] = rgb.plane(c)[k];
  return out;
}

}  // namespace dnb::svgf
