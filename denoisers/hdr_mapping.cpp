#include "denoisers/hdr_mapping.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include "core/errors.h"

namespace dnb {

namespace {
constexpr float kGamma = 2.2f;
// Reinhard's t = x / (1 + x) never reaches 1 for finite x; filtered values are convex
// combinations of inputs so stay below it too, except a value decoded from the top 8-bit code.
// Capping t keeps expand() finite there: t = 1 - 2^-12 is x of about 4095.
constexpr float kMaxReinhardT = 1.0f - 1.0f / 4096.0f;

float srgb_encode(float x) {
  x = std::clamp(x, 0.0f, 1.0f);
  if (x >= 1.0f) return 1.0f;  // exactly: 1.055 * 1 - 0.055 does not round to 1 in float
  return x <= 0.0031308f ? 12.92f * x : std::min(1.055f * std::pow(x, 1.0f / 2.4f) - 0.055f, 1.0f);
}
float srgb_decode(float y) {
  y = std::clamp(y, 0.0f, 1.0f);
  return y <= 0.04045f ? y / 12.92f : std::pow((y + 0.055f) / 1.055f, 2.4f);
}

template <typename F>
void for_each_sample(Image& image, F f) {
  float* d = image.data();
  const std::size_t n = image.size();
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 1 << 14), [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t i = r.begin(); i != r.end(); ++i) d[i] = f(d[i]);
  });
}
}  // namespace

std::vector<std::string> range_map_names() { return {"linear", "log", "reinhard", "srgb"}; }

RangeMap parse_range_map(const std::string& name) {
  if (name == "linear") return RangeMap::Linear;
  if (name == "log") return RangeMap::Log;
  if (name == "reinhard") return RangeMap::Reinhard;
  if (name == "srgb") return RangeMap::Srgb;
  throw InputError(fmt::format("unknown range map '{}' (valid: {})", name, fmt::join(range_map_names(), ", ")));
}

float compress(RangeMap map, float x) {
  switch (map) {
    case RangeMap::Linear: return x;
    case RangeMap::Log: return std::log1p(std::max(x, 0.0f));
    case RangeMap::Reinhard: {
      const float c = std::max(x, 0.0f);
      return std::pow(c / (1.0f + c), 1.0f / kGamma);
    }
    case RangeMap::Srgb: return srgb_encode(x);
  }
  return x;
}

float expand(RangeMap map, float y) {
  switch (map) {
    case RangeMap::Linear: return y;
    case RangeMap::Log: return std::expm1(std::max(y, 0.0f));
    case RangeMap::Reinhard: {
      const float t = std::min(std::pow(std::max(y, 0.0f), kGamma), kMaxReinhardT);
      return t / (1.0f - t);
    }
    case RangeMap::Srgb: return srgb_decode(y);
  }
  return y;
}

void compress(RangeMap map, Image& image) {
  if (map != RangeMap::Linear) for_each_sample(image, [map](float x) { return compress(map, x); });
}
void expand(RangeMap map, Image& image) {
  if (map != RangeMap::Linear) for_each_sample(image, [map](float y) { return expand(map, y); });
}

cv::Mat to_8bit(RangeMap map, const Image& image) {
  cv::Mat out(image.height(), image.width(), CV_8UC(image.channels()));
  const float* src = image.data();
  tbb::parallel_for(0, image.height(), [&](int y) {
    std::uint8_t* row = out.ptr<std::uint8_t>(y);
    const float* s = src + std::size_t(y) * image.width() * image.channels();
    for (int i = 0; i < image.width() * image.channels(); ++i)
      row[i] = std::uint8_t(std::clamp(std::lround(255.0f * compress(map, s[i])), 0L, 255L));
  });
  return out;
}

cv::Mat as_mat(Image& image) {
  return cv::Mat(image.height(), image.width(), CV_32FC(image.channels()), image.data());
}
cv::Mat as_mat(const Image& image) {
  // cv::Mat has no read-only flavour; callers promise not to write (documented in the header).
  return cv::Mat(image.height(), image.width(), CV_32FC(image.channels()), const_cast<float*>(image.data()));
}
Image from_mat(const cv::Mat& m) {
  if (m.depth() != CV_32F) throw WorkError(fmt::format("from_mat: expected a 32-bit float matrix, got depth {}", m.depth()));
  Image out(m.cols, m.rows, m.channels());
  cv::Mat dst = as_mat(out);
  m.copyTo(dst);
  return out;
}

}  // namespace dnb
