// am_opencv: OpenCV ximgproc's AdaptiveManifoldFilter on the same input and guide as `am`
// (linear colour filtered, guide the range-compressed colour), kept as a cross-check of our
// core and as a speed anchor (bench/am_bench.cpp). Differences from `am` that make the outputs
// close but not equal (tests/denoisers/am_test.cpp measures them): OpenCV reduces resolution by
// bilinear resampling (ours: box average of each block), its random split vector comes from
// cv::RNG seeded with the guide's centre pixel (ours: a hash of the guide), and its power
// iteration restarts each step from that random vector.
//
// Parameters: those of `am`, one definition (am_colour.h; `denoisebench list methods`), passed to
// cv::ximgproc::AdaptiveManifoldFilter's setters.
#include <algorithm>
#include <cmath>

#include <opencv2/core.hpp>

#include "denoisers/am_colour.h"
#include "denoisers/am_opencv.h"

namespace dnb {
namespace {

class AmOpenCv final : public ColourAmMethod {
 public:
  using ColourAmMethod::ColourAmMethod;

 private:
  Image filter(const Image& color, const Image& guide, MethodStats& stats) const override {
    const AmSettings& s = settings();
    auto amf = opencv_am_filter(s);
    amf->setUseRNG(true);
    // OpenCV's reduced grid has round(size / df) pixels and asserts on 0: small images are
    // padded (edge pixels replicated) to 2 df and cropped back.
    const int df = am_downsample_factor(s.sigma_s, s.sigma_r);
    const int pw = std::max(0, 2 * df - color.width()), ph = std::max(0, 2 * df - color.height());
    cv::Mat src = as_mat(color), joint = as_mat(guide), out;
    if (pw || ph) {
      cv::copyMakeBorder(as_mat(color), src, 0, ph, 0, pw, cv::BORDER_REPLICATE);
      cv::copyMakeBorder(as_mat(guide), joint, 0, ph, 0, pw, cv::BORDER_REPLICATE);
    }
    amf->filter(src, out, joint);
    Image image = from_mat(out(cv::Rect(0, 0, color.width(), color.height())).clone());
    // OpenCV divides by zero when a split leaves a cluster empty (a flat guide, e.g. a constant
    // image): those pixels come back NaN. They keep their input value, counted.
    std::size_t repaired = 0;
    for (std::size_t k = 0; k < image.size(); ++k)
      if (!std::isfinite(image.data()[k])) {
        image.data()[k] = color.data()[k];
        ++repaired;
      }
    stats.counters["opencv_nonfinite_outputs"] = double(repaired);
    return image;
  }
};

}  // namespace

cv::Ptr<cv::ximgproc::AdaptiveManifoldFilter> opencv_am_filter(const AmSettings& s) {
  auto amf = cv::ximgproc::AdaptiveManifoldFilter::create();
  amf->setSigmaS(s.sigma_s);
  amf->setSigmaR(s.sigma_r);
  amf->setTreeHeight(s.tree_height > 0 ? s.tree_height : -1);
  amf->setPCAIterations(s.pca_iterations);
  amf->setAdjustOutliers(s.adjust_outliers);
  return amf;
}

MethodInfo am_opencv_method() {
  return {
      .name = "am_opencv",
      .description = "OpenCV ximgproc AdaptiveManifoldFilter on the colour (cross-check and speed anchor for am)",
      .kind = MethodKind::Filter,
      .params = colour_am_params("PCA iterations (OpenCV restarts each from its random vector)"),
      .create = [](const Params& p) { return std::make_unique<AmOpenCv>(p); },
  };
}

}  // namespace dnb
