// svgf_temporal: the whole of SVGF (Schied, Kaplanyan, Wyman, Patney, Chaitanya, Burgess, Liu,
// Dachsbacher, Lefohn and Salvi 2017, "Spatiotemporal Variance-Guided Filtering: Real-Time
// Reconstruction for Path-Traced Global Illumination", HPG) over the frames of a sequence, with
// the paper's parameters (TAA, its last step, off by default). Per frame, on the demodulated
// illumination (D and I, which the tracer writes divided by the albedo; each filtered apart, as
// in the paper, with `separate`):
//
// 1. Temporal accumulation. The history is reprojected with the motion layer
//    (metrics/temporal.h: bilinear, taps whose depth or normal disagree dropped; the metrics'
//    own disocclusion test) and blended, c_t = a l_t + (1 - a) W(c_{t-1}), a = max(alpha, 1/n),
//    n the pixel's history length (reprojected, + 1, at most 32; 1 where the history was dropped).
//    The colour history W(c_{t-1}) is the output of the previous frame's first a-trous pass
//    (the paper's choice: filtered history, less noise fed back).
// 2. Variance. The first and second moments of the luminance, mu1 and mu2, are
//    accumulated the same way (a = max(moments_alpha, 1/n)), unfiltered; Var(l) = mu2 - mu1^2.
//    Where n < 4 (too few frames for that), the moments and the illumination come from a 7x7
//    cross-bilateral filter instead (weights: depth |dz| / (3 |grad z| |q - p|), normal
//    max(0, n . n')^sigma_n, luminance |dl| / sigma_l), and the variance is boosted by 4 / n
//    (the authors' reference code, for frames with little history).
// 3. The variance-guided a-trous passes (denoisers/svgf_atrous.h, shared with `svgf`),
//    `iterations` of them, taps 1, 2, 4, ... apart.
// 4. Remodulation F = (D' + I') * T + R + E (R and E pass through from the current frame, as in
//    `svgf`), then, with `taa` (off by default: see "On moving content"), temporal antialiasing
//    (TAA, Karis 2014, the paper's last step) as the TAA pass of the reference implementation
//    (Falcor) does it: where the disocclusion test keeps the history, the previous output
//    fetched with the Catmull-Rom bicubic filter, clamped in YCgCo to the 3x3 neighbourhood's
//    mean +- taa_box_sigma standard deviations of this frame's output, blended with
//    a = taa_alpha.
//
// A frame without history (a still, frame 0 of a sequence, a disoccluded pixel) is filtered from
// its own light alone: step 2's spatial estimate and step 3, as the paper's first frame is.
//
// Differences from the paper: TAA off by default (below, "On moving content"); bilinear
// reprojection without the reference code's 3x3 fallback search for a disoccluded pixel's
// history (a pixel the test rejects starts afresh); normals and depths compared by the metrics'
// thresholds rather than the reference code's screen-space derivatives; no mesh-id test (the
// frames have no ids). The spatial-only `svgf` row reads the tracer's variance layers instead of
// step 2 and has swept defaults; this row has the paper's.
//
// On moving content (docs/method-defaults.md, "svgf_temporal", has the measurements). Every
// history here (step 1's colour, step 2's moments, TAA's output) is fetched at c + motion(c),
// which under a moving camera is a sub-pixel position different at every pixel, and a history
// that is fed back is fetched again every frame: whatever the fetch blurs compounds over the
// frames (Yang et al. 2009, "Amortized supersampling", analyse this blur). What that does here:
// - TAA. Its history is 1 - taa_alpha = 90% of each output and holds the remodulated colour,
//   textures included. TAA antialiases by accumulating sub-pixel jittered frames; the paper
//   runs it on real-time frames whose geometry edges alias. The frames here are rendered with
//   many samples per pixel (already antialiased) and not jittered, so a new frame brings no
//   detail the history lost, and TAA only blurs: with a bilinear history fetch (this row's
//   first version) the 16-spp mse of configs/sequence.toml grew from 17.7 at frame 0 to ~50 by
//   frame 8 (the spatial svgf: ~22); with the Catmull-Rom fetch and the YCgCo box the mean over
//   the frames is still 34.1 against 19.2 without TAA (4 spp: 41.0 against 37.0; TAA does lower
//   the 4-spp tmse, 22.8 against 39.5). Hence taa = false by default; taa = true gives the
//   paper's whole pipeline.
// - The colour history (step 1) is the first a-trous pass's output, fetched bilinearly: filtered
//   again each frame and resampled, it blurs the illumination (not the textures, which the
//   current frame's albedo restores) and lags where the light moves over a surface that does not
//   (a rolling ball's shadow on the rug: the surface's motion vectors do not follow a shadow, nor
//   a glossy highlight; A-SVGF, Schied et al. 2018, exists for this). On the sequence at 16 spp
//   that costs about 5 of the 19.2 (alpha = 1, the colour without history and only the moments
//   accumulated, gives 14.2), mostly near the moving objects and their shadows; at 4 spp its
//   noise reduction about pays for it (37.0 against 36.5) and it steadies the frames (tmse 39.5
//   against 45.6). It is the paper's design and stays; its cost peaks with the ball's speed and
//   does not grow with the history's length.
//
// Deterministic: every pixel of every step reads only the previous step's buffers, sums run in a
// fixed tap order, TBB splits rows only: the output does not depend on the thread count.
//
// Parameters: the ParamSpec list at the end of this file.
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <optional>
#include <vector>

#include <tbb/parallel_for.h>

#include "denoisers/fast_exp.h"
#include "denoisers/illumination.h"
#include "denoisers/method.h"
#include "denoisers/svgf_atrous.h"
#include "denoisers/temporal_history.h"

namespace dnb {
namespace {

using svgf::kLumW;

constexpr float kMaxHistory = 32;    // the reference code's cap on n
constexpr int kShortHistory = 4;     // below it, the variance is estimated spatially (the paper's 4 frames)
constexpr int kSpatialRadius = 3;    // 7x7
constexpr float kDepthScale = 3;     // the 7x7 filter's depth term: 3 |grad z| (reference code)
// Variances beyond this (a frame holding 1e30 somewhere) are clamped so that the squares and
// sums of the passes stay finite; the passes never raise a variance above its input's largest.
constexpr double kMaxVariance = 1e30;

float lum(const float* c) { return kLumW[0] * c[0] + kLumW[1] * c[1] + kLumW[2] * c[2]; }

float power(float b, int e) {
  float r = 1;
  for (; e > 0; e >>= 1, b *= b)
    if (e & 1) r *= b;
  return r;
}

// (mu1, mu2) of a luminance; the square clamped to the float range (a luminance of 1e30).
void moments_of(float l, float* m) {
  m[0] = l;
  m[1] = float(std::min(double(l) * l, double(FLT_MAX)));
}

// YCgCo (Y = R/4 + G/2 + B/4, Co = (R - B)/2, Cg = -R/4 + G/2 - B/4), where TAA clamps its
// history (Karis 2014: luma and chroma apart), and back.
void to_ycgco(const float* rgb, float* out) {
  out[0] = 0.25f * rgb[0] + 0.5f * rgb[1] + 0.25f * rgb[2];
  out[1] = 0.5f * (rgb[0] - rgb[2]);
  out[2] = -0.25f * rgb[0] + 0.5f * rgb[1] - 0.25f * rgb[2];
}
void from_ycgco(const float* ycc, float* rgb) {
  const float t = ycc[0] - ycc[2];
  rgb[0] = t + ycc[1];
  rgb[1] = ycc[0] + ycc[2];
  rgb[2] = t - ycc[1];
}

// The Catmull-Rom weights of the taps at -1, 0, 1, 2 for a position f in [0, 1) past tap 0
// (they sum to 1, and at f = 0 are 0, 1, 0, 0: an integer motion fetches the pixel itself).
void catmull_rom(float f, float* w) {
  const float f2 = f * f, f3 = f2 * f;
  w[0] = -0.5f * f3 + f2 - 0.5f * f;
  w[1] = 1.5f * f3 - 2.5f * f2 + 1.0f;
  w[3] = 0.5f * (f3 - f2);
  w[2] = 1.0f - w[0] - w[1] - w[3];
}

double variance_of(double m1, double m2) {
  const double v = m2 - m1 * m1;
  return v > 0 ? std::min(v, kMaxVariance) : 0.0;  // NaN -> 0 too
}

// One illumination component's history: the first a-trous pass's output (3 channels) and the
// accumulated, unfiltered moments (2).
struct Component {
  Image colour, moments;
};

class SvgfTemporal final : public TemporalIlluminationMethod {
 public:
  explicit SvgfTemporal(const Params& p)
      : alpha_(float(p.f("alpha"))),
        moments_alpha_(float(p.f("moments_alpha"))),
        iterations_(p.i("iterations")),
        sigma_z_(float(p.f("sigma_depth"))),
        separate_(p.b("separate")),
        taa_(p.b("taa")),
        taa_alpha_(float(p.f("taa_alpha"))),
        taa_box_sigma_(float(p.f("taa_box_sigma"))),
        pass_{.sigma_luminance = float(p.f("sigma_luminance")),
              .sigma_normal = p.i("sigma_normal"),
              .variance_prefilter = p.b("variance_prefilter")},
        test_(surface_test(p)) {}

  void reset() override {
    TemporalIlluminationMethod::reset();
    components_.clear();
    length_ = Image();
    output_ = Image();
  }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    const AovFrame& f = *in.frame;
    const bool carry = cursor_.continues(in);
    svgf::Guides g;
    std::optional<metrics::Reprojection> history;
    Image length(f.width(), f.height(), 1, 1.0f);
    {
      ScopedPhase p(r.stats, "guides");
      g = svgf::make_guides(f, sigma_z_);
      if (carry) {
        history.emplace(reproject_history(f, guides_, test_));
        const Image previous = history->warp(length_);
        for (std::size_t k = 0; k < length.size(); ++k)
          if (history->valid(k)) length.data()[k] = std::min(previous.data()[k] + 1.0f, kMaxHistory);
      }
    }
    std::vector<Image> inputs;
    if (separate_) {
      inputs.push_back(f.layer(layer::kDirect));
      inputs.push_back(f.layer(layer::kIndirect));
    } else {
      inputs.push_back(illumination(f));
    }
    std::vector<Component> next(inputs.size());
    Image light(f.width(), f.height(), 3);
    // Each phase timed over the components together (stats.phases is recorded by name).
    double temporal_s = 0, variance_s = 0, atrous_s = 0;
    for (std::size_t i = 0; i < inputs.size(); ++i) {
      Stopwatch watch;
      Component acc = accumulate(inputs[i], history ? &*history : nullptr, history ? &components_[i] : nullptr, length);
      temporal_s += watch.seconds();
      watch.restart();
      svgf::Signal s = estimate_variance(acc, length, g);
      variance_s += watch.seconds();
      watch.restart();
      for (int it = 0; it < iterations_; ++it) {
        s = svgf::pass(s, g, 1 << it, pass_);
        if (it == 0) next[i].colour = svgf::to_image(s.c);  // the colour history (step 1)
      }
      const Image filtered = svgf::to_image(s.c);
      for (std::size_t k = 0; k < light.size(); ++k) light.data()[k] += filtered.data()[k];
      atrous_s += watch.seconds();
      next[i].moments = std::move(acc.moments);
    }
    r.stats.add_phase("temporal", temporal_s);
    r.stats.add_phase("variance", variance_s);
    r.stats.add_phase("atrous", atrous_s);
    {
      ScopedPhase p(r.stats, "compose");
      r.image = compose(light, f);
    }
    if (taa_ && history) {
      ScopedPhase p(r.stats, "taa");
      r.image = antialias(r.image, f, *history);
    }
    r.stats.counters["history_pixels"] = history ? double(length.pixel_count() - history->invalid_count()) : 0.0;
    components_ = std::move(next);
    length_ = std::move(length);
    output_ = r.image;
    guides_ = PreviousGuides::of(f);
    cursor_.advance(in);
    return r;
  }

 private:
  // Step 1 and step 2's moments: the input blended with its reprojected history where there is
  // one (history null: a frame without history).
  Component accumulate(const Image& input, const metrics::Reprojection* history, const Component* previous,
                       const Image& length) const {
    const int w = input.width(), h = input.height();
    Component out{input, Image(w, h, 2)};
    const Image prev_colour = history ? history->warp(previous->colour) : Image();
    const Image prev_moments = history ? history->warp(previous->moments) : Image();
    tbb::parallel_for(0, h, [&](int y) {
      for (int x = 0; x < w; ++x) {
        const std::size_t k = std::size_t(y) * w + x;
        float* c = out.colour.data() + k * 3;
        float* m = out.moments.data() + k * 2;
        moments_of(lum(c), m);
        if (!history || !history->valid(k)) continue;
        const float n = length.data()[k];
        const float a = std::max(alpha_, 1.0f / n), am = std::max(moments_alpha_, 1.0f / n);
        for (int ch = 0; ch < 3; ++ch) c[ch] = a * c[ch] + (1 - a) * prev_colour.data()[k * 3 + ch];
        // In double, clamped: the second moment may be at the float range's end.
        for (int j = 0; j < 2; ++j)
          m[j] = float(std::clamp(am * double(m[j]) + (1 - am) * double(prev_moments.data()[k * 2 + j]),
                                  -double(FLT_MAX), double(FLT_MAX)));
      }
    });
    return out;
  }

  // Step 2: the luminance variance, temporal where n >= 4, else spatial (7x7, which also
  // replaces the illumination with its cross-bilateral filtering, as the reference code does).
  svgf::Signal estimate_variance(const Component& acc, const Image& length, const svgf::Guides& g) const {
    const int w = acc.colour.width(), h = acc.colour.height();
    svgf::Signal s;
    s.c = svgf::to_planes(acc.colour);
    s.var = Planes(w, h, 1);
    tbb::parallel_for(0, h, [&](int y) {
      for (int x = 0; x < w; ++x) {
        const std::size_t k = std::size_t(y) * w + x;
        const float n = length.data()[k];
        if (n >= kShortHistory) {
          s.var.data[k] = float(variance_of(acc.moments.data()[k * 2], acc.moments.data()[k * 2 + 1]));
          continue;
        }
        const float lp = lum(acc.colour.data() + k * 3);
        double sw = 0, m1 = 0, m2 = 0, sc[3] = {0, 0, 0};
        for (int j = -kSpatialRadius; j <= kSpatialRadius; ++j) {
          const int yy = y + j;
          if (yy < 0 || yy >= h) continue;
          for (int i = -kSpatialRadius; i <= kSpatialRadius; ++i) {
            const int xx = x + i;
            if (xx < 0 || xx >= w) continue;
            const std::size_t q = std::size_t(yy) * w + xx;
            float wq = 1;
            if (i != 0 || j != 0) {
              const float ez = std::fabs(g.z.data[k] - g.z.data[q]) * g.inv_fw.data[k] /
                               (kDepthScale * std::sqrt(float(i * i + j * j)));
              const float el = std::fabs(lp - lum(acc.colour.data() + q * 3)) / pass_.sigma_luminance;
              float dot = 0;
              for (int c = 0; c < 4; ++c) dot += g.n.plane(c)[k] * g.n.plane(c)[q];
              wq = power(std::max(0.0f, dot), pass_.sigma_normal) * exp_nonpositive(-(ez + el));
            }
            sw += wq;
            m1 += double(wq) * acc.moments.data()[q * 2];
            m2 += double(wq) * acc.moments.data()[q * 2 + 1];
            for (int c = 0; c < 3; ++c) sc[c] += double(wq) * acc.colour.data()[q * 3 + c];
          }
        }
        // sw >= 1 (the centre's weight).
        s.var.data[k] = float(std::min(variance_of(m1 / sw, m2 / sw) * (kShortHistory / double(n)), kMaxVariance));
        for (int c = 0; c < 3; ++c) s.c.plane(c)[k] = float(sc[c] / sw);
      }
    });
    return s;
  }

  // Step 4's TAA, as the reference implementation's TAA pass (Falcor's, which the SVGF authors'
  // code runs after the filter; Karis 2014): where the previous output reprojects (the
  // disocclusion test's valid pixels), it is fetched with the Catmull-Rom bicubic filter at
  // c + motion(c), taken to YCgCo, clamped to the box mean +- taa_box_sigma standard deviations
  // of this frame's output over the 3x3 neighbourhood (in YCgCo), and blended in with
  // a = taa_alpha. The bicubic fetch keeps the detail that a bilinear one blurs (a bilinear fetch
  // half a pixel off keeps cos(pi / P) of a period of P pixels: 71% at P = 4, 92% at 8), and the
  // output feeds itself back, so a bilinear fetch's blur compounds over the frames under a
  // sub-pixel motion; the box is tighter than the neighbourhood's min and max, which a blurred
  // history lies within.
  Image antialias(const Image& current, const AovFrame& f, const metrics::Reprojection& history) const {
    const int w = current.width(), h = current.height();
    const Image& motion = f.layer(layer::kMotion);
    Image out = current;
    tbb::parallel_for(0, h, [&](int y) {
      for (int x = 0; x < w; ++x) {
        const std::size_t k = std::size_t(y) * w + x;
        if (!history.valid(k)) continue;
        // The 3x3 box in YCgCo (pixels inside the image).
        double mean[3] = {0, 0, 0}, sq[3] = {0, 0, 0};
        int count = 0;
        for (int yy = std::max(0, y - 1); yy <= std::min(h - 1, y + 1); ++yy)
          for (int xx = std::max(0, x - 1); xx <= std::min(w - 1, x + 1); ++xx) {
            float v[3];
            to_ycgco(current.pixel(xx, yy), v);
            for (int c = 0; c < 3; ++c) mean[c] += v[c], sq[c] += double(v[c]) * v[c];
            ++count;
          }
        // The history: Catmull-Rom at the pixel's position in the previous frame, in pixel-centre
        // coordinates (x + motion.X, y + motion.Y), edges clamped.
        const double u = x + double(motion.at(x, y, 0)), v = y + double(motion.at(x, y, 1));
        const double x0 = std::floor(u), y0 = std::floor(v);
        float wx[4], wy[4];
        catmull_rom(float(u - x0), wx);
        catmull_rom(float(v - y0), wy);
        float prev[3] = {0, 0, 0};
        for (int j = 0; j < 4; ++j) {
          const int yy = std::clamp(int(y0) - 1 + j, 0, h - 1);
          for (int i = 0; i < 4; ++i) {
            const int xx = std::clamp(int(x0) - 1 + i, 0, w - 1);
            const float* p = output_.pixel(xx, yy);
            for (int c = 0; c < 3; ++c) prev[c] += wx[i] * wy[j] * p[c];
          }
        }
        float cur[3], hist[3], blend[3];
        to_ycgco(current.pixel(x, y), cur);
        to_ycgco(prev, hist);
        for (int c = 0; c < 3; ++c) {
          const double m = mean[c] / count, sd = std::sqrt(std::max(0.0, sq[c] / count - m * m));
          const float lo = float(m - taa_box_sigma_ * sd), hi = float(m + taa_box_sigma_ * sd);
          const float clamped = std::clamp(hist[c], lo, hi);
          blend[c] = taa_alpha_ * cur[c] + (1 - taa_alpha_) * clamped;
        }
        float* o = out.data() + k * 3;
        from_ycgco(blend, o);
        for (int c = 0; c < 3; ++c) o[c] = std::max(o[c], 0.0f);  // the bicubic's negative lobes
      }
    });
    return out;
  }

  float alpha_, moments_alpha_;
  int iterations_;
  float sigma_z_;
  bool separate_, taa_;
  float taa_alpha_, taa_box_sigma_;
  svgf::PassSettings pass_;
  metrics::SurfaceTest test_;
  // The last frame's: per component its history, the history length n, the output (TAA's
  // history) and the depth and normal.
  std::vector<Component> components_;
  Image length_, output_;
  PreviousGuides guides_;
};

}  // namespace

MethodInfo svgf_temporal_method() {
  std::vector<ParamSpec> params = {
      {"alpha", ParamType::Float, "0.2", "colour history blend: a = max(alpha, 1/n) for the new frame (paper: 0.2)", 0.01,
       1.0},
      {"moments_alpha", ParamType::Float, "0.2", "moments history blend, as alpha (paper: 0.2)", 0.01, 1.0},
      {"iterations", ParamType::Int, "5", "a-trous passes, taps 1, 2, 4, ... apart (paper: 5)", 1.0, 10.0},
      {"sigma_luminance", ParamType::Float, "4", "luminance edge-stopping: |dl| / (sigma sqrt(Var l)) (paper: 4)", 1e-3,
       1e4},
      {"sigma_normal", ParamType::Int, "128", "normal edge-stopping exponent: max(0, n_p . n_q)^sigma (paper: 128)", 0.0,
       4096.0},
      {"sigma_depth", ParamType::Float, "1", "depth edge-stopping: |dz| / (sigma |grad z| |q - p|) (paper: 1)", 1e-4,
       1e4},
      {"separate", ParamType::Bool, "true", "filter D and I apart, each with its own history (paper: true)"},
      {"variance_prefilter", ParamType::Bool, "true", "3x3 Gaussian of the variance before each pass (paper: true)"},
      {"taa", ParamType::Bool, "false",
       "temporal antialiasing of the output (paper: true; off here: the frames are antialiased and not jittered, so "
       "TAA only blurs them, see the file's header)"},
      {"taa_alpha", ParamType::Float, "0.1", "TAA blend weight of the new frame (Karis 2014: 0.1)", 0.01, 1.0},
      {"taa_box_sigma", ParamType::Float, "1",
       "TAA history clamp: the 3x3 neighbourhood's mean +- this many standard deviations, in YCgCo (Falcor's TAA: 1)",
       0.0, 100.0},
  };
  for (auto& s : surface_test_params()) params.push_back(std::move(s));
  return {
      .name = "svgf_temporal",
      .description = "SVGF (Schied et al. 2017) over a sequence: reprojected history, temporal variance, "
                     "variance-guided a-trous, optional TAA",
      .kind = MethodKind::Filter,
      .temporal = true,
      .params = std::move(params),
      .create = [](const Params& p) { return std::make_unique<SvgfTemporal>(p); },
  };
}

}  // namespace dnb
