// atrous: the edge-avoiding a-trous wavelet filter (Dammertz, Sewtz, Hanika and Lensch 2010,
// "Edge-Avoiding A-Trous Wavelet Transform for fast Global Illumination Filtering", HPG) on the
// untextured illumination L = D + I; the result is composed as F' = L' * T + R + E
// (denoisers/illumination.h), the demodulation the paper suggests for textured scenes; R is
// filtered the same way when filter_reflection is set.
//
// Iteration i = 0 .. iterations-1 convolves with the 5x5 B3-spline kernel h = (1, 4, 6, 4, 1)/16
// (outer product) whose taps are 2^i pixels apart (the "holes" of a trous), each tap q of pixel
// p weighted by the edge-stopping functions
//     w(p, q) = h(q) * exp(-|c_p - c_q|^2 / sigma_c,i^2 - |n_p - n_q|^2 / sigma_n^2
//                          - ((z_p - z_q) / z_p)^2 / sigma_z^2)
// and normalised by the sum of weights (taps outside the image are left out). c is the
// illumination of the current iteration; as in the paper its sigma halves every iteration,
// sigma_c,i = 2^-i sigma_c, since each pass has less noise left. n is the shading normal.
//
// Deviations, both because of what the frame stores: the colour distance is measured in a
// range-compressed domain (denoisers/hdr_mapping.h, default reinhard) because a fixed sigma in linear
// radiance does not fit both a shadow and a lamp; and the position term compares depths (relative
// to the depth at p) instead of world positions, which the frame does not hold.
//
// Hand-written: no library implements this filter (OpenCV, OIIO and OIDN do not). Each pixel
// of a pass reads only the previous pass, so rows run in parallel (TBB) and the output does not
// depend on the thread count.
//
// Parameters: the ParamSpec list at the end of this file, the only place they are documented
// (`denoisebench list methods` prints it); how the defaults were chosen: docs/method-defaults.md.
#include <algorithm>
#include <cmath>
#include <cstdint>

#include <tbb/parallel_for.h>

#include "denoisers/fast_exp.h"
#include "denoisers/hdr_mapping.h"
#include "denoisers/illumination.h"
#include "denoisers/method.h"

namespace dnb {
namespace {

constexpr float kB3[5] = {1.0f / 16, 1.0f / 4, 3.0f / 8, 1.0f / 4, 1.0f / 16};

// One image as three (or one) planes of floats: the inner loops over a row then read
// contiguous memory and vectorise.
struct Planes {
  int w = 0, h = 0, n = 0;
  std::vector<float> data;
  Planes(const Image& img) : w(img.width()), h(img.height()), n(img.channels()), data(img.size()) {
    for (int c = 0; c < n; ++c)
      for (std::size_t px = 0; px < img.pixel_count(); ++px) data[c * img.pixel_count() + px] = img.data()[px * n + c];
  }
  const float* row(int c, int y) const { return data.data() + (std::size_t(c) * h + y) * w; }
};

// Adds one tap (offset already applied to the q* rows) to the sums of pixels [x0, x1) of a row.
// Separate, with restrict pointers, so that the compiler vectorises it.
void accumulate_taps(int x0, int x1, float hk, float inv_c, float inv_n, float inv_z, const float* __restrict kr,
                     const float* __restrict kg, const float* __restrict kb, const float* __restrict nx,
                     const float* __restrict ny, const float* __restrict nz, const float* __restrict zp,
                     const float* __restrict inv_zp, const float* __restrict qkr, const float* __restrict qkg,
                     const float* __restrict qkb, const float* __restrict qnx, const float* __restrict qny,
                     const float* __restrict qnz, const float* __restrict qz, const float* __restrict qr,
                     const float* __restrict qg, const float* __restrict qb, float* __restrict sr,
                     float* __restrict sg, float* __restrict sb, float* __restrict ws) {
  for (int x = x0; x < x1; ++x) {
    const float cr = kr[x] - qkr[x], cg = kg[x] - qkg[x], cb = kb[x] - qkb[x];
    const float ax = nx[x] - qnx[x], ay = ny[x] - qny[x], az = nz[x] - qnz[x];
    const float dz = (zp[x] - qz[x]) * inv_zp[x];
    const float e = -(cr * cr + cg * cg + cb * cb) * inv_c - (ax * ax + ay * ay + az * az) * inv_n - dz * dz * inv_z;
    const float wq = hk * exp_nonpositive(e);
    sr[x] += wq * qr[x];
    sg[x] += wq * qg[x];
    sb[x] += wq * qb[x];
    ws[x] += wq;
  }
}

class Atrous final : public Method {
 public:
  explicit Atrous(const Params& p)
      : iterations_(p.i("iterations")),
        sigma_color_(float(p.f("sigma_color"))),
        sigma_normal_(float(p.f("sigma_normal"))),
        sigma_depth_(float(p.f("sigma_depth"))),
        halve_(p.b("halve_color_sigma")),
        map_(parse_range_map(p.s("range_map"))),
        filter_reflection_(p.b("filter_reflection")),
        firefly_ratio_(float(p.f("firefly_ratio"))) {}

  std::vector<std::string> required_layers() const override { return illumination_filter_layers(filter_reflection_); }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    const AovFrame& f = *in.frame;
    Image light;
    {
      ScopedPhase p(r.stats, "prepare");
      light = illumination(f);
      if (firefly_ratio_ > 0) light = split_fireflies(std::move(light), firefly_ratio_, false).kept;  // as proposed's
    }
    {
      ScopedPhase p(r.stats, "atrous");
      light = filter(std::move(light), f, 0);
    }
    Image reflection;
    if (filter_reflection_) {
      ScopedPhase p(r.stats, "atrous_reflection");
      reflection = filter(f.layer(layer::kReflection), f, 1);
    }
    {
      ScopedPhase p(r.stats, "compose");
      r.image = filter_reflection_ ? compose(light, f, reflection) : compose(light, f);
    }
    return r;
  }

 private:
  // All passes over `cur`, with the normal and depth of reflection level `level` (0: the first
  // hit; 1: the hit seen in a mirror).
  Image filter(Image cur, const AovFrame& f, int level) const {
    const Planes normal(f.layer(layer::at_level(level, layer::kNormal)));
    const Planes depth(normalized_depth(f, level));
    Image next(f.width(), f.height(), 3), key;
    float sigma_c = sigma_color_;
    for (int it = 0; it < iterations_; ++it) {
      key = cur;  // the colour the edge-stopping function compares, in the compressed domain
      compress(map_, key);
      pass(Planes(cur), Planes(key), normal, depth, 1 << it, sigma_c, next);
      std::swap(cur, next);
      if (halve_) sigma_c *= 0.5f;
    }
    return cur;
  }

 private:
  void pass(const Planes& in, const Planes& key, const Planes& normal, const Planes& depth, int step, float sigma_c,
            Image& out) const {
    const int w = in.w, h = in.h;
    const float inv_c = 1.0f / (sigma_c * sigma_c);
    const float inv_n = 1.0f / (sigma_normal_ * sigma_normal_);
    const float inv_z = 1.0f / (sigma_depth_ * sigma_depth_);
    tbb::parallel_for(0, h, [&](int y) {
      // Sums over the taps for every pixel of row y, taps in a fixed order (j, then i).
      std::vector<float> acc(4 * std::size_t(w), 0.0f);
      float *sr = acc.data(), *sg = sr + w, *sb = sg + w, *ws = sb + w;
      std::vector<float> inv_zp(w);
      const float* zp = depth.row(0, y);
      // Pixels that hit nothing have depth 0: compare absolute depths there.
      for (int x = 0; x < w; ++x) inv_zp[x] = zp[x] > 0 ? 1.0f / zp[x] : 1.0f;
      const float *kr = key.row(0, y), *kg = key.row(1, y), *kb = key.row(2, y);
      const float *nx = normal.row(0, y), *ny = normal.row(1, y), *nz = normal.row(2, y);
      for (int j = 0; j < 5; ++j) {
        const int yy = y + (j - 2) * step;
        if (yy < 0 || yy >= h) continue;
        const float *qkr = key.row(0, yy), *qkg = key.row(1, yy), *qkb = key.row(2, yy);
        const float *qnx = normal.row(0, yy), *qny = normal.row(1, yy), *qnz = normal.row(2, yy);
        const float* qz = depth.row(0, yy);
        const float *qr = in.row(0, yy), *qg = in.row(1, yy), *qb = in.row(2, yy);
        for (int i = 0; i < 5; ++i) {
          const int dx = (i - 2) * step;
          const float hk = kB3[i] * kB3[j];
          const int x0 = std::max(0, -dx), x1 = std::min(w, w - dx);  // taps inside the image
          accumulate_taps(x0, x1, hk, inv_c, inv_n, inv_z, kr, kg, kb, nx, ny, nz, zp, inv_zp.data(), qkr + dx,
                          qkg + dx, qkb + dx, qnx + dx, qny + dx, qnz + dx, qz + dx, qr + dx, qg + dx, qb + dx, sr, sg,
                          sb, ws);
        }
      }
      // The centre tap has weight h(0)^2 * exp(0) > 0, so ws > 0.
      for (int x = 0; x < w; ++x) {
        float* o = out.pixel(x, y);
        o[0] = sr[x] / ws[x];
        o[1] = sg[x] / ws[x];
        o[2] = sb[x] / ws[x];
      }
    });
  }

  int iterations_;
  float sigma_color_, sigma_normal_, sigma_depth_;
  bool halve_;
  RangeMap map_;
  bool filter_reflection_;
  float firefly_ratio_;
};

}  // namespace

MethodInfo atrous_method() {
  return {
      .name = "atrous",
      .description = "edge-avoiding a-trous wavelet filter (Dammertz et al. 2010) on the illumination D+I, colour/normal/depth stopping",
      .kind = MethodKind::Filter,
      .params =
          {
              {"iterations", ParamType::Int, "5", "number of a-trous passes (tap spacing 1, 2, 4, ...)", 1.0, 10.0},
              {"sigma_color", ParamType::Float, "0.5", "colour edge-stopping sigma of the first pass, compressed units", 1e-4, 1e4},
              {"sigma_normal", ParamType::Float, "0.1", "normal edge-stopping sigma (distance between unit normals)", 1e-4, 1e4},
              {"sigma_depth", ParamType::Float, "0.01", "depth edge-stopping sigma (relative depth difference)", 1e-4, 1e4},
              {"halve_color_sigma", ParamType::Bool, "true", "halve sigma_color after every pass (Dammertz et al.)"},
              {"range_map", ParamType::String, "reinhard", "domain of the colour distance (denoisers/hdr_mapping.h)", {}, {},
               range_map_names()},
              {"filter_reflection", ParamType::Bool, "false", "also filter R, stopping on the refl1 normal/depth"},
              firefly_ratio_param(),
          },
      .create = [](const Params& p) { return std::make_unique<Atrous>(p); },
  };
}

}  // namespace dnb
