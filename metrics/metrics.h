// Error metrics against a reference (DESIGN.md, "Metric conventions").
#pragma once

#include "core/image.h"

namespace dnb::metrics {

// Mean squared error on linear radiance over all pixels and channels. InputError when the
// shapes differ or a sample is not finite (a NaN is refused, never averaged).
double mse_hdr(const Image& image, const Image& reference);

}  // namespace dnb::metrics
