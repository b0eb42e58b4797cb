// Error metrics against a reference (DESIGN.md, "Metric conventions"), each with a per-pixel
// error map, and a registry of them by name.
//
//   mse      8-bit sRGB (exposure 1, clamp [0,1], sRGB transfer, x255, rounded): Table 1's scale
//   mse_hdr  linear radiance
//   relmse   mean of (x - y)^2 / (y^2 + 0.01), linear radiance
//   psnr     10 log10(255^2 / mse) from the 8-bit mse (+inf for identical images)
//   ssim     Wang et al. 2004: Gaussian 11x11, sigma 1.5, K1 0.01, K2 0.03, on the 8-bit image
//            (luminance-free: mean over the R, G, B channels, 'valid' window positions)
//   flip     mean LDR-FLIP (Andersson et al. 2020), 67 pixels per degree
//
// Every metric refuses images of unequal shape and any non-finite sample (InputError): a NaN
// is never silently averaged.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "core/image.h"

namespace dnb::metrics {

struct MetricResult {
  double value = 0;
  Image map;  // 1 channel, the image's size: the per-pixel error (SSIM: 1 - local SSIM)
};

struct MetricInfo {
  std::string name;
  std::string description;       // one line, for `denoisebench list metrics`
  bool lower_is_better = true;   // false for psnr and ssim
  std::function<MetricResult(const Image& image, const Image& reference)> compute;
};

// The registered metrics in report order (mse first: Table 1).
const std::vector<MetricInfo>& all_metrics();
std::vector<std::string> metric_names();
// InputError listing the valid names when unknown.
const MetricInfo& metric(const std::string& name);

// InputError unless both are 3-channel images of the same size with only finite samples.
// `image_name` and `reference_name` name them in the message (file names where known).
void check_pair(const Image& image, const Image& reference, const std::string& image_name = "image",
                const std::string& reference_name = "reference");

// The display transform of the 8-bit metrics: exposure 1, clamp to [0,1], sRGB transfer, 0..255
// rounded to integers (as an 8-bit file would hold them).
Image to_srgb8(const Image& linear);
double srgb_encode(double linear);  // [0,1] -> [0,1]
double srgb_decode(double encoded);

MetricResult mse(const Image& image, const Image& reference);
MetricResult mse_hdr_map(const Image& image, const Image& reference);
double mse_hdr(const Image& image, const Image& reference);
MetricResult relmse(const Image& image, const Image& reference);
MetricResult psnr(const Image& image, const Image& reference);
MetricResult ssim(const Image& image, const Image& reference);
MetricResult flip(const Image& image, const Image& reference, double pixels_per_degree = 67.0);

}  // namespace dnb::metrics
