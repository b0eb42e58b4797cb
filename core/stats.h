// Small statistics over a list of numbers, written once for the runner (median of timing
// repeats), the nightly gates (medians over benchmark repetitions, spreads across seeds) and
// the benchmarks.
#pragma once

#include <cstddef>
#include <vector>

namespace dnb::stats {

// The median (the mean of the two middle values for an even count); NaN for an empty list.
double median(std::vector<double> v);
// The arithmetic mean; NaN for an empty list.
double mean(const std::vector<double>& v);
// Sample standard deviation over the mean (n - 1 in the denominator); 0 for fewer than two
// values or a mean that is not positive.
double relative_std(const std::vector<double>& v);
// max / min - 1: the largest relative change between two of the values; 0 for fewer than two
// values or a minimum that is not positive.
double max_over_min_minus_one(const std::vector<double>& v);

// A two-sided confidence interval for the mean of independent values (one per input seed):
// Student's t-interval, mean +- t_{1 - a/2, n - 1} s / sqrt(n) with the sample standard
// deviation s. `half_width` is NaN for fewer than two values (no interval from one seed).
struct Interval {
  double mean = 0;
  double half_width = 0;
  int n = 0;
};
Interval t_interval(const std::vector<double>& v, double confidence = 0.95);

// The two-sided p-value of the paired t-test that a and b (one pair per seed, same order) have
// the same mean: t = mean(d) / (s_d / sqrt(n)) for d = a - b, n - 1 degrees of freedom. NaN for
// fewer than two pairs or unequal lengths; 0 when every difference is the same non-zero value
// (no spread: the difference is certain), 1 when every difference is zero.
double paired_t_test_p(const std::vector<double>& a, const std::vector<double>& b);

// The mean of a[i] - b[i] over n independent pairs in standard errors of that mean, the error
// from the differences' own spread: the paired t statistic, close to normal with the thousands
// of pairs it serves (the pixels of two renders of one scene: tracer/colour_core.h's checks).
// 0 when every difference is zero; +-infinity when all differences are one non-zero value; NaN
// for fewer than two pairs.
double paired_z(const float* a, const float* b, std::size_t n);

// Kendall's rank correlation of paired values (x_i, y_i), tau-b (ties in either list count as
// neither concordant nor discordant, and shrink the denominator: sqrt((n0 - tx)(n0 - ty)) with
// n0 = n (n - 1) / 2). p_value: two-sided, for tau = 0 (independent rankings); exact from the
// permutation distribution of the discordant count when there are no ties and n <= 60 (the
// Mahonian numbers), else the normal approximation with the tie-corrected variance (Kendall
// 1970, eq. 4.3); `exact` says which. NaN tau and p for fewer than two pairs, unequal lengths,
// or a list whose values are all tied.
struct KendallTau {
  double tau = 0;
  double p_value = 1;
  bool exact = false;
  int n = 0;
  long long concordant = 0, discordant = 0, ties_x = 0, ties_y = 0;
};
KendallTau kendall_tau_b(const std::vector<double>& x, const std::vector<double>& y);

}  // namespace dnb::stats
