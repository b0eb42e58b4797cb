#include "denoisers/illumination.h"

#include <algorithm>
#include <cmath>

#include <tbb/parallel_for.h>

namespace dnb {

std::vector<std::string> illumination_layers() {
  return {layer::kDirect, layer::kIndirect, layer::kAlbedo, layer::kReflection, layer::kEmission};
}

Image illumination(const AovFrame& frame) {
  const Image& d = frame.layer(layer::kDirect);
  const Image& i = frame.layer(layer::kIndirect);
  Image out(frame.width(), frame.height(), 3);
  tbb::parallel_for(std::size_t(0), out.size(), [&](std::size_t k) { out.data()[k] = d.data()[k] + i.data()[k]; });
  return out;
}

std::vector<std::string> reflection_guide_layers() {
  return {layer::at_level(1, layer::kAlbedo), layer::at_level(1, layer::kNormal), layer::at_level(1, layer::kDepth)};
}

Image compose(const Image& l, const AovFrame& frame) { return compose(l, frame, frame.layer(layer::kReflection)); }

Image compose(const Image& l, const AovFrame& frame, const Image& r) {
  const Image& t = frame.layer(layer::kAlbedo);
  const Image& e = frame.layer(layer::kEmission);
  Image out(frame.width(), frame.height(), 3);
  tbb::parallel_for(std::size_t(0), out.size(),
                    [&](std::size_t k) { out.data()[k] = l.data()[k] * t.data()[k] + r.data()[k] + e.data()[k]; });
  return out;
}

Image normalized_depth(const AovFrame& frame, int level) {
  const Image& z = frame.layer(layer::at_level(level, layer::kDepth));
  std::vector<float> valid;
  valid.reserve(z.size());
  for (std::size_t k = 0; k < z.size(); ++k)
    if (std::isfinite(z.data()[k]) && z.data()[k] > 0) valid.push_back(z.data()[k]);
  float median = 1.0f;
  if (!valid.empty()) {
    auto mid = valid.begin() + valid.size() / 2;
    std::nth_element(valid.begin(), mid, valid.end());
    median = *mid;
  }
  Image out(frame.width(), frame.height(), 1);
  for (std::size_t k = 0; k < z.size(); ++k) {
    const float v = z.data()[k];
    out.data()[k] = (std::isfinite(v) && v > 0) ? v / median : 0.0f;
  }
  return out;
}

}  // namespace dnb
