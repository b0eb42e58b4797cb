#include "metrics/metrics.h"

#include <cmath>

#include <fmt/format.h>

#include "core/errors.h"

namespace dnb::metrics {

double mse_hdr(const Image& image, const Image& reference) {
  if (!image.same_shape(reference))
    throw InputError(fmt::format("image is {}x{}x{}, reference is {}x{}x{}: sizes must match", image.width(),
                                 image.height(), image.channels(), reference.width(), reference.height(),
                                 reference.channels()));
  double sum = 0;
  for (std::size_t i = 0; i < image.size(); ++i) {
    double a = image.data()[i], b = reference.data()[i];
    if (!std::isfinite(a) || !std::isfinite(b))
      throw InputError(fmt::format("non-finite sample at pixel {} of the {}", i / image.channels(),
                                   std::isfinite(a) ? "reference" : "image"));
    sum += (a - b) * (a - b);
  }
  return sum / double(image.size());
}

}  // namespace dnb::metrics
