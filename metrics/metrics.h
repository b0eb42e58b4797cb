// Error metrics against a reference (docs/design.md, "Metric conventions"), each with a per-pixel
// error map, and a registry of them by name.
//
//   mse      8-bit sRGB (exposure 1, clamp [0,1], sRGB transfer, x255, rounded): Table 1's scale
//   mse_hdr  linear radiance
//   relmse   mean of (x - y)^2 / (y^2 + 0.01), linear radiance
//   psnr     10 log10(255^2 / mse) from the 8-bit mse (+inf for identical images)
//   ssim     Wang et al. 2004: Gaussian 11x11, sigma 1.5, K1 0.01, K2 0.03, on the 8-bit image
//            (luminance-free: mean over the R, G, B channels, 'valid' window positions)
//   flip     mean LDR-FLIP (Andersson et al. 2020), 67 pixels per degree
//   hdrflip  mean HDR-FLIP (Andersson et al. 2021) on the linear radiance, 67 pixels per degree
//   mse_hdr_nc, relmse_nc  mse_hdr and relmse less the reference's own expected share (see
//            reference_error); need the reference's variance, n/a without it
//   mse_converged  the 8-bit mse over the pixels whose reference has converged (see
//            unconverged_mask); needs the reference's variance, n/a without it
//
// Every metric refuses images of unequal shape and any non-finite sample (InputError): a NaN
// is never silently averaged.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/image.h"

namespace dnb::metrics {

struct MetricResult {
  double value = 0;
  Image map;  // 1 channel, the image's size: the per-pixel error (SSIM: 1 - local SSIM)
};

// The reference's own expected error (reference_error below) for the metrics it is known for.
struct ReferenceError {
  double mse = 0, mse_hdr = 0, relmse = 0;
};

// A metric and everything the harness does differently for it: the one place that knows which
// metrics keep maps, are pooled, need the reference's variance. Adding a metric is one entry
// of all_metrics().
struct MetricInfo {
  std::string name;
  std::string description;       // one line, for `denoisebench list metrics`
  bool lower_is_better = true;   // false for psnr and ssim
  // `reference_variance`: the reference's per-pixel variance of the mean (3 channels), or null
  // where it is not known; the metrics that need it are NaN (n/a) without it.
  std::function<MetricResult(const Image& image, const Image& reference, const Image* reference_variance)> fn;
  // True for the metrics of linear radiance (mse_hdr, relmse, hdrflip): an 8-bit file (PNG, JPEG) holds
  // display values clipped to [0, 1], so those metrics would measure the clipping, not the image.
  bool needs_linear = false;
  bool needs_reference_variance = false;  // n/a without the reference's variance
  // Scores only the reference's converged pixels (unconverged_mask): tables show the share left out.
  bool masks_unconverged = false;
  // A run keeps this metric's map beside every cell's image (files "error_<name>") for the report.
  bool run_keeps_map = false;
  // Its map is pooled as FLIP's tool reports it (pool_flip: weighted median, quartiles, ...).
  bool pooled = false;
  // Its map lives in [0, 1] and is shown so (FLIP, 1 - SSIM); other maps up to their 99th percentile.
  bool unit_map = false;
  std::string map_label = {};  // the map's colour-bar label where it is not the name (ssim: "1 - ssim")
  // The reference's own expected share of this metric (reference_error), or null where unknown.
  double ReferenceError::*reference_error = nullptr;
  // Keeps the last reference's filtered images between calls (FLIP's memo): a benchmark times a
  // new reference as well as a repeated one.
  bool memoises_reference = false;

  MetricResult compute(const Image& image, const Image& reference, const Image* reference_variance = nullptr) const {
    return fn(image, reference, reference_variance);
  }
  const std::string& map_name() const { return map_label.empty() ? name : map_label; }
};

// The registered metrics in report order (mse first: Table 1).
const std::vector<MetricInfo>& all_metrics();
std::vector<std::string> metric_names();
// InputError listing the valid names when unknown.
const MetricInfo& metric(const std::string& name);
// Null when unknown (a results file of another build may name metrics this one lacks).
const MetricInfo* find_metric(const std::string& name);
// The reference's own expected error by metric name, for the metrics that have one.
std::map<std::string, double> reference_error_by_metric(const ReferenceError& e);

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

// HDR-FLIP (Andersson, Nilsson, Shirley, Akenine-Moller: "Visualizing Errors in Rendered High
// Dynamic Range Images", Eurographics 2021 short paper), as NVIDIA's FLIP tool computes it:
// both images are exposed (x 2^c) and tone-mapped at `count` exposures c evenly spaced from
// `start` to `stop`, LDR-FLIP (above, without its display transform) scores each pair, and a
// pixel's error is its largest over the exposures. The tone mapper is the paper's ACES fit
// (Narkowicz) with FLIP's 0.6 pre-exposure:
//   T(x) = clamp((k0 x^2 + k1 x) / (k3 x^2 + k4 x + k5), 0, 1),
//   k0 = 0.6^2 2.51, k1 = 0.6 0.03, k3 = 0.6^2 2.43, k4 = 0.6 0.59, k5 = 0.14,
// per channel. The range comes from the reference (section 3): x_max is the radiance T maps to
// 0.85, and with Y the luminance (0.2126 R + 0.7152 G + 0.0722 B)
//   start = log2(x_max / Y_max)     the brightest pixel just below white,
//   stop  = log2(x_max / Y_median)  the median pixel just below white,
//   count = max(2, ceil(stop - start)).
// Y_median is the luminance at rank n/2 of the n sorted ones (the middle one for odd n, the upper
// middle one for even n), as in FLIP 1.7; some older FLIP releases averaged the two middle ones. Two cases FLIP leaves undefined (it divides by
// zero): a reference whose median pixel is black takes the median of its non-black pixels, and
// an all-black reference takes start = stop = 0. Negative samples count as 0 (black), as in
// LDR-FLIP's clamp; FLIP itself requires non-negative input.
struct HdrFlipExposures {
  double start = 0;            // c_start, stops
  double stop = 0;             // c_stop, stops (>= start)
  int count = 2;               // exposures, >= 2, `start` and `stop` included
  double luminance_max = 0;    // Y_max of the reference
  double luminance_median = 0; // the Y used for `stop` (see above)
  double exposure(int i) const { return start + i * (stop - start) / (count - 1); }
};
// InputError unless `reference` is a 3-channel image with only finite samples.
HdrFlipExposures hdrflip_exposures(const Image& reference);
// The LDR image HDR-FLIP scores at exposure c: T(2^c max(x, 0)) per channel, linear, in [0, 1].
Image hdrflip_tone_map(const Image& linear, double exposure);
// The map is the per-pixel HDR-FLIP (the largest LDR-FLIP over the exposures), in [0, 1].
MetricResult hdrflip(const Image& image, const Image& reference, double pixels_per_degree = 67.0);

// A FLIP error map pooled as FLIP's tool reports it (its text, CSV and histogram outputs): the mean,
// min and max, and percentiles weighted by the error values themselves, so that a few large errors
// are not lost among many small ones. The weighted p-percentile is the smallest error e of the
// map, sorted ascending, at which the running sum of the errors up to and including e exceeds
// p times their total (FLIP's pooling::getPercentile(p, weighted = true); not its 100-bucket
// histogram). All zero for a map without error.
struct FlipPooled {
  double mean = 0;
  double weighted_median = 0;          // p = 0.5
  double weighted_first_quartile = 0;  // p = 0.25
  double weighted_third_quartile = 0;  // p = 0.75
  double min = 0;
  double max = 0;
};
// InputError unless `map` is a non-empty 1-channel image with only finite values (a
// MetricResult's map).
FlipPooled pool_flip(const Image& map);

// Where a method makes things worse, not only how much on average: the image and the baseline it
// was made from (a method's input frame) cut into `block` x `block` tiles (the last row and
// column of tiles take what is left), each tile's 8-bit mse against the reference, and the share
// of tiles where the image's is above the baseline's, and above twice it. A method that erases
// thin features can have the lowest mean error and still be worse than its input in places.
struct WorseBlocks {
  int block = 16;
  int count = 0;                 // tiles
  double worse = 0;              // share of tiles with mse(image) > mse(baseline)
  double worse_twice = 0;        // share with mse(image) > 2 mse(baseline)
  // The tiles where the image is worse, worst first (by mse(image) / mse(baseline); a tile whose
  // baseline error is 0 counts as kMaxRatio), at most kMaxTiles of them: where to look.
  struct Tile {
    int x = 0, y = 0, w = 0, h = 0;
    double ratio = 0;
  };
  static constexpr std::size_t kMaxTiles = 64;
  static constexpr double kMaxRatio = 1e6;
  std::vector<Tile> tiles;
};
// InputError unless the three are 3-channel images of one size with finite samples.
WorseBlocks worse_blocks(const Image& image, const Image& baseline, const Image& reference, int block = 16);

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

// The reference's own error, from its variance of the mean v. Scored against a noisy
// reference r = mu + e, an image x independent of it has E[(x - r)^2] = E[(x - mu)^2] + Var(r)
// per sample: the reference adds its variance to every method's mse_hdr. Hence
//   mse_hdr_nc = mean of (x - r)^2 - v             (unbiased for the error against the truth)
//   relmse_nc  = mean of ((x - r)^2 - v) / (r^2 + 0.01)   (first order in v / (r^2 + 0.01))
// and the reference's own expected error, what a perfect image would score: mean v (mse_hdr),
// mean v / (r^2 + 0.01) (relmse), and for the 8-bit mse the first-order (delta-method)
// estimate mean of (d display / d r)^2 v, which ignores rounding and, where the clamp holds
// (r >= 1), counts nothing. The variance must be the variance of the mean (tracer version 4 on:
// docs/references.md); InputError as for mse_converged.
ReferenceError reference_error(const Image& reference, const Image& reference_variance);
MetricResult mse_hdr_nc(const Image& image, const Image& reference, const Image* reference_variance);
MetricResult relmse_nc(const Image& image, const Image& reference, const Image* reference_variance);
// InputError unless `variance` is a 3-channel image of the reference's size, finite and >= 0.
void check_variance(const Image& reference, const Image& variance);

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
