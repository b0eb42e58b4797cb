// temporal_accumulation: the simplest temporal method, and the temporal rows' floor. It keeps one
// image of history, reprojects it onto each new frame with the motion layer, drops it where the
// disocclusion test fails, and blends exponentially:
//     L_t = a * l_t + (1 - a) * W(L_{t-1}),   a = max(alpha, 1 / n),
// W the reprojection (metrics/temporal.h: bilinear, the taps of other surfaces dropped), n the
// pixel's history length counting this frame (the reprojected length + 1; 1 where the history was
// dropped, so L_t = l_t). The 1/n floor makes the first frames a plain mean of what there is,
// rather than weighting frame 0 by (1 - alpha)^t (SVGF's reference code does the same); alpha is
// SVGF's 0.2, which holds the variance of a static pixel at alpha / (2 - alpha) = 1/9 of a frame's.
// No spatial filter: a pixel without history is its input.
//
// On the demodulated illumination l = D + I (denoisers/illumination.h), remodulated with the
// current frame's albedo, F = L * T + R + E: the albedo is noise-free and sharp in every frame,
// so a texture moving under the camera stays as sharp as this frame shows it, and the bilinear
// reprojection blurs only the smooth illumination. R (mirror reflections) and E pass through from
// the current frame: a reflection moves with the mirrored surface, not with the mirror, so
// surface motion vectors would smear it.
//
// Deterministic: each pixel is computed on its own in a fixed order; TBB splits rows only.
//
// Parameters: the ParamSpec list at the end of this file.
#include <algorithm>
#include <vector>

#include <tbb/parallel_for.h>

#include "denoisers/illumination.h"
#include "denoisers/method.h"
#include "denoisers/temporal_history.h"

namespace dnb {
namespace {

class TemporalAccumulation final : public TemporalIlluminationMethod {
 public:
  explicit TemporalAccumulation(const Params& p) : alpha_(float(p.f("alpha"))), test_(surface_test(p)) {}

  void reset() override {
    TemporalIlluminationMethod::reset();
    history_ = Image();
    length_ = Image();
  }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    const AovFrame& f = *in.frame;
    const bool carry = cursor_.continues(in);
    Image light = illumination(f);
    Image length(f.width(), f.height(), 1, 1.0f);
    std::size_t kept = 0;
    if (carry) {
      ScopedPhase p(r.stats, "reproject");
      const metrics::Reprojection history = reproject_history(f, guides_, test_);
      const Image previous = history.warp(history_), previous_length = history.warp(length_);
      tbb::parallel_for(0, f.height(), [&](int y) {
        for (int x = 0; x < f.width(); ++x) {
          const std::size_t k = std::size_t(y) * f.width() + x;
          if (!history.valid(k)) continue;
          const float n = previous_length.data()[k] + 1.0f;
          const float a = std::max(alpha_, 1.0f / n);
          for (int c = 0; c < 3; ++c) light.data()[k * 3 + c] = a * light.data()[k * 3 + c] + (1 - a) * previous.data()[k * 3 + c];
          length.data()[k] = n;
        }
      });
      kept = f.width() * std::size_t(f.height()) - history.invalid_count();
    }
    r.stats.counters["history_pixels"] = double(kept);
    {
      ScopedPhase p(r.stats, "compose");
      r.image = compose(light, f);
    }
    history_ = std::move(light);
    length_ = std::move(length);
    guides_ = PreviousGuides::of(f);
    cursor_.advance(in);
    return r;
  }

 private:
  float alpha_;
  metrics::SurfaceTest test_;
  Image history_, length_;  // the accumulated illumination L and the history length n of the last frame
  PreviousGuides guides_;
};

}  // namespace

MethodInfo temporal_accumulation_method() {
  std::vector<ParamSpec> params = {
      {"alpha", ParamType::Float, "0.2",
       "blend weight of the new frame, a = max(alpha, 1/n) for a history of n frames (SVGF's 0.2)", 0.01, 1.0},
  };
  for (auto& s : surface_test_params()) params.push_back(std::move(s));
  return {
      .name = "temporal_accumulation",
      .description = "reprojected exponential average of the demodulated illumination over a sequence's frames, "
                     "history dropped at disocclusions; no spatial filter",
      .kind = MethodKind::Filter,
      .temporal = true,
      .params = std::move(params),
      .create = [](const Params& p) { return std::make_unique<TemporalAccumulation>(p); },
  };
}

}  // namespace dnb
