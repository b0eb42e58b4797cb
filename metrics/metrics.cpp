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

Image unconverged_mask(const Image& reference, const Image& variance, double max_rse) {
  if (variance.channels() != 3 || variance.width() != reference.width() || variance.height() != reference.height())
    throw InputError(fmt::format("the reference's variance is {}x{} with {} channels: expected {}x{} with 3 "
                                 "(variance.R, variance.G, variance.B)",
                                 variance.width(), variance.height(), variance.channels(), reference.width(),
                                 reference.height()));
  Image mask(reference.width(), reference.height(), 1);
  for (std::size_t p = 0; p < reference.pixel_count(); ++p) {
    double mean = 0, var = 0;
    for (int c = 0; c < 3; ++c) {
      const double v = variance.data()[3 * p + c];
      if (!(v >= 0) || !std::isfinite(v)) {
        throw InputError(fmt::format("the reference's variance at pixel ({}, {}) channel {} is {}: expected a finite "
                                     "value >= 0",
                                     p % reference.width(), p / reference.width(), "RGB"[c], v));
      }
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
// g(x) = a1 sqrt(pi/b1) exp(-pi^2 x^2 / b1) + a2 sqrt(pi/b2) exp(-pi^2 x^2 / b2), x in degrees.
cv::Mat csf_kernel(double a1, double b1, double a2, double b2, double ppd, int radius) {
  cv::Mat k(2 * radius + 1, 2 * radius + 1, CV_64F);
  const double pi2 = M_PI * M_PI;
  double sum = 0;
  for (int j = -radius; j <= radius; ++j)
    for (int i = -radius; i <= radius; ++i) {
      double d2 = (i * i + j * j) / (ppd * ppd);
      double g = a1 * std::sqrt(M_PI / b1) * std::exp(-pi2 * d2 / b1) + a2 * std::sqrt(M_PI / b2) * std::exp(-pi2 * d2 / b2);
      k.at<double>(j + radius, i + radius) = g;
      sum += g;
    }
  return k / sum;
}

// Edge (first derivative of a Gaussian) and point (second derivative) detectors, x direction;
// positive and negative weights normalised to sum to +1 and -1 (paper section 4.2).
void feature_kernels(double ppd, cv::Mat& edge, cv::Mat& point) {
  const double sd = 0.5 * 0.082 * ppd;
  const int r = int(std::ceil(3 * sd));
  edge.create(2 * r + 1, 2 * r + 1, CV_64F);
  point.create(2 * r + 1, 2 * r + 1, CV_64F);
  double ep = 0, en = 0, pp = 0, pn = 0;
  for (int y = -r; y <= r; ++y)
    for (int x = -r; x <= r; ++x) {
      double g = std::exp(-(x * x + y * y) / (2 * sd * sd));
      double e = -x * g, p = (x * x / (sd * sd) - 1) * g;
      edge.at<double>(y + r, x + r) = e;
      point.at<double>(y + r, x + r) = p;
      (e > 0 ? ep : en) += e;
      (p > 0 ? pp : pn) += p;
    }
  for (auto [k, pos, neg] : {std::tuple{&edge, ep, en}, std::tuple{&point, pp, pn}})
    for (auto it = k->begin<double>(); it != k->end<double>(); ++it) *it = *it > 0 ? *it / pos : *it / -neg;
}

cv::Mat filtered(const cv::Mat& in, const cv::Mat& kernel) {
  cv::Mat out;
  cv::filter2D(in, out, CV_64F, kernel, cv::Point(-1, -1), 0, cv::BORDER_REPLICATE);
  return out;
}

}  // namespace

MetricResult flip(const Image& image, const Image& reference, double ppd) {
  check_pair(image, reference);
  const int w = image.width(), h = image.height();
  const double qc = 0.7, qf = 0.5, pc = 0.4, pt = 0.95;

  const double bmax = 0.04;  // the widest CSF term (blue-yellow b1)
  const int radius = int(std::ceil(3 * std::sqrt(bmax / (2 * M_PI * M_PI)) * ppd));
  const cv::Mat csf[3] = {csf_kernel(1, 0.0047, 0, 1e-5, ppd, radius), csf_kernel(1, 0.0053, 0, 1e-5, ppd, radius),
                          csf_kernel(34.1, 0.04, 13.5, 0.025, ppd, radius)};
  cv::Mat edge, point;
  feature_kernels(ppd, edge, point);
  const cv::Mat edge_t = edge.t(), point_t = point.t();

  struct Prepared { cv::Mat lab[3]; cv::Mat edge_mag, point_mag; };
  auto prepare = [&](const Image& im) {
    // LDR input: the same display transform as the 8-bit metrics, back to linear for FLIP.
    cv::Mat ycc[3];
    for (auto& m : ycc) m.create(h, w, CV_64F);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const float* p = im.pixel(x, y);
        Vec3 lin{srgb_decode(srgb_encode(p[0])), srgb_decode(srgb_encode(p[1])), srgb_decode(srgb_encode(p[2]))};
        Vec3 v = xyz_to_ycxcz(rgb_to_xyz(lin));
        ycc[0].at<double>(y, x) = v.x; ycc[1].at<double>(y, x) = v.y; ycc[2].at<double>(y, x) = v.z;
      }
    Prepared out;
    cv::Mat f[3];
    for (int c = 0; c < 3; ++c) f[c] = filtered(ycc[c], csf[c]);
    for (auto& m : out.lab) m.create(h, w, CV_64F);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        Vec3 rgb = xyz_to_rgb(ycxcz_to_xyz({f[0].at<double>(y, x), f[1].at<double>(y, x), f[2].at<double>(y, x)}));
        rgb = {std::clamp(rgb.x, 0.0, 1.0), std::clamp(rgb.y, 0.0, 1.0), std::clamp(rgb.z, 0.0, 1.0)};
        Vec3 lab = hunt(xyz_to_lab(rgb_to_xyz(rgb)));
        out.lab[0].at<double>(y, x) = lab.x; out.lab[1].at<double>(y, x) = lab.y; out.lab[2].at<double>(y, x) = lab.z;
      }
    cv::Mat yn = (ycc[0] + 16) / 116;  // achromatic channel normalised to [0, 1]
    cv::Mat ex = filtered(yn, edge), ey = filtered(yn, edge_t), px = filtered(yn, point), py = filtered(yn, point_t);
    cv::magnitude(ex, ey, out.edge_mag);
    cv::magnitude(px, py, out.point_mag);
    return out;
  };
  const Prepared a = prepare(image), b = prepare(reference);

  const double cmax = std::pow(hyab(hunt(xyz_to_lab(rgb_to_xyz({0, 1, 0}))), hunt(xyz_to_lab(rgb_to_xyz({0, 0, 1})))), qc);
  MetricResult r{0, Image(w, h, 1)};
  double total = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      Vec3 la{a.lab[0].at<double>(y, x), a.lab[1].at<double>(y, x), a.lab[2].at<double>(y, x)};
      Vec3 lb{b.lab[0].at<double>(y, x), b.lab[1].at<double>(y, x), b.lab[2].at<double>(y, x)};
      double dc = std::pow(hyab(la, lb), qc);
      double ec = dc < pc * cmax ? pt / (pc * cmax) * dc : pt + (dc - pc * cmax) / (cmax - pc * cmax) * (1 - pt);
      double df = std::max(std::abs(a.edge_mag.at<double>(y, x) - b.edge_mag.at<double>(y, x)),
                           std::abs(a.point_mag.at<double>(y, x) - b.point_mag.at<double>(y, x)));
      double ef = std::pow(df / std::sqrt(2.0), qf);
      double e = std::pow(ec, 1 - ef);
      r.map.at(x, y, 0) = float(e);
      total += e;
    }
  r.value = total / (double(w) * h);
  return r;
}

const std::vector<MetricInfo>& all_metrics() {
  // Metrics that do not use the reference's variance ignore it.
  using Plain = MetricResult (*)(const Image&, const Image&);
  auto plain = [](Plain f) { return [f](const Image& a, const Image& b, const Image*) { return f(a, b); }; };
  static const std::vector<MetricInfo> list = {
      {"mse", "mean squared error of the 8-bit sRGB images (0..255): Table 1's scale", true, plain(mse)},
      {"mse_hdr", "mean squared error of the linear radiance", true, plain(mse_hdr_map), true},
      {"relmse", "relative MSE, (x - y)^2 / (y^2 + 0.01), linear radiance", true, plain(relmse), true},
      {"psnr", "peak signal-to-noise ratio of the 8-bit images, dB", false, plain(psnr)},
      {"ssim", "structural similarity (Wang et al. 2004) of the 8-bit images", false, plain(ssim)},
      {"flip", "mean LDR-FLIP (Andersson et al. 2020), 67 pixels per degree", true,
       [](const Image& a, const Image& b, const Image*) { return flip(a, b); }},
      {"mse_converged",
       "8-bit mse over the pixels whose reference has converged (relative standard error at most 1/2: "
       "more than about 4 samples carry the pixel); n/a without the reference's variance",
       true, mse_converged},
  };
  return list;
}

std::vector<std::string> metric_names() {
  std::vector<std::string> n;
  for (const auto& m : all_metrics()) n.push_back(m.name);
  return n;
}

const MetricInfo& metric(const std::string& name) {
  for (const auto& m : all_metrics())
    if (m.name == name) return m;
  std::string valid;
  for (const auto& n : metric_names()) valid += (valid.empty() ? "" : ", ") + n;
  throw InputError(fmt::format("unknown metric '{}': valid metrics are {}", name, valid));
}

}  // namespace dnb::metrics
