// Several input seeds per cell: the interval arithmetic against hand-computed cases, the
// "significantly best" mark, Table 1's cells and the config's seeds.
#include <cmath>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/errors.h"
#include "core/stats.h"
#include "experiment/config.h"
#include "experiment/report.h"
#include "test_util.h"

namespace dnb {
namespace {
using ::testing::HasSubstr;

TEST(Seeds, TIntervalAndPairedTestAgainstHandComputedValues) {
  // {1, 2, 3, 4}: mean 2.5, s = sqrt(5/3) = 1.29099445, t_{0.975, 3} = 3.18244631 (tables), so the
  // half width is 3.18244631 * 1.29099445 / 2 = 2.05426026.
  const stats::Interval i = stats::t_interval({1, 2, 3, 4});
  EXPECT_DOUBLE_EQ(i.mean, 2.5);
  EXPECT_EQ(i.n, 4);
  EXPECT_NEAR(i.half_width, 2.05426026, 1e-7);  // the 9 digits of the tabled quantile
  EXPECT_TRUE(std::isnan(stats::t_interval({7.0}).half_width));  // one seed: no interval
  // Differences {0.5, 0.2, 0.8}: mean 0.5, s = 0.3, t = 0.5 / (0.3 / sqrt 3) = 2.8867513 on 2
  // degrees of freedom, whose CDF is closed-form, 1/2 + t / (2 sqrt(2 + t^2)): p = 0.10197349.
  // 1e-7: the digits written here; Boost's t CDF is exact to double rounding.
  EXPECT_NEAR(stats::paired_t_test_p({1, 2, 3}, {0.5, 1.8, 2.2}), 0.10197349, 1e-7);
  EXPECT_DOUBLE_EQ(stats::paired_t_test_p({1, 2, 3}, {1, 2, 3}), 1.0);
  EXPECT_DOUBLE_EQ(stats::paired_t_test_p({2, 3, 4}, {1, 2, 3}), 0.0);  // always 1 lower: certain
  EXPECT_TRUE(std::isnan(stats::paired_t_test_p({1, 2}, {1})));
}

TEST(Seeds, TheBestIsMarkedOnlyWhenSignificantlyBetter) {
  using Cells = std::vector<std::map<std::uint64_t, double>>;
  // Overlapping by construction: the same values over the seeds in another order have the same
  // mean: never marked, whichever is listed first.
  EXPECT_EQ(experiment::significantly_best(Cells{{{1, 10}, {2, 12}, {3, 14}}, {{1, 14}, {2, 10}, {3, 12}}}, true), -1);
  // Close means, large spread: not significant (p about 0.6).
  EXPECT_EQ(experiment::significantly_best(Cells{{{1, 10}, {2, 15}, {3, 12}}, {{1, 11}, {2, 13}, {3, 14}}}, true), -1);
  // Lower on every seed by about the same amount: marked, the lower for mse, the higher for ssim.
  const Cells clear{{{1, 20}, {2, 22}, {3, 21}}, {{1, 10.1}, {2, 12.0}, {3, 10.9}}, {{1, 30}, {2, 31}, {3, 29}}};
  EXPECT_EQ(experiment::significantly_best(clear, true), 1);
  EXPECT_EQ(experiment::significantly_best(clear, false), 2);
  // One seed each: nothing to test, nothing marked.
  EXPECT_EQ(experiment::significantly_best(Cells{{{1, 5}}, {{1, 9}}}, true), -1);
}

experiment::CellRecord rec(const std::string& method, experiment::Role role, std::uint64_t seed, double mse) {
  experiment::CellRecord r;
  r.scene = "box";
  r.method = method;
  r.role = role;
  r.spp = 4;
  r.seed = seed;
  r.metrics["mse"] = mse;
  return r;
}

TEST(Seeds, Table1GivesMeanAndIntervalAndMarksOnlyTheSignificantBest) {
  experiment::ResultsDocument d;
  d.config.spp = {4};
  d.config.seeds = {1, 2, 3};
  const double a[] = {10, 11, 12}, b[] = {20, 22, 21}, in[] = {50, 52, 51};
  for (std::uint64_t s = 1; s <= 3; ++s) {
    d.records.push_back(rec("input", experiment::Role::Input, s, in[s - 1]));
    d.records.push_back(rec("a", experiment::Role::Method, s, a[s - 1]));
    d.records.push_back(rec("b", experiment::Role::Method, s, b[s - 1]));
  }
  const experiment::Table t = experiment::table1(d, "mse");
  ASSERT_EQ(t.rows.size(), 1u);
  // a: mean 11, s = 1, half width t_{0.975,2} / sqrt 3 = 4.3026527 / 1.7320508 = 2.4841 -> "2.5".
  EXPECT_EQ(t.rows[0][1], "11 ± 2.5 *");
  EXPECT_EQ(t.rows[0][2], "21 ± 2.5");
  EXPECT_THAT(t.note, HasSubstr("t-interval"));
  EXPECT_THAT(t.note, HasSubstr("paired t-test"));
  EXPECT_THAT(t.latex(), HasSubstr("11 $\\pm$ 2.5"));
}

TEST(Seeds, ConfigSeedsEveryCellAndKeepsTheReferenceApart) {
  test::TempDir dir;
  const std::string base = "width = 16\nheight = 12\nscenes = [\"cornell-box\"]\nspp = [2]\nmethods = [\"bilateral\"]\n";
  test::write(dir.file("a.toml"), base + "seeds = [4, 5, 6]\n");
  const auto c = experiment::load_config(dir.file("a.toml"));
  EXPECT_EQ(c.seeds, (std::vector<std::uint64_t>{4, 5, 6}));
  EXPECT_EQ(c.seed, 4u);
  EXPECT_EQ(c.recorded().seeds, c.seeds);
  test::write(dir.file("b.toml"), base + "seeds = [4, 4]\n");
  EXPECT_THAT(test::error_of<InputError>([&] { experiment::load_config(dir.file("b.toml")); }), HasSubstr("twice"));
  test::write(dir.file("c.toml"), base + "seed = 3\nseeds = [4]\n");
  EXPECT_THAT(test::error_of<InputError>([&] { experiment::load_config(dir.file("c.toml")); }), HasSubstr("not both"));
  test::write(dir.file("d.toml"), base + "seeds = [1, 7]\n[reference]\nseed = 7\n");
  EXPECT_THAT(test::error_of<InputError>([&] { experiment::load_config(dir.file("d.toml")); }), HasSubstr("also an input seed"));
}

}  // namespace
}  // namespace dnb
