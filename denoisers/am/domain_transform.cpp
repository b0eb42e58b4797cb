// The domain-transform recursive filter's constant-feedback half (see domain_transform.h).
#include "denoisers/am/domain_transform.h"

#include <cmath>

namespace dnb::domain_transform {

std::vector<float> low_pass_weights(int n, double sigma) {
  return std::vector<float>(std::max(n, 1), float(std::exp(-std::sqrt(2.0) / sigma)));
}

void low_pass(Interleaved& p, double sigma) {
  const std::vector<float> a = low_pass_weights(p.w, sigma);
  const int w = p.w, h = p.h, nb = p.dp / 8;
  const int groups = (h + kRowGroup - 1) / kRowGroup;
  tbb::parallel_for(0, groups, [&](int g) {
    const int y0 = g * kRowGroup, n = std::min(kRowGroup, h - y0);
    float* rows[kRowGroup];
    const float* ar[kRowGroup];
    for (int r = 0; r < n; ++r) rows[r] = p.row(y0 + r), ar[r] = a.data();
    recursive_interleaved(rows, ar, w, nb, n);
  });
  const float k = a[0];
  const std::size_t len = std::size_t(w) * p.dp;
  constexpr std::size_t kChunk = 512;
  tbb::parallel_for(std::size_t(0), (len + kChunk - 1) / kChunk, [&](std::size_t chunk) {
    const std::size_t i0 = chunk * kChunk, i1 = std::min(len, i0 + kChunk);
    for (int y = 1; y < h; ++y) {
      float* __restrict r = p.row(y);
      const float* __restrict q = p.row(y - 1);
      for (std::size_t i = i0; i < i1; ++i) r[i] += k * (q[i] - r[i]);
    }
    for (int y = h - 2; y >= 0; --y) {
      float* __restrict r = p.row(y);
      const float* __restrict q = p.row(y + 1);
      for (std::size_t i = i0; i < i1; ++i) r[i] += k * (q[i] - r[i]);
    }
  });
}

}  // namespace dnb::domain_transform
