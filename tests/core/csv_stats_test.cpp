// core/csv.h and core/stats.h: the CSV every table and history is written in, and the medians
// and spreads the runner and the nightly gates compute.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

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

TEST(Stats, PairedZOfTheMeanDifference) {
  // d = 1, 2, 3, 4: mean 2.5, sample variance 5/3, standard error sqrt(5/12).
  const float a[] = {1, 2, 3, 4}, zero[] = {0, 0, 0, 0};
  EXPECT_NEAR(stats::paired_z(a, zero, 4), 2.5 / std::sqrt(5.0 / 12.0), 1e-12);
  EXPECT_NEAR(stats::paired_z(zero, a, 4), -2.5 / std::sqrt(5.0 / 12.0), 1e-12);
  EXPECT_EQ(stats::paired_z(a, a, 4), 0.0);  // no difference at all
  const float b[] = {0, 1, 2, 3};            // always 1 lower: the difference is certain
  EXPECT_EQ(stats::paired_z(a, b, 4), std::numeric_limits<double>::infinity());
  EXPECT_TRUE(std::isnan(stats::paired_z(a, b, 1)));
}

// Kendall's tau-b against cases worked out by hand (the Mahonian counts for n = 4 are
// 1 3 5 6 5 3 1 of 24; the tie variance by Kendall's eq. 4.3), and scipy.stats.kendalltau
// 1.10's values for the same lists (exact method, and asymptotic where there are ties).
TEST(Stats, KendallTauBAgainstHandWorkedCases) {
  // Identical orders: tau 1; only the identity and the reversal are as extreme: p = 2 / 5!.
  stats::KendallTau k = stats::kendall_tau_b({1, 2, 3, 4, 5}, {10, 20, 30, 40, 50});
  EXPECT_DOUBLE_EQ(k.tau, 1.0);
  EXPECT_TRUE(k.exact);
  EXPECT_NEAR(k.p_value, 2.0 / 120.0, 1e-12);
  // One swap in four: C = 5, D = 1, tau = 4/6; |D - 3| >= 2 holds for D = 0, 1, 5, 6: 8 of 24.
  k = stats::kendall_tau_b({1, 2, 3, 4}, {1, 3, 2, 4});
  EXPECT_EQ(k.concordant, 5);
  EXPECT_EQ(k.discordant, 1);
  EXPECT_NEAR(k.tau, 4.0 / 6.0, 1e-12);
  EXPECT_NEAR(k.p_value, 8.0 / 24.0, 1e-12);
  // A reversed order is tau -1 with the same p as the identity.
  k = stats::kendall_tau_b({1, 2, 3, 4, 5}, {5, 4, 3, 2, 1});
  EXPECT_DOUBLE_EQ(k.tau, -1.0);
  EXPECT_NEAR(k.p_value, 2.0 / 120.0, 1e-12);
  // scipy: tau 0.619047..., p 0.069047... (exact).
  k = stats::kendall_tau_b({1, 2, 3, 4, 5, 6, 7}, {2, 1, 4, 3, 7, 5, 6});
  EXPECT_NEAR(k.tau, 0.6190476190476191, 1e-12);
  EXPECT_NEAR(k.p_value, 0.06904761904761905, 1e-12);
  // Ties: C = 4, D = 0, one tie in each list: tau = 4 / sqrt(5 * 5) = 0.8; variance
  // (156 - 18 - 18) / 18 + 4 / 24 = 6.8333, z = 4 / sqrt(6.8333): p = 0.125971 (scipy: 0.12597116).
  k = stats::kendall_tau_b({1, 2, 2, 3}, {1, 2, 3, 3});
  EXPECT_NEAR(k.tau, 0.8, 1e-12);
  EXPECT_FALSE(k.exact);
  EXPECT_EQ(k.ties_x, 1);
  EXPECT_EQ(k.ties_y, 1);
  EXPECT_NEAR(k.p_value, 0.12597116307723114, 1e-9);
  // Nothing to rank: NaN, not a number that looks like an answer.
  EXPECT_TRUE(std::isnan(stats::kendall_tau_b({1}, {1}).tau));
  EXPECT_TRUE(std::isnan(stats::kendall_tau_b({1, 1, 1}, {1, 2, 3}).tau));
  EXPECT_TRUE(std::isnan(stats::kendall_tau_b({1, 2}, {1, 2, 3}).p_value));
}

}  // namespace
}  // namespace dnb
