// nlmeans: OpenCV's fastNlMeansDenoisingColored (Buades, Coll and Morel 2005) on the colour
// image F. OpenCV converts to CIELAB and denoises lightness with `h` and colour with `h_color`.
//
// HDR: that function takes 8-bit images only. The radiance is mapped to 8 bits through a range
// map (denoisers/hdr_mapping.h), denoised, and the denoiser's *correction* is applied to the
// unquantized input in the compressed domain:
//     y_out = y_in + (den8 - in8) / 255
// where in8 is the input after the same 8-bit RGB -> CIELAB -> RGB round trip the function
// makes. A region the denoiser leaves alone thus comes back exactly (no banding; constants stay
// constant), and quantization costs at most the input's own rounding residual (half a code).
// The maps:
//   srgb      (default) the sRGB transfer of [0, 1], the metrics' own 8-bit domain, so all 256
//             codes go where the 8-bit MSE looks. The part of a value above 1 is not filtered: it
//             is added back unchanged, so highlights keep their energy but not their denoising.
//   reinhard  y = (x / (1 + x))^(1/2.2): keeps every value, but [0, 1] gets only 186 codes.
// What is lost in either: patch distances see 8-bit data, so differences below one code are
// invisible to the weights: with srgb one code is about 0.9% of the value at x = 1 and 2.3% at
// x = 0.1; with reinhard 2.4% at x = 1 and far more in highlights.
//
// Parameters: the ParamSpec list at the end of this file, the only place they are documented
// (`denoisebench list methods` prints it); how the defaults were chosen: docs/method-defaults.md.
#include <algorithm>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>
#include <tbb/parallel_for.h>

#include "core/errors.h"
#include "denoisers/hdr_mapping.h"
#include "denoisers/method.h"

namespace dnb {
namespace {

class NlMeans final : public Method {
 public:
  explicit NlMeans(const Params& p)
      : h_(float(p.f("h"))),
        h_color_(float(p.f("h_color"))),
        template_window_(p.i("template_window")),
        search_window_(p.i("search_window")),
        map_(parse_range_map(p.s("range_map"))) {
    for (const char* k : {"template_window", "search_window"})
      if (p.i(k) % 2 == 0) throw InputError(fmt::format("method 'nlmeans': parameter '{}' = {}: expected an odd number", k, p.i(k)));
  }

  std::vector<std::string> required_layers() const override { return {layer::kColor}; }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    const Image& color = in.frame->layer(layer::kColor);
    cv::Mat in8, den8;
    {
      ScopedPhase p(r.stats, "to_8bit");
      in8 = to_8bit(map_, color);
    }
    {
      ScopedPhase p(r.stats, "nlmeans");
      // OpenCV expects BGR order; the conversion to CIELAB inside depends on it.
      cv::Mat bgr, lab;  // OpenCV works in BGR order; its Lab conversion is of linear BGR ("LBGR")
      cv::cvtColor(in8, bgr, cv::COLOR_RGB2BGR);
      cv::fastNlMeansDenoisingColored(bgr, den8, h_, h_color_, template_window_, search_window_);
      cv::cvtColor(den8, den8, cv::COLOR_BGR2RGB);
      // The function works on 8-bit CIELAB, and the 8-bit RGB -> Lab -> RGB round trip alone moves
      // codes. The correction is measured against that round trip, so that only the denoising,
      // not the colour-space quantization, is applied to the input.
      cv::cvtColor(bgr, lab, cv::COLOR_LBGR2Lab);
      cv::cvtColor(lab, in8, cv::COLOR_Lab2LRGB);
    }
    {
      ScopedPhase p(r.stats, "apply_correction");
      Image out(color.width(), color.height(), 3);
      const int w = color.width();
      tbb::parallel_for(0, color.height(), [&](int y) {
        const std::uint8_t* a = in8.ptr<std::uint8_t>(y);
        const std::uint8_t* b = den8.ptr<std::uint8_t>(y);
        for (int i = 0; i < 3 * w; ++i) {
          const float x = color.pixel(0, y)[i];
          const float yin = std::clamp(compress(map_, x), 0.0f, 1.0f);
          const float yout = yin + (float(b[i]) - float(a[i])) / 255.0f;
          // srgb keeps [0, 1] only: the excess above 1 passes through unfiltered.
          const float excess = map_ == RangeMap::Srgb ? std::max(x - 1.0f, 0.0f) : 0.0f;
          out.pixel(0, y)[i] = expand(map_, std::clamp(yout, 0.0f, 1.0f)) + excess;
        }
      });
      r.image = std::move(out);
    }
    return r;
  }

 private:
  float h_, h_color_;
  int template_window_, search_window_;
  RangeMap map_;
};

}  // namespace

MethodInfo nlmeans_method() {
  return {
      .name = "nlmeans",
      .description = "OpenCV fastNlMeansDenoisingColored on the colour image, through a documented 8-bit HDR mapping",
      .kind = MethodKind::Filter,
      .params =
          {
              {"h", ParamType::Float, "5", "filter strength for lightness, 8-bit code units", 0.0, 255.0},
              {"h_color", ParamType::Float, "1", "filter strength for colour (CIELAB a, b), 8-bit code units", 0.0, 255.0},
              {"template_window", ParamType::Int, "5", "patch side in pixels (odd)", 1.0, 35.0},
              {"search_window", ParamType::Int, "21", "search window side in pixels (odd)", 1.0, 101.0},
              {"range_map", ParamType::String, "srgb", "domain of the 8-bit mapping (denoisers/hdr_mapping.h)", {}, {},
               {"reinhard", "srgb"}},
          },
      .create = [](const Params& p) { return std::make_unique<NlMeans>(p); },
  };
}

}  // namespace dnb
