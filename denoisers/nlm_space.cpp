#include "denoisers/nlm_space.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>

#include <opencv2/core.hpp>
#include <opencv2/core/hal/hal.hpp>
#include <opencv2/imgproc.hpp>
#include <tbb/parallel_for.h>

#include "core/errors.h"

namespace dnb {
namespace {

float mean_luminance(const Image& img) {
  // Row sums in parallel, added in row order: the same double whatever the thread count.
  std::vector<double> rows(std::size_t(img.height()), 0.0);
  tbb::parallel_for(0, img.height(), [&](int y) {
    double s = 0;
    const float* p = img.pixel(0, y);
    for (int x = 0; x < img.width(); ++x) s += std::max(0.0f, luminance(p + std::size_t(x) * 3));
    rows[std::size_t(y)] = s;
  });
  double s = 0;
  for (double r : rows) s += r;
  const double m = s / double(std::max<std::size_t>(img.pixel_count(), 1));
  return m > 1e-12 ? float(m) : 1.0f;  // a black image: any scale
}

}  // namespace

// log(1 + x) through OpenCV's vectorised log32f, for whole rows (libm's log1pf, one pixel at a
// time, was a tenth of nlm_space's time), and through the same function for single values, so
// that compress() of a pixel equals its entry in the compressed image (log32f's vector and
// scalar paths agree bit for bit; checked on 4M values). Next to log1p it loses relative
// precision only for x below about 1e-4, where the absolute error (1e-7) is far under any sigma.
namespace {
// The argument of compress()'s log: 1 + max(0, lum) / m.
float log_argument(const float* rgb, float m) { return 1.0f + std::max(0.0f, luminance(rgb)) / m; }
}  // namespace

float NlmSpace::compress(const float* rgb) const {
  const float x = log_argument(rgb, mean_luminance);
  float y;
  cv::hal::log32f(&x, &y, 1);
  return y;
}

void NlmSpace::vector_with_center(const Image& illumination, int x, int y, const float* rgb, float* out) const {
  vectors_with_centers(illumination, x, y, rgb, 1, out, vectors.channels());
}

void NlmSpace::vectors_with_centers(const Image& illumination, int x, int y, const float* rgb, int n, float* out,
                                    int stride) const {
  constexpr int kBatch = 32;
  float ys[kBatch + 1];
  const float* v = vectors.pixel(x, y);
  for (int first = 0; first < n; first += kBatch) {
    const int m = std::min(kBatch, n - first);
    // The pixel's own value first, then the batch: one log32f call, as compress() computes each.
    ys[0] = log_argument(illumination.pixel(x, y), mean_luminance);
    for (int i = 0; i < m; ++i) ys[1 + i] = log_argument(rgb + 3 * (first + i), mean_luminance);
    cv::hal::log32f(ys, ys, m + 1);
    for (int i = 0; i < m; ++i) {
      const float delta = ys[1 + i] - ys[0];
      float* o = out + std::size_t(first + i) * stride;
      for (int k = 0; k < vectors.channels(); ++k) o[k] = v[k] + center[k] * delta;
    }
  }
}

float illumination_scale(const Image& illumination) { return mean_luminance(illumination); }

std::uint64_t nlm_sample_seed(ConstImageView img) {
  std::uint64_t h = 1469598103934665603ull;
  const std::size_t ch = std::size_t(img.channels), n = std::size_t(img.width) * img.height * ch;
  for (std::size_t k = 0; k < n; k += 53) {
    const std::size_t px = k / ch;
    std::uint32_t bits;
    std::memcpy(&bits, img.pixel(int(px % std::size_t(img.width)), int(px / std::size_t(img.width))) + k % ch, 4);
    h = (h ^ bits) * 1099511628211ull;
  }
  return h ^ (std::uint64_t(img.width) << 32 | std::uint64_t(img.height));
}

std::vector<float> nlm_patch_weights(const NlmSpaceSettings& s) {
  const int side = 2 * s.radius + 1;
  std::vector<float> weight(std::size_t(side) * side);
  double wsum = 0;
  for (int dy = -s.radius; dy <= s.radius; ++dy)
    for (int dx = -s.radius; dx <= s.radius; ++dx) {
      const double v = std::exp(-(dx * dx + dy * dy) / (2.0 * s.patch_sigma * s.patch_sigma));
      weight[std::size_t((dy + s.radius) * side + dx + s.radius)] = float(v);
      wsum += v;
    }
  for (auto& v : weight) v = float(v / wsum);
  return weight;
}

std::vector<int> nlm_sample_pixels(std::uint64_t seed, int w, int h, int samples) {
  const int n = std::min(samples, w * h);
  std::vector<int> out(std::size_t(std::max(n, 0)));
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> px(0, w * h - 1);
  for (int r = 0; r < n; ++r) out[std::size_t(r)] = n == w * h ? r : px(rng);
  return out;
}

NlmBasis nlm_basis(const cv::Mat& patches, const std::vector<float>& weight, int dims) {
  cv::Mat covar, mean;
  cv::calcCovarMatrix(patches, covar, mean, cv::COVAR_NORMAL | cv::COVAR_ROWS | cv::COVAR_SCALE, CV_64F);
  return nlm_basis_from_covariance(covar, mean, weight, dims);
}

NlmBasis nlm_basis_from_covariance(const cv::Mat& covar, const cv::Mat& mean, const std::vector<float>& weight, int dims) {
  const int P = covar.cols, side = int(std::lround(std::sqrt(double(P))));
  cv::Mat evals, evecs;
  cv::eigen(covar, evals, evecs);  // rows of evecs: eigenvectors, eigenvalues descending
  NlmBasis b;
  b.kernels.assign(std::size_t(dims) * P, 0.0f);
  b.offsets.assign(std::size_t(dims), 0.0);
  b.center.resize(std::size_t(dims));
  for (int k = 0; k < dims; ++k) {
    for (int j = 0; j < P; ++j) {
      const double e = evecs.at<double>(k, j);
      b.kernels[std::size_t(k) * P + j] = float(e * weight[std::size_t(j)]);
      b.offsets[std::size_t(k)] += e * mean.at<double>(0, j);
    }
    b.center[std::size_t(k)] = b.kernels[std::size_t(k) * P + std::size_t((side / 2) * side + side / 2)];
  }
  return b;
}

Image compressed_illumination(const Image& illumination, float m) {
  Image out(illumination.width(), illumination.height(), 3);
  tbb::parallel_for(0, out.height(), [&](int y) {
    const float* in = illumination.pixel(0, y);
    float* o = out.pixel(0, y);
    for (int k = 0; k < out.width() * 3; ++k) o[k] = std::log1p(std::max(0.0f, in[k]) / m);
  });
  return out;
}

NlmSpace nlm_space(const Image& illumination, const NlmSpaceSettings& s) {
  if (illumination.channels() != 3) throw WorkError("nlm_space: needs an RGB illumination");
  const int w = illumination.width(), h = illumination.height();
  const int side = 2 * s.radius + 1, P = side * side;
  const int dims = std::clamp(s.dims, 1, P);
  NlmSpace out;
  out.mean_luminance = mean_luminance(illumination);

  // The compressed luminance, padded by the patch radius (reflected borders).
  cv::Mat y(h, w, CV_32F);
  tbb::parallel_for(0, h, [&](int j) {
    float* row = y.ptr<float>(j);
    for (int i = 0; i < w; ++i) row[i] = log_argument(illumination.pixel(i, j), out.mean_luminance);
    cv::hal::log32f(row, row, w);  // as compress()
  });
  cv::Mat padded;
  cv::copyMakeBorder(y, padded, s.radius, s.radius, s.radius, s.radius,
                     (w > s.radius && h > s.radius) ? cv::BORDER_REFLECT_101 : cv::BORDER_REPLICATE);

  const std::vector<float> weight = nlm_patch_weights(s);

  // PCA of the weighted patches of a deterministic random subset of pixels.
  const std::vector<int> picks = nlm_sample_pixels(nlm_sample_seed(illumination.cview()), w, h, s.samples);
  const int n = int(picks.size());
  cv::Mat patches(n, P, CV_64F);
  for (int r = 0; r < n; ++r) {
    const int p = picks[std::size_t(r)];
    const int cx = p % w, cy = p / w;
    double* row = patches.ptr<double>(r);
    for (int dy = 0; dy < side; ++dy)
      for (int dx = 0; dx < side; ++dx) row[dy * side + dx] = weight[dy * side + dx] * padded.at<float>(cy + dy, cx + dx);
  }
  const NlmBasis basis = nlm_basis(patches, weight, dims);

  out.vectors = Image(w, h, dims);
  out.center = basis.center;
  std::vector<cv::Mat> kernels(dims);
  const std::vector<double>& offsets = basis.offsets;
  for (int k = 0; k < dims; ++k) {
    kernels[k] = cv::Mat(side, side, CV_32F);
    for (int j = 0; j < P; ++j) kernels[k].at<float>(j / side, j % side) = basis.kernels[std::size_t(k) * P + j];
  }
  // Projections: one task per (dimension, band of rows), each a filter2D over its band of the
  // padded image (the band plus the patch radius above and below), written into the
  // interleaved vectors. Bands, not dimensions alone: 3 dimensions do not split well over the
  // cores. Every output pixel sees the same kernel over the same padded pixels, so the result
  // does not depend on the banding.
  const int band = 32, bands = (h + band - 1) / band;
  tbb::parallel_for(0, dims * bands, [&](int t) {
    const int k = t / bands, y0 = (t % bands) * band, y1 = std::min(h, y0 + band);
    const cv::Mat src = padded(cv::Rect(0, y0, w + 2 * s.radius, y1 - y0 + 2 * s.radius));
    cv::Mat full;
    cv::filter2D(src, full, CV_32F, kernels[k], cv::Point(-1, -1), -offsets[k], cv::BORDER_CONSTANT | cv::BORDER_ISOLATED);
    for (int yy = y0; yy < y1; ++yy) {
      const float* r = full.ptr<float>(yy - y0 + s.radius) + s.radius;
      float* o = out.vectors.pixel(0, yy) + k;
      for (int x = 0; x < w; ++x) o[std::size_t(x) * dims] = r[x];
    }
  });
  return out;
}

}  // namespace dnb
