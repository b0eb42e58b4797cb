#include "core/stats.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <boost/math/distributions/normal.hpp>

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

double paired_z(const float* a, const float* b, std::size_t n) {
  if (n < 2) return std::numeric_limits<double>::quiet_NaN();
  double sum = 0, sum2 = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double d = double(a[i]) - double(b[i]);
    sum += d;
    sum2 += d * d;
  }
  const double m = sum / double(n), var = std::max(0.0, (sum2 - sum * m) / double(n - 1));
  if (var == 0) return m == 0 ? 0.0 : std::copysign(std::numeric_limits<double>::infinity(), m);
  return m / std::sqrt(var / double(n));
}

// Written here: neither Boost.Math nor the project's other libraries have Kendall's tau; the
// O(n^2) pair count is plenty for tens of methods.
KendallTau kendall_tau_b(const std::vector<double>& x, const std::vector<double>& y) {
  KendallTau k;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  k.n = int(x.size());
  if (x.size() != y.size() || x.size() < 2) return k.tau = nan, k.p_value = nan, k;
  for (std::size_t i = 0; i < x.size(); ++i)
    for (std::size_t j = i + 1; j < x.size(); ++j) {
      const double dx = x[i] - x[j], dy = y[i] - y[j];
      if (dx == 0) ++k.ties_x;
      if (dy == 0) ++k.ties_y;
      if (dx == 0 || dy == 0) continue;
      ((dx > 0) == (dy > 0) ? k.concordant : k.discordant) += 1;
    }
  const long long n = k.n, n0 = n * (n - 1) / 2;
  if (k.ties_x == n0 || k.ties_y == n0) return k.tau = nan, k.p_value = nan, k;
  k.tau = double(k.concordant - k.discordant) / std::sqrt(double(n0 - k.ties_x) * double(n0 - k.ties_y));
  if (k.ties_x == 0 && k.ties_y == 0 && n <= 60) {
    // counts[d]: permutations of n items with d inversions (Mahonian numbers), built one item
    // at a time; as doubles (n <= 60: at most 60! ~ 8e81, well inside double's range).
    std::vector<double> counts{1.0};
    for (long long m = 2; m <= n; ++m) {
      std::vector<double> next(counts.size() + std::size_t(m - 1), 0.0);
      for (std::size_t d = 0; d < counts.size(); ++d)
        for (long long add = 0; add < m; ++add) next[d + std::size_t(add)] += counts[d];
      counts.swap(next);
    }
    double total = 0;
    for (double c : counts) total += c;
    // Two-sided: the permutations whose discordant count is at least as far from n0 / 2.
    const double dev = std::abs(double(k.discordant) - double(n0) / 2.0);
    double tail = 0;
    for (std::size_t d = 0; d < counts.size(); ++d)
      if (std::abs(double(d) - double(n0) / 2.0) >= dev - 1e-9) tail += counts[d];
    k.p_value = std::min(1.0, tail / total);
    k.exact = true;
    return k;
  }
  // Normal approximation of S = C - D with ties (the tie groups' sizes t: v0 - vt - vu over 18,
  // plus the two cross terms).
  std::map<double, long long> gx, gy;
  for (double v : x) ++gx[v];
  for (double v : y) ++gy[v];
  auto sum_t = [](const std::map<double, long long>& g, auto f) {
    double s = 0;
    for (const auto& [v, t] : g) s += f(double(t));
    return s;
  };
  const double dn = double(n);
  const double v0 = dn * (dn - 1) * (2 * dn + 5);
  const double vt = sum_t(gx, [](double t) { return t * (t - 1) * (2 * t + 5); });
  const double vu = sum_t(gy, [](double t) { return t * (t - 1) * (2 * t + 5); });
  const double v1 = sum_t(gx, [](double t) { return t * (t - 1); }) * sum_t(gy, [](double t) { return t * (t - 1); });
  const double v2 = sum_t(gx, [](double t) { return t * (t - 1) * (t - 2); }) *
                    sum_t(gy, [](double t) { return t * (t - 1) * (t - 2); });
  double var = (v0 - vt - vu) / 18.0 + v1 / (2 * dn * (dn - 1));
  if (n > 2) var += v2 / (9 * dn * (dn - 1) * (dn - 2));
  const double s = double(k.concordant - k.discordant);
  if (!(var > 0)) return k.p_value = nan, k;
  const boost::math::normal z;
  k.p_value = std::min(1.0, 2 * boost::math::cdf(boost::math::complement(z, std::abs(s) / std::sqrt(var))));
  return k;
}

}  // namespace dnb::stats
