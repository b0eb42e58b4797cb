// svgf: the spatial filter of SVGF (Schied, Kaplanyan, Wyman, Patney, Chaitanya, Burgess, Liu,
// Dachsbacher, Lefohn and Salvi 2017, "Spatiotemporal Variance-Guided Filtering: Real-Time
// Reconstruction for Path-Traced Global Illumination", HPG), on one frame: the temporal
// accumulation is left out (the harness denoises single frames), the rest is the paper's section 4.
//
// Input: the demodulated (untextured) illumination, which the tracer writes already divided by
// the albedo (D and I, denoisers/illumination.h). As in SVGF, direct and indirect light are
// filtered apart (`separate`, the paper's choice; off, the default after the sweep: L = D + I in
// one chain), and the result is remodulated,
// F' = (D' + I') * T + R + E. R and E pass through unfiltered (SVGF filters what its primary
// hits see; specular paths are not its subject).
//
// Variance: SVGF estimates the luminance variance of each pixel from temporal moments (spatially
// from a 7x7 window where the history is short). A frame of this harness carries the variance of
// each pixel's mean instead (direct_variance, indirect_variance: from the spread of the tracer's
// independent sample groups, tracer/render.cpp), so the luminance variance is taken from it:
// Var(l) = sum_c w_c^2 Var_c with the Rec. 709 weights w (channels taken as uncorrelated).
//
// Iteration i = 0 .. iterations-1 is an a-trous pass with the 5x5 B3-spline kernel h, taps 2^i
// apart; tap q of pixel p has the weight
//     w(p, q) = h(q) * exp(-|z_p - z_q| / (sigma_z |grad z_p| 2^i |q - p|_taps)
//                          - |l_p - l_q| / (sigma_l sqrt(g3x3(Var(l))_p) + eps))
//                    * max(0, n_p . n_q)^sigma_n,
// l the luminance of the current iteration's illumination, g3x3 the 3x3 Gaussian prefilter of
// the variance, and the variance is carried through every pass as Var'(p) = sum w^2 Var(q) /
// (sum w)^2 (the paper's equations 1-4). |grad z| is SVGF's fwidth of depth: the sum over x and y
// of the one-sided depth difference of smaller magnitude (a screen-space derivative that does
// not jump at silhouettes), on the depth normalised by its median (normalized_depth), floored
// at 1e-8. Pixels that hit nothing (zero normal) blend only with each other. The paper's values
// (five passes, sigma_z = 1, sigma_n = 128, sigma_l = 4, D and I apart) were the sweep's start;
// the defaults are its result on the training scene (docs/method-defaults.md, "svgf").
//
// Hand-written: no library implements SVGF (OpenCV, OIIO and OIDN do not). Each pixel of a pass
// reads only the previous pass, rows run in parallel (TBB), taps are summed in a fixed order:
// the output does not depend on the thread count.
//
// Parameters: the ParamSpec list at the end of this file; how the defaults were chosen:
// docs/method-defaults.md.
#include <algorithm>
#include <cmath>
#include <vector>

#include <tbb/parallel_for.h>

#include "denoisers/buffer_pool.h"
#include "denoisers/fast_exp.h"
#include "denoisers/illumination.h"
#include "denoisers/method.h"

namespace dnb {
namespace {

constexpr float kB3[5] = {1.0f / 16, 1.0f / 4, 3.0f / 8, 1.0f / 4, 1.0f / 16};
constexpr float kLumW[3] = {0.2126f, 0.7152f, 0.0722f};  // Rec. 709

// What the edge-stopping functions compare, fixed over the passes.
struct Guides {
  Planes n;          // unit normal (x, y, z, 0); a pixel that hit nothing gets (0, 0, 0, 1)
  Planes z, inv_fw;  // normalised depth, 1 / (sigma_z max(fwidth z, 1e-8))
};

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

// Illumination being filtered (three planes) and its luminance variance.
struct Signal {
  Planes c;    // 3 channels
  Planes var;  // 1
};

Signal make_signal(const Image& light, const Image& variance) {
  const int w = light.width(), h = light.height();
  Signal s;
  s.c = Planes(w, h, 3);
  s.var = Planes(w, h, 1);
  for (std::size_t k = 0; k < light.pixel_count(); ++k) {
    float v = 0;
    for (int c = 0; c < 3; ++c) {
      s.c.plane(c)[k] = light.data()[k * 3 + c];
      const float vc = variance.data()[k * 3 + c];
      v += kLumW[c] * kLumW[c] * (std::isfinite(vc) && vc > 0 ? vc : 0.0f);
    }
    s.var.data[k] = v;
  }
  return s;
}

class Svgf final : public Method {
 public:
  explicit Svgf(const Params& p)
      : iterations_(p.i("iterations")),
        sigma_l_(float(p.f("sigma_luminance"))),
        sigma_n_(p.i("sigma_normal")),
        sigma_z_(float(p.f("sigma_depth"))),
        separate_(p.b("separate")),
        prefilter_(p.b("variance_prefilter")) {}

  std::vector<std::string> required_layers() const override {
    auto l = illumination_layers();
    for (const char* n : {layer::kNormal, layer::kDepth, layer::kDirectVariance, layer::kIndirectVariance})
      l.emplace_back(n);
    return l;
  }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    const AovFrame& f = *in.frame;
    Guides g;
    {
      ScopedPhase p(r.stats, "guides");
      g = make_guides(f, sigma_z_);
    }
    Image light;
    {
      ScopedPhase p(r.stats, "atrous");
      if (separate_) {
        light = filter(make_signal(f.layer(layer::kDirect), f.layer(layer::kDirectVariance)), g);
        const Image ind = filter(make_signal(f.layer(layer::kIndirect), f.layer(layer::kIndirectVariance)), g);
        for (std::size_t k = 0; k < light.size(); ++k) light.data()[k] += ind.data()[k];
      } else {
        Image var = f.layer(layer::kDirectVariance);
        const Image& vi = f.layer(layer::kIndirectVariance);
        for (std::size_t k = 0; k < var.size(); ++k) var.data()[k] += vi.data()[k];
        light = filter(make_signal(illumination(f), var), g);
      }
    }
    {
      ScopedPhase p(r.stats, "compose");
      r.image = compose(light, f);
    }
    return r;
  }

 private:
  Image filter(Signal s, const Guides& g) const {
    for (int it = 0; it < iterations_; ++it) s = pass(s, g, 1 << it);
    const int w = s.var.w, h = s.var.h;
    Image out(w, h, 3);
    for (std::size_t k = 0; k < out.pixel_count(); ++k)
      for (int c = 0; c < 3; ++c) out.data()[k * 3 + c] = s.c.plane(c)[k];
    return out;
  }

  Signal pass(const Signal& in, const Guides& g, int step) const {
    const int w = in.var.w, h = in.var.h;
    const Planes var_f = prefilter_ ? prefilter_variance(in.var) : Planes(in.var);
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
        inv_l[x] = 1.0f / (sigma_l_ * std::sqrt(std::max(0.0f, var_f.row(0, y)[x]) + 1e-10f));
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
            for (int e = sigma_n_; e > 0; e >>= 1) {  // wn^sigma_n by binary powering
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

  int iterations_;
  float sigma_l_;
  int sigma_n_;
  float sigma_z_;
  bool separate_, prefilter_;
};

}  // namespace

MethodInfo svgf_method() {
  return {
      .name = "svgf",
      .description = "SVGF's spatial filter (Schied et al. 2017): variance-guided a-trous on demodulated D and I",
      .kind = MethodKind::Filter,
      .params =
          {
              {"iterations", ParamType::Int, "3", "number of a-trous passes (tap spacing 1, 2, 4, ...)", 1.0, 10.0},
              {"sigma_luminance", ParamType::Float, "2", "luminance edge-stopping: |dl| / (sigma sqrt(Var l))", 1e-3, 1e4},
              {"sigma_normal", ParamType::Int, "4", "normal edge-stopping exponent: max(0, n_p . n_q)^sigma", 0.0, 4096.0},
              {"sigma_depth", ParamType::Float, "1", "depth edge-stopping: |dz| / (sigma |grad z| |q - p|)", 1e-4, 1e4},
              {"separate", ParamType::Bool, "false", "filter D and I apart, each with its variance (SVGF); false: D + I together"},
              {"variance_prefilter", ParamType::Bool, "true", "3x3 Gaussian of the variance before each pass (SVGF)"},
          },
      .create = [](const Params& p) { return std::make_unique<Svgf>(p); },
  };
}

}  // namespace dnb
