#include "core/stats.h"

#include <algorithm>
#include <cmath>

namespace dnb::stats {

double median(std::vector<double> v) {
  const std::size_t n = v.size();
  if (n == 0) return NAN;
  std::sort(v.begin(), v.end());
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double mean(const std::vector<double>& v) {
  if (v.empty()) return NAN;
  double s = 0;
  for (double x : v) s += x;
  return s / double(v.size());
}

double relative_std(const std::vector<double>& v) {
  if (v.size() < 2) return 0;
  const double m = mean(v);
  double ss = 0;
  for (double x : v) ss += (x - m) * (x - m);
  return m > 0 ? std::sqrt(ss / double(v.size() - 1)) / m : 0;
}

double max_over_min_minus_one(const std::vector<double>& v) {
  if (v.size() < 2) return 0;
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  return *lo > 0 ? *hi / *lo - 1.0 : 0;
}

}  // namespace dnb::stats
