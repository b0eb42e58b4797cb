// bilateral: OpenCV's bilateralFilter (Tomasi and Manduchi 1998) on the colour image F, the
// paper's "Photoshop denoise" baseline. It sees only the colour, so texture and noise are
// smoothed alike; it is the yardstick the illumination filters must beat.
//
// HDR: the range kernel exp(-|c_p - c_q|^2 / (2 sigma_color^2)) compares colours, and in linear
// radiance a fixed sigma_color is far too small next to a lamp and far too large in a shadow.
// The filter therefore runs in a range-compressed domain (denoisers/hdr_mapping.h): by default
// reinhard, y = (x / (1 + x))^(1/2.2), which maps all radiance into [0, 1) with display-like
// steps (the sweep preferred it to log, y = log(1 + x), where sigma_color would be a relative
// difference), and the result is mapped back with the inverse. Averaging in a concave domain
// gives a mean below the linear one, so noisy pixels come back slightly darker (Jensen's
// inequality); `range_map=linear` avoids that bias at the price of the range problem above.
//
// Parameters: the ParamSpec list at the end of this file, the only place they are documented
// (`denoisebench list methods` prints it); how the defaults were chosen: docs/method-defaults.md.
#include <opencv2/imgproc.hpp>

#include "core/errors.h"
#include "denoisers/hdr_mapping.h"
#include "denoisers/method.h"

namespace dnb {
namespace {

class Bilateral final : public Method {
 public:
  explicit Bilateral(const Params& p)
      : sigma_space_(p.f("sigma_space")),
        sigma_color_(p.f("sigma_color")),
        diameter_(p.i("diameter")),
        map_(parse_range_map(p.s("range_map"))) {}

  std::vector<std::string> required_layers() const override { return {layer::kColor}; }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    Image y = in.frame->layer(layer::kColor);  // a copy: compressed in place
    {
      ScopedPhase p(r.stats, "compress");
      compress(map_, y);
    }
    Image out(y.width(), y.height(), 3);
    {
      ScopedPhase p(r.stats, "bilateral");
      // OpenCV splits rows over threads and computes each pixel alone: the result does not
      // depend on the thread count.
      cv::Mat dst = as_mat(out);
      cv::bilateralFilter(as_mat(y), dst, diameter_, sigma_color_, sigma_space_, cv::BORDER_REFLECT);
      if (dst.data != reinterpret_cast<uchar*>(out.data())) throw WorkError("bilateralFilter reallocated its output");
    }
    {
      ScopedPhase p(r.stats, "expand");
      expand(map_, out);
    }
    r.image = std::move(out);
    return r;
  }

 private:
  double sigma_space_, sigma_color_;
  int diameter_;
  RangeMap map_;
};

}  // namespace

MethodInfo bilateral_method() {
  return {
      .name = "bilateral",
      .description = "OpenCV bilateralFilter on the colour image in a range-compressed domain (paper's Photoshop baseline)",
      .kind = MethodKind::Filter,
      .params =
          {
              {"sigma_space", ParamType::Float, "1.5", "spatial Gaussian sigma in pixels", 0.1, 100.0},
              {"sigma_color", ParamType::Float, "0.1", "range Gaussian sigma in the compressed domain", 1e-4, 1e4},
              {"diameter", ParamType::Int, "0", "window diameter in pixels; 0: 2*round(1.5*sigma_space)+1", 0.0, 201.0},
              {"range_map", ParamType::String, "reinhard", "domain of the range kernel (denoisers/hdr_mapping.h)", {}, {},
               range_map_names()},
          },
      .create = [](const Params& p) { return std::make_unique<Bilateral>(p); },
  };
}

}  // namespace dnb
