#include "core/image.h"

#include <cmath>
#include <string>

#include <fmt/format.h>

#include "core/errors.h"

namespace dnb {

void Image::check_size(int width, int height, int channels, const char* what) {
  if (width <= 0 || height <= 0 || channels <= 0 || width > kMaxSide || height > kMaxSide ||
      std::int64_t(width) * height > kMaxPixels || channels > 1024) {
    throw InputError(fmt::format(
        "{}: image size {}x{} with {} channels is not accepted (expected 1..{} pixels per side, "
        "at most {} pixels, 1..1024 channels)",
        what, width, height, channels, kMaxSide, kMaxPixels));
  }
}

Image::Image(int width, int height, int channels, float fill) {
  check_size(width, height, channels, "image");
  width_ = width;
  height_ = height;
  channels_ = channels;
  data_.assign(std::size_t(width) * height * channels, fill);
}

Image::Image(int width, int height, int channels, NoFill) {
  check_size(width, height, channels, "image");
  width_ = width;
  height_ = height;
  channels_ = channels;
  data_.resize(std::size_t(width) * height * channels);
}

Image to_image(ConstImageView v) {
  Image out(v.width, v.height, v.channels);
  for (int y = 0; y < v.height; ++y) {
    const float* src = v.row(y);
    float* dst = out.pixel(0, y);
    for (int i = 0; i < v.width * v.channels; ++i) dst[i] = src[i];
  }
  return out;
}

std::size_t count_non_finite(ConstImageView v) {
  std::size_t n = 0;
  for (int y = 0; y < v.height; ++y) {
    const float* r = v.row(y);
    for (int i = 0; i < v.width * v.channels; ++i) n += !std::isfinite(r[i]);
  }
  return n;
}

double relative_rms(const float* a, const float* b, std::size_t n) {
  double d = 0, r = 0;
  for (std::size_t i = 0; i < n; ++i) {
    d += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    r += double(b[i]) * b[i];
  }
  return r > 0 ? std::sqrt(d / r) : std::sqrt(d);
}

}  // namespace dnb
