// Small statistics over a list of numbers, written once for the runner (median of timing
// repeats), the nightly gates (medians over benchmark repetitions, spreads across seeds) and
// the benchmarks.
#pragma once

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

}  // namespace dnb::stats
