// am_opencv: OpenCV ximgproc's AdaptiveManifoldFilter on the same input and guide as `am`
// (linear colour filtered, guide the range-compressed colour), kept as a cross-check of our
// core and as a speed anchor (bench/am_bench.cpp). Differences from `am` that make the outputs
// close but not equal (tests/denoisers/am_test.cpp measures them): OpenCV reduces resolution by
// bilinear resampling (ours: box average of each block), its random split vector comes from
// cv::RNG seeded with the guide's centre pixel (ours: a hash of the guide), and its power
// iteration restarts each step from that random vector.
//
// Parameters: those of `am`, the same list (`denoisebench list methods`), passed to
// cv::ximgproc::AdaptiveManifoldFilter's setters.
#include <algorithm>
#include <cmath>

#include <opencv2/core.hpp>
#include <opencv2/ximgproc/edge_filter.hpp>

#include "denoisers/adaptive_manifold.h"
#include "denoisers/hdr_mapping.h"
#include "denoisers/method.h"

namespace dnb {
namespace {

class AmOpenCv final : public Method {
 public:
  explicit AmOpenCv(const Params& p)
      : sigma_s_(p.f("sigma_s")),
        sigma_r_(p.f("sigma_r")),
        tree_height_(p.i("tree_height")),
        pca_iterations_(p.i("pca_iterations")),
        adjust_outliers_(p.b("adjust_outliers")),
        map_(parse_range_map(p.s("range_map"))) {}

  std::vector<std::string> required_layers() const override { return {layer::kColor}; }

  MethodResult execute(const MethodInput& in) override {
    MethodResult r;
    const Image& color = in.frame->layer(layer::kColor);
    Image guide = color;
    {
      ScopedPhase p(r.stats, "guide");
      compress(map_, guide);
    }
    {
      ScopedPhase p(r.stats, "adaptive_manifolds");
      auto amf = cv::ximgproc::AdaptiveManifoldFilter::create();
      amf->setSigmaS(sigma_s_);
      amf->setSigmaR(sigma_r_);
      amf->setTreeHeight(tree_height_ > 0 ? tree_height_ : -1);
      amf->setPCAIterations(pca_iterations_);
      amf->setAdjustOutliers(adjust_outliers_);
      amf->setUseRNG(true);
      // OpenCV's reduced grid has round(size / df) pixels and asserts on 0: small images are
      // padded (edge pixels replicated) to 2 df and cropped back.
      const int df = am_downsample_factor(sigma_s_, sigma_r_);
      const int pw = std::max(0, 2 * df - color.width()), ph = std::max(0, 2 * df - color.height());
      cv::Mat src = as_mat(color), joint = as_mat(guide), out;
      if (pw || ph) {
        cv::copyMakeBorder(as_mat(color), src, 0, ph, 0, pw, cv::BORDER_REPLICATE);
        cv::copyMakeBorder(as_mat(guide), joint, 0, ph, 0, pw, cv::BORDER_REPLICATE);
      }
      amf->filter(src, out, joint);
      r.image = from_mat(out(cv::Rect(0, 0, color.width(), color.height())).clone());
    }
    // OpenCV divides by zero when a split leaves a cluster empty (a flat guide, e.g. a constant
    // image): those pixels come back NaN. They keep their input value, counted.
    std::size_t repaired = 0;
    for (std::size_t k = 0; k < r.image.size(); ++k)
      if (!std::isfinite(r.image.data()[k])) {
        r.image.data()[k] = color.data()[k];
        ++repaired;
      }
    r.stats.counters["opencv_nonfinite_outputs"] = double(repaired);
    return r;
  }

 private:
  double sigma_s_, sigma_r_;
  int tree_height_, pca_iterations_;
  bool adjust_outliers_;
  RangeMap map_;
};

}  // namespace

MethodInfo am_opencv_method() {
  return {
      .name = "am_opencv",
      .description = "OpenCV ximgproc AdaptiveManifoldFilter on the colour (cross-check and speed anchor for am)",
      .kind = MethodKind::Filter,
      .params =
          {
              {"sigma_s", ParamType::Float, "4", "spatial standard deviation, pixels", 1.0, 512.0},
              {"sigma_r", ParamType::Float, "0.05", "range standard deviation, compressed-colour units", 1e-3, 1.0},
              {"tree_height", ParamType::Int, "0", "manifold tree height; 0: from sigma_s and sigma_r", 0.0, 12.0},
              {"pca_iterations", ParamType::Int, "1", "PCA iterations (OpenCV restarts each from its random vector)", 1.0, 100.0},
              {"adjust_outliers", ParamType::Bool, "true", "Gastal and Oliveira's outlier adjustment (eq. 11)"},
              {"range_map", ParamType::String, "reinhard", "domain of the guide (denoisers/hdr_mapping.h)", {}, {},
               range_map_names()},
          },
      .create = [](const Params& p) { return std::make_unique<AmOpenCv>(p); },
  };
}

}  // namespace dnb
