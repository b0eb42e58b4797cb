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
//   mse_converged  the 8-bit mse over the pixels whose reference has converged (see
//            unconverged_mask); needs the reference's variance, n/a without it
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
  // `reference_variance`: the reference's per-pixel variance of the mean (3 channels), or null
  // where it is not known; only mse_converged uses it (its value is NaN without it).
  std::function<MetricResult(const Image& image, const Image& reference, const Image* reference_variance)> fn;
  // True for the metrics of linear radiance (mse_hdr, relmse): an 8-bit file (PNG, JPEG) holds
  // display values clipped to [0, 1], so those metrics would measure the clipping, not the image.
  bool needs_linear = false;

  MetricResult compute(const Image& image, const Image& reference, const Image* reference_variance = nullptr) const {
    return fn(image, reference, reference_variance);
  }
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

// The reference's own noise. A 4096-spp reference still holds fireflies: pixels whose value is
// carried by a handful of its samples, often several times their neighbours' brightness. No
// unbiased method can match them, and in a scene like sponza they hold most of every method's
// 8-bit MSE, which then measures the reference more than the method. From the reference's
// variance of the mean, a pixel's relative standard error is
//   rse = max over channels of sqrt(variance) / max over channels of the mean;
// when k samples of equal size carry a pixel's value, rse is about 1/sqrt(k), so rse > 1/2 says
// "fewer than about 4 samples carry this pixel". Such pixels are unconverged (1 in the mask).
// A pixel of zero mean is unconverged only if its variance is not zero.
inline constexpr double kUnconvergedRse = 0.5;
Image unconverged_mask(const Image& reference, const Image& reference_variance, double max_rse = kUnconvergedRse);
// Share of the reference's pixels the mask leaves out, in [0, 1].
double unconverged_share(const Image& reference, const Image& reference_variance, double max_rse = kUnconvergedRse);
// The 8-bit mse over the converged pixels only (the same pixels for every method scored against
// this reference); the map is the 8-bit squared error with the unconverged pixels set to 0.
// InputError if the variance is not a 3-channel image of the reference's size with finite,
// non-negative samples. NaN (reported n/a) when `reference_variance` is null or when every
// pixel is unconverged.
MetricResult mse_converged(const Image& image, const Image& reference, const Image* reference_variance);

// `denoisebench metrics IMAGE REF`: IMAGE's R,G,B scored against REF's with every metric, the
// reference's variance of the mean (variance.R/G/B) used when the file has it. InputErrors name
// the file (and the channel): a missing channel, unequal sizes, a malformed variance.
struct FileScores {
  std::vector<std::pair<std::string, double>> values;  // every metric, in all_metrics() order
  bool has_variance = false;          // mse_converged is NaN without it
  double unconverged_share = 0;       // of the reference's pixels (when has_variance)
};
FileScores score_files(const std::string& image_path, const std::string& reference_path);

}  // namespace dnb::metrics
