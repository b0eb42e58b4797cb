#include "metrics/temporal.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <fmt/format.h>

#include "core/errors.h"

namespace dnb::metrics {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

void check_layer(const Image& img, int w, int h, int channels, const char* what) {
  if (img.width() != w || img.height() != h || img.channels() != channels)
    throw InputError(fmt::format("{} is {}x{} with {} channels: expected {}x{} with {}", what, img.width(), img.height(),
                                 img.channels(), w, h, channels));
}

bool is_miss(float depth) { return !(std::isfinite(depth) && depth > 0); }

}  // namespace

bool same_surface(float z, const float* n, float zp, const float* np, const SurfaceTest& test) {
  const bool miss = is_miss(z), miss_p = is_miss(zp);
  if (miss || miss_p) return miss && miss_p;
  if (std::fabs(z - zp) > test.max_relative_depth * std::max(z, zp)) return false;
  const double dot = double(n[0]) * np[0] + double(n[1]) * np[1] + double(n[2]) * np[2];
  const double len = std::sqrt((double(n[0]) * n[0] + double(n[1]) * n[1] + double(n[2]) * n[2]) *
                               (double(np[0]) * np[0] + double(np[1]) * np[1] + double(np[2]) * np[2]));
  // A hit without a usable normal (zero length, or not finite) cannot be matched.
  if (!(len > 1e-12) || !std::isfinite(len)) return false;
  return dot >= test.min_normal_cosine * len;
}

Reprojection::Reprojection(const Image& motion) {
  check_layer(motion, motion.width(), motion.height(), 2, "the motion layer");
  place(motion, nullptr, nullptr, nullptr, nullptr, {});
}

Reprojection::Reprojection(const Image& motion, const Image& depth, const Image& normal, const Image& previous_depth,
                           const Image& previous_normal, const SurfaceTest& test) {
  const int w = motion.width(), h = motion.height();
  check_layer(motion, w, h, 2, "the motion layer");
  check_layer(depth, w, h, 1, "the depth layer");
  check_layer(normal, w, h, 3, "the normal layer");
  check_layer(previous_depth, w, h, 1, "the previous frame's depth layer");
  check_layer(previous_normal, w, h, 3, "the previous frame's normal layer");
  place(motion, &depth, &normal, &previous_depth, &previous_normal, test);
}

void Reprojection::place(const Image& motion, const Image* depth, const Image* normal, const Image* previous_depth,
                         const Image* previous_normal, const SurfaceTest& test) {
  w_ = motion.width(), h_ = motion.height();
  taps_.assign(motion.pixel_count(), Taps{});
  for (int y = 0; y < h_; ++y)
    for (int x = 0; x < w_; ++x) {
      const std::size_t k = std::size_t(y) * w_ + x;
      Taps& t = taps_[k];
      for (int i = 0; i < 4; ++i) t.index[i] = std::int32_t(k), t.weight[i] = 0;
      // Film position in pixels (centres at +0.5), then in pixel-centre coordinates.
      const double fx = x + 0.5 + double(motion.at(x, y, 0)), fy = y + 0.5 + double(motion.at(x, y, 1));
      if (!(fx >= 0 && fx <= w_ && fy >= 0 && fy <= h_)) continue;  // outside, or not finite
      const double u = fx - 0.5, v = fy - 0.5;
      const double x0 = std::floor(u), y0 = std::floor(v);
      const double a = u - x0, b = v - y0;
      const double wt[4] = {(1 - a) * (1 - b), a * (1 - b), (1 - a) * b, a * b};
      double kept = 0;
      for (int i = 0; i < 4; ++i) {
        if (wt[i] == 0) continue;  // an integer motion has one tap; the others must not veto it
        const int tx = std::clamp(int(x0) + (i & 1), 0, w_ - 1), ty = std::clamp(int(y0) + (i >> 1), 0, h_ - 1);
        const std::size_t q = std::size_t(ty) * w_ + tx;
        if (depth && !same_surface(depth->data()[k], normal->pixel(x, y), previous_depth->data()[q],
                                   previous_normal->data() + q * 3, test))
          continue;
        t.index[i] = std::int32_t(q);
        t.weight[i] = float(wt[i]);
        kept += wt[i];
      }
      if (kept < kMinHistoryWeight) {
        for (float& wi : t.weight) wi = 0;
        continue;
      }
      for (float& wi : t.weight) wi = float(wi / kept);
    }
}

Image Reprojection::mask() const {
  Image m(w_, h_, 1);
  for (std::size_t k = 0; k < taps_.size(); ++k) m.data()[k] = valid(k) ? 1.0f : 0.0f;
  return m;
}

std::size_t Reprojection::invalid_count() const {
  std::size_t n = 0;
  for (std::size_t k = 0; k < taps_.size(); ++k) n += !valid(k);
  return n;
}

void Reprojection::warp_pixel(const Image& previous, std::size_t pixel, float* out) const {
  const int nc = previous.channels();
  const Taps& t = taps_[pixel];
  for (int c = 0; c < nc; ++c) out[c] = 0;
  for (int i = 0; i < 4; ++i) {
    if (t.weight[i] == 0) continue;
    const float* p = previous.data() + std::size_t(t.index[i]) * nc;
    for (int c = 0; c < nc; ++c) out[c] += t.weight[i] * p[c];
  }
}

Image Reprojection::warp(const Image& previous) const {
  if (previous.width() != w_ || previous.height() != h_)
    throw InputError(fmt::format("reprojection: the previous image is {}x{}, the motion layer {}x{}", previous.width(),
                                 previous.height(), w_, h_));
  Image out(w_, h_, previous.channels());
  for (std::size_t k = 0; k < taps_.size(); ++k) warp_pixel(previous, k, out.data() + k * previous.channels());
  return out;
}

Reprojected reproject(const Image& previous, const Image& motion) {
  const Reprojection r(motion);
  return {r.warp(previous), r.mask()};
}

Image disocclusion_mask(const Image& motion, const Image& depth, const Image& normal, const Image& previous_depth,
                        const Image& previous_normal, const SurfaceTest& test) {
  return Reprojection(motion, depth, normal, previous_depth, previous_normal, test).mask();
}

FrameTerm tmse_frame(const Image& output, const Image& previous_output, const Image& reference,
                     const Image& previous_reference, const Reprojection& history) {
  check_pair(output, reference, "output", "reference");
  check_pair(previous_output, previous_reference, "previous output", "previous reference");
  check_pair(output, previous_output, "output", "previous output");
  if (output.width() != history.width() || output.height() != history.height())
    throw InputError(fmt::format("tmse: the images are {}x{}, the motion layer {}x{}", output.width(), output.height(),
                                 history.width(), history.height()));
  // On the display scale first (what a viewer sees flicker on), then warped: W of the 8-bit image.
  const Image o = to_srgb8(output), r = to_srgb8(reference);
  const Image wo = history.warp(to_srgb8(previous_output)), wr = history.warp(to_srgb8(previous_reference));
  FrameTerm t;
  t.result.map = Image(output.width(), output.height(), 1);
  for (std::size_t p = 0; p < output.pixel_count(); ++p) {
    if (!history.valid(p)) continue;
    double s = 0;
    for (int c = 0; c < 3; ++c) {
      const std::size_t i = p * 3 + c;
      const double d = (double(o.data()[i]) - wo.data()[i]) - (double(r.data()[i]) - wr.data()[i]);
      s += d * d;
    }
    t.result.map.data()[p] = float(s / 3);
    t.sum += s / 3;
    ++t.count;
  }
  t.result.value = t.count ? t.sum / double(t.count) : kNaN;
  return t;
}

FrameTerm disocclusion_mse_frame(const Image& output, const Image& reference, const Reprojection& history) {
  if (output.width() != history.width() || output.height() != history.height())
    throw InputError(fmt::format("disocclusion_mse: the images are {}x{}, the motion layer {}x{}", output.width(),
                                 output.height(), history.width(), history.height()));
  FrameTerm t;
  t.result = mse(output, reference);  // checks the pair; its map is the per-pixel 8-bit error
  for (std::size_t p = 0; p < output.pixel_count(); ++p) {
    if (history.valid(p)) {
      t.result.map.data()[p] = 0;
    } else {
      t.sum += t.result.map.data()[p];
      ++t.count;
    }
  }
  t.result.value = t.count ? t.sum / double(t.count) : kNaN;
  return t;
}

void TemporalScorer::add(const TemporalFrame& f) {
  if (!f.output || !f.reference || !f.depth || !f.normal || (previous_ && !f.motion))
    throw InputError("temporal metrics: a frame needs its output, reference, depth and normal (and motion after frame 0)");
  const int w = f.output->width(), h = f.output->height();
  check_pair(*f.output, *f.reference, "output", "reference");
  check_layer(*f.depth, w, h, 1, "the depth layer");
  check_layer(*f.normal, w, h, 3, "the normal layer");
  if (previous_) {
    check_layer(*f.motion, w, h, 2, "the motion layer");
    if (previous_->output.width() != w || previous_->output.height() != h)
      throw InputError(fmt::format("temporal metrics: frame {} is {}x{}, the previous one {}x{}",
                                   scores_.tmse_per_frame.size(), w, h, previous_->output.width(),
                                   previous_->output.height()));
    const Reprojection history(*f.motion, *f.depth, *f.normal, previous_->depth, previous_->normal, test_);
    const FrameTerm t = tmse_frame(*f.output, previous_->output, *f.reference, previous_->reference, history);
    const FrameTerm d = disocclusion_mse_frame(*f.output, *f.reference, history);
    scores_.tmse_per_frame.push_back(t.result.value);
    tmse_sum_ += t.sum;
    tmse_count_ += t.count;
    scores_.disocclusion_mse_per_frame.push_back(d.result.value);
    scores_.disoccluded_pixels.push_back(d.count);
  } else {
    scores_.tmse_per_frame.push_back(kNaN);
    scores_.disocclusion_mse_per_frame.push_back(kNaN);
    scores_.disoccluded_pixels.push_back(0);
    previous_.emplace();
  }
  previous_->output = *f.output;
  previous_->reference = *f.reference;
  previous_->depth = *f.depth;
  previous_->normal = *f.normal;
}

TemporalScores TemporalScorer::scores() const {
  TemporalScores s = scores_;
  s.tmse = tmse_count_ ? tmse_sum_ / double(tmse_count_) : kNaN;
  double sum = 0;
  int frames = 0;
  for (double v : s.disocclusion_mse_per_frame)
    if (!std::isnan(v)) sum += v, ++frames;
  s.disocclusion_mse = frames ? sum / frames : kNaN;
  return s;
}

}  // namespace dnb::metrics
