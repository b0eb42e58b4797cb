// svgf: the spatial filter of SVGF (Schied, Kaplanyan, Wyman, Patney, Chaitanya, Burgess, Liu,
// Dachsbacher, Lefohn and Salvi 2017, "Spatiotemporal Variance-Guided Filtering: Real-Time
// Reconstruction for Path-Traced Global Illumination", HPG), on one frame: the temporal
// accumulation is left out (a still has no history), the rest is the paper's section 4. The
// paper's whole pipeline, for animated sequences, is `svgf_temporal` (denoisers/svgf_temporal.cpp).
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
// The a-trous passes (iterations of them, taps 1, 2, 4, ... apart) are SVGF's, shared with
// svgf_temporal: denoisers/svgf_atrous.h gives their weights. The paper's values (five passes,
// sigma_z = 1, sigma_n = 128, sigma_l = 4, D and I apart) were the sweep's start; the defaults are
// its result on the training scene (docs/method-defaults.md, "svgf").
//
// Parameters: the ParamSpec list at the end of this file; how the defaults were chosen:
// docs/method-defaults.md.
#include <cmath>
#include <vector>

#include "denoisers/illumination.h"
#include "denoisers/method.h"
#include "denoisers/svgf_atrous.h"

namespace dnb {
namespace {

using svgf::Guides;
using svgf::kLumW;
using svgf::Signal;

// The illumination's planes and its luminance variance from the per-channel variance of its
// mean (the channels taken as uncorrelated).
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
        sigma_z_(float(p.f("sigma_depth"))),
        separate_(p.b("separate")),
        pass_{.sigma_luminance = float(p.f("sigma_luminance")),
              .sigma_normal = p.i("sigma_normal"),
              .variance_prefilter = p.b("variance_prefilter")} {}

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
      g = svgf::make_guides(f, sigma_z_);
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
    for (int it = 0; it < iterations_; ++it) s = svgf::pass(s, g, 1 << it, pass_);
    return svgf::to_image(s.c);
  }

  int iterations_;
  float sigma_z_;
  bool separate_;
  svgf::PassSettings pass_;
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
