// OpenCV ximgproc's AdaptiveManifoldFilter set up from our AmSettings, for am_opencv and for the
// tests that compare it with our core (tests/denoisers/am_test.cpp).
#pragma once

#include <opencv2/ximgproc/edge_filter.hpp>

#include "denoisers/am/adaptive_manifold.h"

namespace dnb {

// sigma_s, sigma_r, tree_height (0: OpenCV's automatic height), pca_iterations and
// adjust_outliers passed to the filter's setters; its other settings are OpenCV's defaults.
cv::Ptr<cv::ximgproc::AdaptiveManifoldFilter> opencv_am_filter(const AmSettings& s);

}  // namespace dnb
