#include "core/stats.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <boost/math/distributions/students_t.hpp>

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

namespace {
double sample_sd(const std::vector<double>& v, double m) {
  double ss = 0;
  for (double x : v) ss += (x - m) * (x - m);
  return std::sqrt(ss / double(v.size() - 1));
}
}  // namespace

// Student's t quantiles and tail probabilities from Boost.Math (students_t), not a hand-written
// approximation: a table of small-sample intervals is only as good as its quantiles.
Interval t_interval(const std::vector<double>& v, double confidence) {
  Interval r;
  r.n = int(v.size());
  r.mean = mean(v);
  if (v.size() < 2) {
    r.half_width = std::numeric_limits<double>::quiet_NaN();
    return r;
  }
  const boost::math::students_t t(double(v.size() - 1));
  r.half_width = boost::math::quantile(t, 0.5 + confidence / 2) * sample_sd(v, r.mean) / std::sqrt(double(v.size()));
  return r;
}

double paired_t_test_p(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size() || a.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  std::vector<double> d(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) d[i] = a[i] - b[i];
  const double m = mean(d), sd = sample_sd(d, m);
  if (sd == 0) return m == 0 ? 1.0 : 0.0;
  const double tstat = m / (sd / std::sqrt(double(d.size())));
  const boost::math::students_t t(double(d.size() - 1));
  return 2 * boost::math::cdf(boost::math::complement(t, std::abs(tstat)));
}

}  // namespace dnb::stats
