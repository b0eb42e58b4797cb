// atrous: the edge-avoiding a-trous wavelet filter (Dammertz, Sewtz, Hanika and Lensch 2010,
// "Edge-Avoiding A-Trous Wavelet Transform for fast Global Illumination Filtering", HPG) on the
// untextured illumination L = D + I; the result is composed as F' = L' * T + R + E
// (denoisers/illumination.h), the demodulation the paper suggests for textured scenes.
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
// range-compressed domain (denoisers/hdr_mapping.h, default log) because a fixed sigma in linear
// radiance does not fit both a shadow and a lamp; and the position term compares depths (relative
// to the depth at p) instead of world positions, which the frame does not hold.
//
// Hand-written: no library implements this filter (OpenCV, OIIO and OIDN do not). Each pixel
// of a pass reads only the previous pass, so rows run in parallel (TBB) and the output does not
// depend on the thread count.
//
// Parameters:
//   iterations         int     number of a-trous passes (tap spacing 1, 2, 4, ...)
//   sigma_color        float   colour edge-stopping sigma of the first pass, compressed units
//   sigma_normal       float   normal edge-stopping sigma (distance between unit normals)
//   sigma_depth        float   depth edge-stopping sigma (relative depth difference)
//   halve_color_sigma  bool    halve sigma_color after every pass (Dammertz et al.)
//   range_map          string  domain of the colour distance: linear, log, reinhard, srgb
#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

#include "denoisers/hdr_mapping.h"
#include "denoisers/illumination.h"
#include "denoisers/method.h"

namespace dnb {
namespace {

constexpr float kB3[5] = {1.0f / 16, 1.0f / 4, 3.0f / 8, 1.0f / 4, 1.0f / 16};

class Atrous final : public Method {
 public:
  explicit Atrous(const Params& p)
      : iterations_(p.i("iterations")),
        sigma_color_(float(p.f("sigma_color"))),
        sigma_normal_(float(p.f("sigma_normal"))),
        sigma_depth_(float(p.f("sigma_depth"))),
        halve_(p.b("halve_color_sigma")),
        map_(parse_range_map(p.s("range_map"))) {}

  std::vector<std::string> required_layers() const override {
    auto layers = illumination_layers();
    layers.push_back(layer::kNormal);
    layers.push_back(layer::kDepth);
    return layers;
  }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    const AovFrame& f = *in.frame;
    const Image& normal = f.layer(layer::kNormal);
    Image depth, cur, next(f.width(), f.height(), 3), key;
    {
      ScopedPhase p(r.stats, "prepare");
      depth = normalized_depth(f);
      cur = illumination(f);
    }
    {
      ScopedPhase p(r.stats, "atrous");
      float sigma_c = sigma_color_;
      for (int it = 0; it < iterations_; ++it) {
        key = cur;  // the colour the edge-stopping function compares, in the compressed domain
        compress(map_, key);
        pass(cur, key, normal, depth, 1 << it, sigma_c, next);
        std::swap(cur, next);
        if (halve_) sigma_c *= 0.5f;
      }
    }
    {
      ScopedPhase p(r.stats, "compose");
      r.image = compose(cur, f);
    }
    return r;
  }

 private:
  void pass(const Image& in, const Image& key, const Image& normal, const Image& depth, int step, float sigma_c,
            Image& out) const {
    const int w = in.width(), h = in.height();
    const float inv_c = 1.0f / (sigma_c * sigma_c);
    const float inv_n = 1.0f / (sigma_normal_ * sigma_normal_);
    const float inv_z = 1.0f / (sigma_depth_ * sigma_depth_);
    tbb::parallel_for(0, h, [&](int y) {
      for (int x = 0; x < w; ++x) {
        const float* kp = key.pixel(x, y);
        const float* np = normal.pixel(x, y);
        const float zp = depth.at(x, y, 0);
        // Pixels that hit nothing have depth 0: compare absolute depths there.
        const float inv_zp = zp > 0 ? 1.0f / zp : 1.0f;
        float sum[3] = {0, 0, 0}, wsum = 0;
        for (int j = 0; j < 5; ++j) {
          const int yy = y + (j - 2) * step;
          if (yy < 0 || yy >= h) continue;
          for (int i = 0; i < 5; ++i) {
            const int xx = x + (i - 2) * step;
            if (xx < 0 || xx >= w) continue;
            const float* kq = key.pixel(xx, yy);
            const float* nq = normal.pixel(xx, yy);
            float dc = 0, dn = 0;
            for (int c = 0; c < 3; ++c) {
              dc += (kp[c] - kq[c]) * (kp[c] - kq[c]);
              dn += (np[c] - nq[c]) * (np[c] - nq[c]);
            }
            const float dz = (zp - depth.at(xx, yy, 0)) * inv_zp;
            const float wq = kB3[i] * kB3[j] * std::exp(-dc * inv_c - dn * inv_n - dz * dz * inv_z);
            const float* cq = in.pixel(xx, yy);
            for (int c = 0; c < 3; ++c) sum[c] += wq * cq[c];
            wsum += wq;
          }
        }
        // The centre tap always has weight h(0)^2 > 0, so wsum > 0.
        float* o = out.pixel(x, y);
        for (int c = 0; c < 3; ++c) o[c] = sum[c] / wsum;
      }
    });
  }

  int iterations_;
  float sigma_color_, sigma_normal_, sigma_depth_;
  bool halve_;
  RangeMap map_;
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
              {"sigma_normal", ParamType::Float, "0.3", "normal edge-stopping sigma (distance between unit normals)", 1e-4, 1e4},
              {"sigma_depth", ParamType::Float, "0.1", "depth edge-stopping sigma (relative depth difference)", 1e-4, 1e4},
              {"halve_color_sigma", ParamType::Bool, "true", "halve sigma_color after every pass (Dammertz et al.)"},
              {"range_map", ParamType::String, "log", "domain of the colour distance (denoisers/hdr_mapping.h)", {}, {},
               range_map_names()},
          },
      .create = [](const Params& p) { return std::make_unique<Atrous>(p); },
  };
}

}  // namespace dnb
