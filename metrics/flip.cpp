// FLIP, NVIDIA's perceptual error metric: LDR-FLIP (`flip`), HDR-FLIP (`hdrflip`) and the pooled
// statistics of FLIP's tool (metrics.h documents each).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <tuple>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"
#include "metrics/metrics.h"

namespace dnb::metrics {

// ---------------------------------------------------------------------------------------------
// LDR-FLIP (Andersson, Nilsson, Akenine-Moller, Oskarsson, Astrom, Fairchild: "FLIP: A Difference
// Evaluator for Alternating Images", HPG 2020). Written here from the paper because no Debian
// package provides it (NVIDIA's reference code is not packaged). Constants are the paper's:
// CSFs in YCxCz, Hunt-adjusted HyAB colour distance with qc = 0.7, pc = 0.4, pt = 0.95, edge and
// point detectors (w = 0.082 degrees) on the normalised achromatic channel with qf = 0.5.
namespace {

struct Vec3 { double x, y, z; };

// Linear sRGB <-> CIE XYZ (D65).
Vec3 rgb_to_xyz(Vec3 c) {
  return {0.4124564 * c.x + 0.3575761 * c.y + 0.1804375 * c.z, 0.2126729 * c.x + 0.7151522 * c.y + 0.0721750 * c.z,
          0.0193339 * c.x + 0.1191920 * c.y + 0.9503041 * c.z};
}
Vec3 xyz_to_rgb(Vec3 c) {
  return {3.2404542 * c.x - 1.5371385 * c.y - 0.4985314 * c.z, -0.9692660 * c.x + 1.8760108 * c.y + 0.0415560 * c.z,
          0.0556434 * c.x - 0.2040259 * c.y + 1.0572252 * c.z};
}
const Vec3 kWhite = rgb_to_xyz({1, 1, 1});

Vec3 xyz_to_ycxcz(Vec3 c) {
  double x = c.x / kWhite.x, y = c.y / kWhite.y, z = c.z / kWhite.z;
  return {116 * y - 16, 500 * (x - y), 200 * (y - z)};
}
Vec3 ycxcz_to_xyz(Vec3 c) {
  double y = (c.x + 16) / 116, x = y + c.y / 500, z = y - c.z / 200;
  return {x * kWhite.x, y * kWhite.y, z * kWhite.z};
}
Vec3 xyz_to_lab(Vec3 c) {
  auto f = [](double t) { const double d = 6.0 / 29; return t > d * d * d ? std::cbrt(t) : t / (3 * d * d) + 4.0 / 29; };
  double fx = f(c.x / kWhite.x), fy = f(c.y / kWhite.y), fz = f(c.z / kWhite.z);
  return {116 * fy - 16, 500 * (fx - fy), 200 * (fy - fz)};
}
// Hunt-adjusted Lab: chroma scaled by 0.01 L.
Vec3 hunt(Vec3 lab) { return {lab.x, 0.01 * lab.x * lab.y, 0.01 * lab.x * lab.z}; }
double hyab(Vec3 a, Vec3 b) { return std::abs(a.x - b.x) + std::hypot(a.y - b.y, a.z - b.z); }

// The contrast sensitivity functions as spatial kernels (paper section 4.1, Table 1 constants):
// g(x) = a1 sqrt(pi/b1) exp(-pi^2 x^2 / b1) + a2 sqrt(pi/b2) exp(-pi^2 x^2 / b2), x in degrees,
// sampled on a (2 radius + 1)^2 grid and normalised to sum 1. Each term is a 2-D Gaussian, the
// product of two 1-D ones, so the 2-D kernel is applied as a weighted sum of separable filters
// (2 x 21 taps a pixel instead of 21 x 21 at 67 pixels per degree): the same kernel, so the same
// filter up to rounding.
struct SeparableTerm { cv::Mat taps; double weight; };  // taps sum to 1; the 2-D term is weight * taps x taps^T

std::vector<SeparableTerm> csf_terms(double a1, double b1, double a2, double b2, double ppd, int radius) {
  const double pi2 = M_PI * M_PI;
  std::vector<SeparableTerm> terms;
  double total = 0;
  for (auto [a, b] : {std::pair{a1, b1}, std::pair{a2, b2}}) {
    if (a == 0) continue;
    cv::Mat t(2 * radius + 1, 1, CV_64F);
    double sum = 0;
    for (int i = -radius; i <= radius; ++i) sum += t.at<double>(i + radius) = std::exp(-pi2 * (i * i) / (ppd * ppd) / b);
    // This term's share of the 2-D kernel's sum: a sqrt(pi/b) times the sum of its 2-D taps, sum^2.
    const double mass = a * std::sqrt(M_PI / b) * sum * sum;
    cv::Mat taps;
    cv::Mat(t / sum).convertTo(taps, CV_32F);  // the images are filtered in float, as FLIP's own code does
    terms.push_back({taps, mass});
    total += mass;
  }
  for (auto& t : terms) t.weight /= total;
  return terms;
}

// Edge (first derivative of a Gaussian) and point (second derivative) detectors, x direction;
// positive and negative weights normalised to sum to +1 and -1 (paper section 4.2). Both are a
// 1-D profile in x times a Gaussian in y, and a weight's sign depends on x alone, so the
// normalised 2-D kernel is the x profile normalised by sign (`edge`, `point`) times the y Gaussian
// normalised to 1 (`along`); the y-direction detectors are the same kernels with x and y swapped.
struct FeatureKernels { cv::Mat edge, point, along; };

FeatureKernels feature_kernels(double ppd) {
  const double sd = 0.5 * 0.082 * ppd;
  const int r = int(std::ceil(3 * sd));
  FeatureKernels k;
  k.edge.create(2 * r + 1, 1, CV_64F);
  k.point.create(2 * r + 1, 1, CV_64F);
  k.along.create(2 * r + 1, 1, CV_64F);
  double ep = 0, en = 0, pp = 0, pn = 0, g_sum = 0;
  for (int x = -r; x <= r; ++x) {
    const double g = std::exp(-(x * x) / (2 * sd * sd));
    const double e = -x * g, p = (x * x / (sd * sd) - 1) * g;
    k.edge.at<double>(x + r) = e;
    k.point.at<double>(x + r) = p;
    k.along.at<double>(x + r) = g;
    (e > 0 ? ep : en) += e;
    (p > 0 ? pp : pn) += p;
    g_sum += g;
  }
  for (auto [m, pos, neg] : {std::tuple{&k.edge, ep, en}, std::tuple{&k.point, pp, pn}})
    for (auto it = m->begin<double>(); it != m->end<double>(); ++it) *it = *it > 0 ? *it / pos : *it / -neg;
  k.along /= g_sum;
  for (cv::Mat* m : {&k.edge, &k.point, &k.along}) m->convertTo(*m, CV_32F);  // applied in float, as FLIP's code does
  return k;
}

// Correlation with the separable kernel kx (along rows) x ky (along columns), edges replicated,
// as filter2D with the full kernel computes it.
cv::Mat filtered(const cv::Mat& in, const cv::Mat& kx, const cv::Mat& ky) {
  cv::Mat out;
  cv::sepFilter2D(in, out, CV_32F, kx, ky, cv::Point(-1, -1), 0, cv::BORDER_REPLICATE);
  return out;
}

cv::Mat filtered(const cv::Mat& in, const std::vector<SeparableTerm>& terms) {
  cv::Mat out;
  for (const auto& t : terms) {
    cv::Mat f = filtered(in, t.taps, t.taps);
    if (out.empty()) out = t.weight * f;
    else cv::scaleAdd(f, t.weight, out, out);
  }
  return out;
}

// Rows [0, h) of an image, in parallel: every pixel is computed alone, so the result is the same
// whatever the thread count.
template <typename Row>
void for_rows(int h, Row row) {
  tbb::parallel_for(tbb::blocked_range<int>(0, h, 16), [&](const tbb::blocked_range<int>& r) {
    for (int y = r.begin(); y < r.end(); ++y) row(y);
  });
}

// LDR-FLIP in three named steps, so that HDR-FLIP runs the same code on each exposure:
// the filters for a viewing distance, each image in FLIP's working spaces, the per-pixel error.
// Every step works on linear RGB in [0, 1]; `to_linear` says how a pixel of the input gets there.
struct FlipFilters {
  std::vector<SeparableTerm> csf[3];  // Y, Cx, Cz contrast sensitivity (section 4.1)
  FeatureKernels feature;             // edge and point detectors (section 4.2)

  explicit FlipFilters(double ppd) : feature(feature_kernels(ppd)) {
    const double bmax = 0.04;  // the widest CSF term (blue-yellow b1)
    const int radius = int(std::ceil(3 * std::sqrt(bmax / (2 * M_PI * M_PI)) * ppd));
    csf[0] = csf_terms(1, 0.0047, 0, 1e-5, ppd, radius);
    csf[1] = csf_terms(1, 0.0053, 0, 1e-5, ppd, radius);
    csf[2] = csf_terms(34.1, 0.04, 13.5, 0.025, ppd, radius);
  }
};

// One image as the error needs it: the CSF-filtered image in Hunt-adjusted Lab, and the edge and
// point magnitudes of its normalised achromatic channel.
struct Prepared { cv::Mat lab[3]; cv::Mat edge_mag, point_mag; };

template <typename ToLinear>
Prepared prepare(const Image& im, const FlipFilters& k, ToLinear to_linear) {
  const int w = im.width(), h = im.height();
  cv::Mat ycc[3];
  for (auto& m : ycc) m.create(h, w, CV_32F);
  for_rows(h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      Vec3 v = xyz_to_ycxcz(rgb_to_xyz(to_linear(im.pixel(x, y))));
      ycc[0].at<float>(y, x) = float(v.x); ycc[1].at<float>(y, x) = float(v.y); ycc[2].at<float>(y, x) = float(v.z);
    }
  });
  Prepared out;
  cv::Mat f[3];
  for (int c = 0; c < 3; ++c) f[c] = filtered(ycc[c], k.csf[c]);
  for (auto& m : out.lab) m.create(h, w, CV_32F);
  for_rows(h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      Vec3 rgb = xyz_to_rgb(ycxcz_to_xyz({f[0].at<float>(y, x), f[1].at<float>(y, x), f[2].at<float>(y, x)}));
      rgb = {std::clamp(rgb.x, 0.0, 1.0), std::clamp(rgb.y, 0.0, 1.0), std::clamp(rgb.z, 0.0, 1.0)};
      Vec3 lab = hunt(xyz_to_lab(rgb_to_xyz(rgb)));
      out.lab[0].at<float>(y, x) = float(lab.x); out.lab[1].at<float>(y, x) = float(lab.y);
      out.lab[2].at<float>(y, x) = float(lab.z);
    }
  });
  cv::Mat yn = (ycc[0] + 16) / 116;  // achromatic channel normalised to [0, 1]
  const FeatureKernels& fk = k.feature;
  cv::Mat ex = filtered(yn, fk.edge, fk.along), ey = filtered(yn, fk.along, fk.edge);
  cv::Mat px = filtered(yn, fk.point, fk.along), py = filtered(yn, fk.along, fk.point);
  cv::magnitude(ex, ey, out.edge_mag);
  cv::magnitude(px, py, out.point_mag);
  return out;
}

// The per-pixel LDR-FLIP error in [0, 1] (CV_64F): the colour error raised to 1 minus the feature
// error (section 4.3).
cv::Mat flip_error(const Prepared& a, const Prepared& b) {
  const double qc = 0.7, pc = 0.4, pt = 0.95;  // and qf = 0.5
  const double cmax = std::pow(hyab(hunt(xyz_to_lab(rgb_to_xyz({0, 1, 0}))), hunt(xyz_to_lab(rgb_to_xyz({0, 0, 1})))), qc);
  const int w = a.edge_mag.cols, h = a.edge_mag.rows;
  cv::Mat err(h, w, CV_64F);
  for_rows(h, [&](int y) {
    for (int x = 0; x < w; ++x) {
      Vec3 la{a.lab[0].at<float>(y, x), a.lab[1].at<float>(y, x), a.lab[2].at<float>(y, x)};
      Vec3 lb{b.lab[0].at<float>(y, x), b.lab[1].at<float>(y, x), b.lab[2].at<float>(y, x)};
      double dc = std::pow(hyab(la, lb), qc);
      double ec = dc < pc * cmax ? pt / (pc * cmax) * dc : pt + (dc - pc * cmax) / (cmax - pc * cmax) * (1 - pt);
      double df = std::max(std::abs(double(a.edge_mag.at<float>(y, x)) - b.edge_mag.at<float>(y, x)),
                           std::abs(double(a.point_mag.at<float>(y, x)) - b.point_mag.at<float>(y, x)));
      double ef = std::sqrt(df / std::sqrt(2.0));  // pow(., qf) with qf = 1/2
      err.at<double>(y, x) = std::pow(ec, 1 - ef);
    }
  });
  return err;
}

// The reference's prepared images, kept between calls. A run scores every cell of a scene, and
// `metrics` every image it is given, against one reference, and preparing the reference is half of
// FLIP's work (ten times per image for HDR-FLIP's exposures), so it is done once per reference and
// exposure. The memo holds the last reference seen, compared by content (not by address: a caller
// may free one reference and allocate another in its place), and is safe to use from threads.
class ReferenceMemo {
 public:
  // Makes `reference` the memo's reference (compared once per call of flip or hdrflip, not per
  // exposure) and returns its generation, for `get`.
  std::uint64_t adopt(const Image& reference) {
    const std::lock_guard lock(mutex_);
    if (!same(reference)) {
      reference_ = reference;
      prepared_.clear();
      ++generation_;
    }
    return generation_;
  }
  // The reference of `generation` prepared for `kind` (0: LDR-FLIP's display transform; 1:
  // HDR-FLIP at `exposure`): kept, or made now and kept while that reference is the memo's.
  template <typename Make>
  std::shared_ptr<const Prepared> get(std::uint64_t generation, double ppd, int kind, double exposure, Make make) {
    const Key key{ppd, kind, exposure};
    {
      const std::lock_guard lock(mutex_);
      if (generation == generation_)
        if (auto it = prepared_.find(key); it != prepared_.end()) return it->second;
    }
    auto made = std::make_shared<const Prepared>(make());  // outside the lock: exposures run in parallel
    const std::lock_guard lock(mutex_);
    if (generation == generation_) prepared_.emplace(key, made);
    return made;
  }

 private:
  using Key = std::tuple<double, int, double>;
  bool same(const Image& r) const {
    return r.width() == reference_.width() && r.height() == reference_.height() && r.channels() == reference_.channels() &&
           std::memcmp(r.data(), reference_.data(), r.size() * sizeof(float)) == 0;
  }
  std::mutex mutex_;
  Image reference_;
  std::uint64_t generation_ = 0;
  std::map<Key, std::shared_ptr<const Prepared>> prepared_;
};

ReferenceMemo& reference_memo() {
  static ReferenceMemo memo;
  return memo;
}

// The map as a 1-channel image and its mean.
MetricResult mean_of(const cv::Mat& err) {
  const int w = err.cols, h = err.rows;
  MetricResult r{0, Image(w, h, 1)};
  double total = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const double e = err.at<double>(y, x);
      r.map.at(x, y, 0) = float(e);
      total += e;
    }
  r.value = total / (double(w) * h);
  return r;
}

}  // namespace

MetricResult flip(const Image& image, const Image& reference, double ppd) {
  check_pair(image, reference);
  // LDR input: the same display transform as the 8-bit metrics, back to linear for FLIP.
  auto display = [](const float* p) {
    return Vec3{srgb_decode(srgb_encode(p[0])), srgb_decode(srgb_encode(p[1])), srgb_decode(srgb_encode(p[2]))};
  };
  const FlipFilters filters(ppd);
  const std::uint64_t generation = reference_memo().adopt(reference);
  const auto ref = reference_memo().get(generation, ppd, 0, 0.0, [&] { return prepare(reference, filters, display); });
  return mean_of(flip_error(prepare(image, filters, display), *ref));
}

// ---------------------------------------------------------------------------------------------
// HDR-FLIP (Andersson, Nilsson, Shirley, Akenine-Moller, Eurographics 2021 short paper). Constants
// and the exposure range as NVIDIA's FLIP tool has them (checked against flip-evaluator 1.7 in
// tests/metrics/flip_reference_test.cpp).
namespace {

// The tone curve, y(x) = (k0 x^2 + k1 x + k2) / (k3 x^2 + k4 x + k5), ACES with 0.6 pre-exposure.
constexpr double kAces[6] = {0.6 * 0.6 * 2.51, 0.6 * 0.03, 0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14};
double aces(double x) {
  return (kAces[0] * x * x + kAces[1] * x + kAces[2]) / (kAces[3] * x * x + kAces[4] * x + kAces[5]);
}

// The radiance the curve maps to t, the positive root of (k0 - t k3) x^2 + (k1 - t k4) x + (k2 - t k5) = 0
// (section 3: the curve rises from y(0) = 0, so the other root is negative).
double aces_inverse(double t) {
  const double a = kAces[0] - t * kAces[3], b = kAces[1] - t * kAces[4], c = kAces[2] - t * kAces[5];
  return (-b + std::sqrt(b * b - 4 * a * c)) / (2 * a);
}

// The tone-mapped value the exposure range aims the brightest (start) and median (stop) pixel at.
constexpr double kExposureTarget = 0.85;

}  // namespace

HdrFlipExposures hdrflip_exposures(const Image& reference) {
  check_pair(reference, reference, "reference", "reference");
  std::vector<double> lum(reference.pixel_count());
  for (std::size_t p = 0; p < lum.size(); ++p) {
    const float* c = reference.data() + 3 * p;
    lum[p] = 0.2126 * std::max(0.0f, c[0]) + 0.7152 * std::max(0.0f, c[1]) + 0.0722 * std::max(0.0f, c[2]);
  }
  HdrFlipExposures ex;
  if (lum.empty()) return ex;
  ex.luminance_max = *std::max_element(lum.begin(), lum.end());
  if (ex.luminance_max <= 0) return ex;  // all black: one exposure is as good as another
  auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  ex.luminance_median = median(lum);
  if (ex.luminance_median <= 0) {  // most of the reference black: the median of what is lit
    lum.erase(std::remove_if(lum.begin(), lum.end(), [](double y) { return y <= 0; }), lum.end());
    ex.luminance_median = median(lum);
  }
  const double x_max = aces_inverse(kExposureTarget);
  ex.start = std::log2(x_max / ex.luminance_max);
  ex.stop = std::log2(x_max / ex.luminance_median);
  ex.count = int(std::max(2.0, std::ceil(ex.stop - ex.start)));
  return ex;
}

Image hdrflip_tone_map(const Image& linear, double exposure) {
  const double scale = std::exp2(exposure);
  Image out(linear.width(), linear.height(), linear.channels());
  for (std::size_t i = 0; i < linear.size(); ++i)
    out.data()[i] = float(std::clamp(aces(scale * std::max(0.0, double(linear.data()[i]))), 0.0, 1.0));
  return out;
}

MetricResult hdrflip(const Image& image, const Image& reference, double ppd) {
  check_pair(image, reference);
  const HdrFlipExposures ex = hdrflip_exposures(reference);
  const FlipFilters filters(ppd);
  // The tone-mapped images are already linear in [0, 1]: LDR-FLIP takes them as they are.
  auto as_is = [](const float* p) { return Vec3{p[0], p[1], p[2]}; };
  // The exposures in parallel: the per-pixel maximum is exact and does not depend on the order
  // in which the exposures' maps arrive.
  cv::Mat worst(image.height(), image.width(), CV_64F, cv::Scalar(0));
  std::mutex worst_mutex;
  const std::uint64_t generation = reference_memo().adopt(reference);
  tbb::parallel_for(0, ex.count, [&](int i) {
    const double c = ex.exposure(i);
    const auto ref = reference_memo().get(generation, ppd, 1, c,
                                          [&] { return prepare(hdrflip_tone_map(reference, c), filters, as_is); });
    const cv::Mat err = flip_error(prepare(hdrflip_tone_map(image, c), filters, as_is), *ref);
    const std::lock_guard lock(worst_mutex);
    worst = cv::max(worst, err);
  });
  return mean_of(worst);
}

// ---------------------------------------------------------------------------------------------
// FLIP's pooled statistics (its tool's pooling.h, getPercentile with weights).
FlipPooled pool_flip(const Image& map) {
  if (map.channels() != 1 || map.empty())
    throw InputError(fmt::format("pool_flip needs a non-empty 1-channel error map, not {}x{} with {} channels",
                                 map.width(), map.height(), map.channels()));
  std::vector<double> v(map.data(), map.data() + map.size());
  for (std::size_t i = 0; i < v.size(); ++i)
    if (!std::isfinite(v[i]))
      throw InputError(fmt::format("the error map has a non-finite value at pixel ({}, {})", i % map.width(),
                                   i / map.width()));
  std::sort(v.begin(), v.end());
  double total = 0;
  for (double e : v) total += e;
  auto weighted = [&](double p) {
    double running = 0;
    for (double e : v)
      if ((running += e) > p * total) return e;
    return 0.0;  // no error at all
  };
  FlipPooled r;
  r.mean = total / double(v.size());
  r.weighted_median = weighted(0.5);
  r.weighted_first_quartile = weighted(0.25);
  r.weighted_third_quartile = weighted(0.75);
  r.min = v.front();
  r.max = v.back();
  return r;
}

}  // namespace dnb::metrics
