#include "metrics/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "core/errors.h"

namespace dnb::metrics {

void check_pair(const Image& image, const Image& reference, const std::string& image_name,
                const std::string& reference_name) {
  if (image.channels() != 3 || reference.channels() != 3)
    throw InputError(fmt::format("{} has {} channels and {} has {}: metrics need R,G,B (3 channels)", image_name,
                                 image.channels(), reference_name, reference.channels()));
  if (image.width() != reference.width() || image.height() != reference.height())
    throw InputError(fmt::format("{} is {}x{} but {} is {}x{}: sizes must match", image_name, image.width(),
                                 image.height(), reference_name, reference.width(), reference.height()));
  for (const auto* im : {&image, &reference})
    for (std::size_t i = 0; i < im->size(); ++i)
      if (!std::isfinite(im->data()[i])) {
        std::size_t p = i / 3;
        throw InputError(fmt::format("{} has a non-finite sample at pixel ({}, {}) channel {}: refused, not averaged",
                                     im == &image ? image_name : reference_name, p % im->width(),
                                     p / im->width(), "RGB"[i % 3]));
      }
}

double srgb_encode(double v) {
  v = std::clamp(v, 0.0, 1.0);
  return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}
double srgb_decode(double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); }

Image to_srgb8(const Image& linear) {
  Image out(linear.width(), linear.height(), linear.channels());
  for (std::size_t i = 0; i < linear.size(); ++i)
    out.data()[i] = float(std::round(255.0 * srgb_encode(linear.data()[i])));
  return out;
}

namespace {

// Mean over pixels of a per-pixel value that is itself the mean over channels.
template <typename F>
MetricResult per_sample(const Image& a, const Image& b, F f) {
  check_pair(a, b);
  MetricResult r{0, Image(a.width(), a.height(), 1)};
  double total = 0;
  for (std::size_t p = 0; p < a.pixel_count(); ++p) {
    double s = 0;
    for (int c = 0; c < 3; ++c) s += f(double(a.data()[3 * p + c]), double(b.data()[3 * p + c]));
    r.map.data()[p] = float(s / 3);
    total += s;
  }
  r.value = total / double(a.size());
  return r;
}

cv::Mat plane(const Image& im, int c) {
  cv::Mat m(im.height(), im.width(), CV_64F);
  for (int y = 0; y < im.height(); ++y)
    for (int x = 0; x < im.width(); ++x) m.at<double>(y, x) = im.at(x, y, c);
  return m;
}

}  // namespace

MetricResult mse(const Image& image, const Image& reference) {
  check_pair(image, reference);
  return per_sample(to_srgb8(image), to_srgb8(reference), [](double x, double y) { return (x - y) * (x - y); });
}

void check_variance(const Image& reference, const Image& variance) {
  if (variance.channels() != 3 || variance.width() != reference.width() || variance.height() != reference.height())
    throw InputError(fmt::format("the reference's variance is {}x{} with {} channels: expected {}x{} with 3 "
                                 "(variance.R, variance.G, variance.B)",
                                 variance.width(), variance.height(), variance.channels(), reference.width(),
                                 reference.height()));
  for (std::size_t i = 0; i < variance.size(); ++i) {
    const double v = variance.data()[i];
    if (!(v >= 0) || !std::isfinite(v)) {
      const std::size_t p = i / 3;
      throw InputError(fmt::format("the reference's variance at pixel ({}, {}) channel {} is {}: expected a finite "
                                   "value >= 0",
                                   p % reference.width(), p / reference.width(), "RGB"[i % 3], v));
    }
  }
}

Image unconverged_mask(const Image& reference, const Image& variance, double max_rse) {
  check_variance(reference, variance);
  Image mask(reference.width(), reference.height(), 1);
  for (std::size_t p = 0; p < reference.pixel_count(); ++p) {
    double mean = 0, var = 0;
    for (int c = 0; c < 3; ++c) {
      const double v = variance.data()[3 * p + c];
      mean = std::max(mean, double(reference.data()[3 * p + c]));
      var = std::max(var, v);
    }
    const bool unconverged = mean > 0 ? std::sqrt(var) > max_rse * mean : var > 0;
    mask.data()[p] = unconverged ? 1.0f : 0.0f;
  }
  return mask;
}

double unconverged_share(const Image& reference, const Image& variance, double max_rse) {
  const Image mask = unconverged_mask(reference, variance, max_rse);
  double n = 0;
  for (std::size_t p = 0; p < mask.pixel_count(); ++p) n += mask.data()[p];
  return mask.pixel_count() ? n / double(mask.pixel_count()) : 0.0;
}

MetricResult mse_converged(const Image& image, const Image& reference, const Image* variance) {
  MetricResult r = mse(image, reference);
  if (!variance) {
    r.value = std::numeric_limits<double>::quiet_NaN();
    return r;
  }
  const Image mask = unconverged_mask(reference, *variance);
  double total = 0;
  std::size_t kept = 0;
  for (std::size_t p = 0; p < mask.pixel_count(); ++p) {
    if (mask.data()[p] != 0) {
      r.map.data()[p] = 0;
    } else {
      total += r.map.data()[p];  // the map holds the mean over the 3 channels
      ++kept;
    }
  }
  r.value = kept ? total / double(kept) : std::numeric_limits<double>::quiet_NaN();
  return r;
}

MetricResult mse_hdr_map(const Image& image, const Image& reference) {
  return per_sample(image, reference, [](double x, double y) { return (x - y) * (x - y); });
}
double mse_hdr(const Image& image, const Image& reference) { return mse_hdr_map(image, reference).value; }

MetricResult relmse(const Image& image, const Image& reference) {
  return per_sample(image, reference, [](double x, double y) { return (x - y) * (x - y) / (y * y + 0.01); });
}

namespace {

// A linear-radiance metric less the reference's expected share of it, per sample: `error(x, y)`
// is the metric's own per-sample term, `share(y, v)` the reference's (v its variance of the mean).
template <typename E, typename S>
MetricResult noise_corrected(const Image& image, const Image& reference, const Image* variance, E error, S share) {
  check_pair(image, reference);
  MetricResult r{0, Image(image.width(), image.height(), 1)};
  if (!variance) {
    r.value = std::numeric_limits<double>::quiet_NaN();
    return r;
  }
  check_variance(reference, *variance);
  double total = 0;
  for (std::size_t p = 0; p < image.pixel_count(); ++p) {
    double s = 0;
    for (int c = 0; c < 3; ++c) {
      const std::size_t i = 3 * p + c;
      const double x = image.data()[i], y = reference.data()[i];
      s += error(x, y) - share(y, double(variance->data()[i]));
    }
    r.map.data()[p] = float(s / 3);
    total += s;
  }
  r.value = total / double(image.size());
  return r;
}

// d/dy of the 8-bit display value 255 srgb_encode(clamp(y, 0, 1)): 0 where the clamp holds.
double srgb8_slope(double y) {
  if (!(y > 0) || y >= 1) return y == 0 ? 255 * 12.92 : 0.0;
  return 255 * (y <= 0.0031308 ? 12.92 : 1.055 / 2.4 * std::pow(y, 1.0 / 2.4 - 1.0));
}

}  // namespace

MetricResult mse_hdr_nc(const Image& image, const Image& reference, const Image* variance) {
  return noise_corrected(image, reference, variance, [](double x, double y) { return (x - y) * (x - y); },
                         [](double, double v) { return v; });
}

MetricResult relmse_nc(const Image& image, const Image& reference, const Image* variance) {
  return noise_corrected(image, reference, variance, [](double x, double y) { return (x - y) * (x - y) / (y * y + 0.01); },
                         [](double y, double v) { return v / (y * y + 0.01); });
}

ReferenceError reference_error(const Image& reference, const Image& variance) {
  check_variance(reference, variance);
  ReferenceError e;
  for (std::size_t i = 0; i < reference.size(); ++i) {
    const double y = reference.data()[i], v = variance.data()[i], k = srgb8_slope(y);
    e.mse_hdr += v;
    e.relmse += v / (y * y + 0.01);
    e.mse += k * k * v;
  }
  const double n = double(std::max<std::size_t>(1, reference.size()));
  e.mse_hdr /= n;
  e.relmse /= n;
  e.mse /= n;
  return e;
}

MetricResult psnr(const Image& image, const Image& reference) {
  MetricResult r = mse(image, reference);
  r.value = r.value == 0 ? std::numeric_limits<double>::infinity() : 10.0 * std::log10(255.0 * 255.0 / r.value);
  return r;  // the map stays the per-pixel 8-bit squared error
}

// Wang, Bovik, Sheikh, Simoncelli 2004, with their published settings; the Gaussian windows are
// OpenCV's. As in their reference code only window positions inside the image are averaged
// ('valid'), except for images smaller than the window (then reflected borders).
MetricResult ssim(const Image& image, const Image& reference) {
  check_pair(image, reference);
  const Image a8 = to_srgb8(image), b8 = to_srgb8(reference);
  const double C1 = std::pow(0.01 * 255, 2), C2 = std::pow(0.03 * 255, 2);
  const int w = image.width(), h = image.height(), r = 5;
  const bool valid = w > 2 * r && h > 2 * r;
  MetricResult res{0, Image(w, h, 1)};
  double total = 0;
  std::size_t count = 0;
  for (int c = 0; c < 3; ++c) {
    cv::Mat x = plane(a8, c), y = plane(b8, c), mx, my, sxx, syy, sxy;
    auto blur = [](const cv::Mat& in, cv::Mat& out) { cv::GaussianBlur(in, out, cv::Size(11, 11), 1.5, 1.5, cv::BORDER_REFLECT); };
    blur(x, mx); blur(y, my); blur(x.mul(x), sxx); blur(y.mul(y), syy); blur(x.mul(y), sxy);
    for (int j = 0; j < h; ++j)
      for (int i = 0; i < w; ++i) {
        double ux = mx.at<double>(j, i), uy = my.at<double>(j, i);
        double vx = sxx.at<double>(j, i) - ux * ux, vy = syy.at<double>(j, i) - uy * uy;
        double cxy = sxy.at<double>(j, i) - ux * uy;
        double s = ((2 * ux * uy + C1) * (2 * cxy + C2)) / ((ux * ux + uy * uy + C1) * (vx + vy + C2));
        res.map.at(i, j, 0) += float((1 - s) / 3);
        if (!valid || (i >= r && j >= r && i < w - r && j < h - r)) { total += s; ++count; }
      }
  }
  res.value = total / double(count);
  return res;
}

const std::vector<MetricInfo>& all_metrics() {
  // Metrics that do not use the reference's variance ignore it.
  using Plain = MetricResult (*)(const Image&, const Image&);
  auto plain = [](Plain f) { return [f](const Image& a, const Image& b, const Image*) { return f(a, b); }; };
  static const std::vector<MetricInfo> list = {
      {.name = "mse", .description = "mean squared error of the 8-bit sRGB images (0..255): Table 1's scale",
       .fn = plain(mse), .reference_error = &ReferenceError::mse},
      {.name = "mse_hdr", .description = "mean squared error of the linear radiance", .fn = plain(mse_hdr_map),
       .needs_linear = true, .reference_error = &ReferenceError::mse_hdr},
      {.name = "relmse", .description = "relative MSE, (x - y)^2 / (y^2 + 0.01), linear radiance", .fn = plain(relmse),
       .needs_linear = true, .run_keeps_map = true, .reference_error = &ReferenceError::relmse},
      {.name = "psnr", .description = "peak signal-to-noise ratio of the 8-bit images, dB", .lower_is_better = false,
       .fn = plain(psnr)},
      {.name = "ssim", .description = "structural similarity (Wang et al. 2004) of the 8-bit images",
       .lower_is_better = false, .fn = plain(ssim), .unit_map = true, .map_label = "1 - ssim"},
      {.name = "flip", .description = "mean LDR-FLIP (Andersson et al. 2020), 67 pixels per degree",
       .fn = [](const Image& a, const Image& b, const Image*) { return flip(a, b); }, .run_keeps_map = true,
       .pooled = true, .unit_map = true, .memoises_reference = true},
      {.name = "hdrflip",
       .description = "mean HDR-FLIP (Andersson et al. 2021) of the linear radiance: LDR-FLIP's largest error over "
                      "ACES-tone-mapped exposures, the range from the reference; 67 pixels per degree",
       .fn = [](const Image& a, const Image& b, const Image*) { return hdrflip(a, b); }, .needs_linear = true,
       .run_keeps_map = true, .pooled = true, .unit_map = true, .memoises_reference = true},
      {.name = "mse_hdr_nc",
       .description = "mse_hdr less the reference's own expected share, the mean of its variance of the mean "
                      "(noise-corrected; can fall below 0 for a method closer to the truth than the reference's "
                      "noise); n/a without the variance",
       .fn = mse_hdr_nc, .needs_linear = true, .needs_reference_variance = true},
      {.name = "relmse_nc",
       .description = "relmse less the reference's own expected share, variance / (y^2 + 0.01) (noise-corrected, "
                      "first order); n/a without the variance",
       .fn = relmse_nc, .needs_linear = true, .needs_reference_variance = true},
      {.name = "mse_converged",
       .description = "8-bit mse over the pixels whose reference has converged (relative standard error at most 1/2: "
                      "more than about 4 samples carry the pixel); n/a without the reference's variance",
       .fn = mse_converged, .needs_reference_variance = true, .masks_unconverged = true},
  };
  return list;
}

std::vector<std::string> metric_names() {
  std::vector<std::string> n;
  for (const auto& m : all_metrics()) n.push_back(m.name);
  return n;
}

const MetricInfo* find_metric(const std::string& name) {
  for (const auto& m : all_metrics())
    if (m.name == name) return &m;
  return nullptr;
}

std::map<std::string, double> reference_error_by_metric(const ReferenceError& e) {
  std::map<std::string, double> out;
  for (const auto& m : all_metrics())
    if (m.reference_error) out[m.name] = e.*m.reference_error;
  return out;
}

const MetricInfo& metric(const std::string& name) {
  if (const MetricInfo* m = find_metric(name)) return *m;
  std::string valid;
  for (const auto& n : metric_names()) valid += (valid.empty() ? "" : ", ") + n;
  throw InputError(fmt::format("unknown metric '{}': valid metrics are {}", name, valid));
}

WorseBlocks worse_blocks(const Image& image, const Image& baseline, const Image& reference, int block) {
  check_pair(image, reference);
  check_pair(baseline, reference, "baseline");
  if (block < 1) throw InputError(fmt::format("worse_blocks: block size {} is not positive", block));
  const Image a = to_srgb8(image), b = to_srgb8(baseline), r = to_srgb8(reference);
  const int w = image.width(), h = image.height();
  WorseBlocks out;
  out.block = block;
  int twice = 0;
  for (int y0 = 0; y0 < h; y0 += block)
    for (int x0 = 0; x0 < w; x0 += block) {
      double ea = 0, eb = 0;
      for (int y = y0; y < std::min(h, y0 + block); ++y)
        for (int x = x0; x < std::min(w, x0 + block); ++x)
          for (int c = 0; c < 3; ++c) {
            const double da = a.at(x, y, c) - r.at(x, y, c), db = b.at(x, y, c) - r.at(x, y, c);
            ea += da * da;
            eb += db * db;
          }
      ++out.count;
      twice += ea > 2 * eb;  // the same pixel count on both sides: sums compare as means
      if (ea > eb)
        out.tiles.push_back({x0, y0, std::min(block, w - x0), std::min(block, h - y0),
                             eb > 0 ? std::min(ea / eb, WorseBlocks::kMaxRatio) : WorseBlocks::kMaxRatio});
    }
  out.worse = double(out.tiles.size()) / out.count;  // every worse tile, before the list is cut
  // Worst first; ties in reading order (stable), so the list is the same on every machine.
  std::stable_sort(out.tiles.begin(), out.tiles.end(), [](const auto& p, const auto& q) { return p.ratio > q.ratio; });
  if (out.tiles.size() > WorseBlocks::kMaxTiles) out.tiles.resize(WorseBlocks::kMaxTiles);
  out.worse_twice = double(twice) / out.count;
  return out;
}

}  // namespace dnb::metrics
