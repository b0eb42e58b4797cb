// core/csv.h and core/stats.h: the CSV every table and history is written in, and the medians
// and spreads the runner and the nightly gates compute.
#include <gtest/gtest.h>

#include <cmath>

#include "core/csv.h"
#include "core/stats.h"

namespace dnb {
namespace {

TEST(Csv, QuotesOnlyWhatMustBeQuotedAndSplitsItBack) {
  EXPECT_EQ(csv::field("plain"), "plain");
  EXPECT_EQ(csv::field("a,b"), "\"a,b\"");
  EXPECT_EQ(csv::field("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(csv::field("two\nlines"), "\"two\nlines\"");
  const std::vector<std::string> fields = {"scene", "a,b", "q\"uote", "", "sigma=2;radius=3"};
  EXPECT_EQ(csv::line(fields), "scene,\"a,b\",\"q\"\"uote\",,sigma=2;radius=3");
  EXPECT_EQ(csv::split(csv::line(fields)), fields);
  EXPECT_EQ(csv::split(""), std::vector<std::string>{""});
}

TEST(Stats, MedianMeanAndSpreads) {
  EXPECT_DOUBLE_EQ(stats::median({3, 1, 2}), 2);
  EXPECT_DOUBLE_EQ(stats::median({4, 1, 3, 2}), 2.5);
  EXPECT_TRUE(std::isnan(stats::median({})));
  EXPECT_DOUBLE_EQ(stats::mean({1, 2, 6}), 3);
  // Sample standard deviation of {1, 2, 6} is sqrt(7) (n - 1 = 2: (4 + 1 + 9) / 2).
  EXPECT_NEAR(stats::relative_std({1, 2, 6}), std::sqrt(7.0) / 3, 1e-15);
  EXPECT_EQ(stats::relative_std({5}), 0);
  EXPECT_DOUBLE_EQ(stats::max_over_min_minus_one({2, 3, 2.5}), 0.5);
  EXPECT_EQ(stats::max_over_min_minus_one({0, 3}), 0);  // no relative change from zero
}

}  // namespace
}  // namespace dnb
