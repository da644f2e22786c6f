// Statistics against values computed by hand (the arithmetic is in the comments) and binomial tables.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "timing/stats.hpp"

namespace hp {
namespace {

TEST(Quantile, Type7MatchesR) {
  // R: quantile(1:10, 0.95) == 9.55 (h = 9 * 0.95 = 8.55 -> 9 + 0.55 * (10 - 9)).
  std::vector<double> v{10, 9, 8, 7, 6, 5, 4, 3, 2, 1};
  EXPECT_DOUBLE_EQ(quantile(v, 0.95), 9.55);
  EXPECT_DOUBLE_EQ(quantile(v, 0.5), 5.5);
  EXPECT_DOUBLE_EQ(quantile(v, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(quantile(v, 1.0), 10.0);
  EXPECT_DOUBLE_EQ(quantile(v, 0.25), 3.25);  // h = 2.25 -> 3 + 0.25
  EXPECT_THROW(quantile(v, 1.5), std::invalid_argument);
}

TEST(Summarize, OddCount) {
  // Sorted 1..5: mean 3; squared deviations 4+1+0+1+4 = 10, / (5-1) = 2.5.
  // p95: h = 4 * 0.95 = 3.8 -> 4 + 0.8 * (5 - 4) = 4.8.
  const std::vector<double> v{5, 1, 4, 2, 3};
  const Summary s = summarize(v);
  EXPECT_EQ(s.count, 5u);
  EXPECT_DOUBLE_EQ(s.min, 1);
  EXPECT_DOUBLE_EQ(s.max, 5);
  EXPECT_DOUBLE_EQ(s.median, 3);
  EXPECT_DOUBLE_EQ(s.mean, 3);
  EXPECT_DOUBLE_EQ(s.p95, 4.8);
  ASSERT_TRUE(s.stddev.has_value());
  EXPECT_DOUBLE_EQ(*s.stddev, std::sqrt(2.5));
  ASSERT_TRUE(s.cv.has_value());
  EXPECT_DOUBLE_EQ(*s.cv, std::sqrt(2.5) / 3.0);
  // n = 5 < 6: no 95% interval exists; the full range reaches 1 - 2/2^5 = 0.9375.
  EXPECT_FALSE(s.median_ci.valid);
  EXPECT_DOUBLE_EQ(s.median_ci.low, 1);
  EXPECT_DOUBLE_EQ(s.median_ci.high, 5);
  EXPECT_DOUBLE_EQ(s.median_ci.coverage, 0.9375);
  EXPECT_EQ(s.median_ci.method, "order-statistic");
  EXPECT_FALSE(s.median_ci_bootstrap.has_value());
}

TEST(Summarize, EvenCountWithTies) {
  // {10, 20, 20, 40}: median h = 1.5 -> 20; mean 22.5; p95 h = 2.85 -> 20 + 0.85 * 20 = 37.
  // Deviations -12.5, -2.5, -2.5, 17.5: squares sum 475, / 3.
  const std::vector<double> v{40, 20, 10, 20};
  const Summary s = summarize(v);
  EXPECT_DOUBLE_EQ(s.median, 20);
  EXPECT_DOUBLE_EQ(s.mean, 22.5);
  EXPECT_DOUBLE_EQ(s.p95, 37);
  EXPECT_DOUBLE_EQ(*s.stddev, std::sqrt(475.0 / 3.0));
}

TEST(Summarize, SixIsTheSmallestCountWithA95Interval) {
  // n = 6: P(B <= 0) = 1/64 <= 0.025 < P(B <= 1) = 7/64 -> ranks 1 and 6, coverage 62/64.
  // Median of 1..6: h = 2.5 -> 3.5; p95 h = 4.75 -> 5.75.
  const std::vector<double> v{6, 5, 4, 3, 2, 1};
  const Summary s = summarize(v);
  EXPECT_DOUBLE_EQ(s.median, 3.5);
  EXPECT_DOUBLE_EQ(s.p95, 5.75);
  EXPECT_TRUE(s.median_ci.valid);
  EXPECT_EQ(s.median_ci.lower_rank, 1u);
  EXPECT_EQ(s.median_ci.upper_rank, 6u);
  EXPECT_DOUBLE_EQ(s.median_ci.coverage, 62.0 / 64.0);
}

TEST(Summarize, OneSample) {
  const std::vector<double> v{7};
  const Summary s = summarize(v);
  EXPECT_EQ(s.count, 1u);
  EXPECT_DOUBLE_EQ(s.median, 7);
  EXPECT_DOUBLE_EQ(s.p95, 7);
  EXPECT_FALSE(s.stddev.has_value());  // n - 1 = 0: undefined, not 0
  EXPECT_FALSE(s.cv.has_value());
  EXPECT_FALSE(s.median_ci.valid);
  EXPECT_DOUBLE_EQ(s.median_ci.low, 7);
  EXPECT_DOUBLE_EQ(s.median_ci.high, 7);
  EXPECT_DOUBLE_EQ(s.median_ci.coverage, 0.0);  // 1 - 2 * P(B <= 0) = 1 - 2 * 0.5
}

TEST(Summarize, TwoSamples) {
  // {3, 9}: median 6, p95 = 3 + 0.95 * 6 = 8.7, stddev sqrt((9 + 9) / 1).
  const std::vector<double> v{9, 3};
  const Summary s = summarize(v);
  EXPECT_DOUBLE_EQ(s.median, 6);
  EXPECT_DOUBLE_EQ(s.mean, 6);
  EXPECT_DOUBLE_EQ(s.p95, 8.7);
  EXPECT_DOUBLE_EQ(*s.stddev, std::sqrt(18.0));
  EXPECT_FALSE(s.median_ci.valid);
  EXPECT_DOUBLE_EQ(s.median_ci.coverage, 0.5);
}

TEST(Summarize, ZeroMeanHasNoCv) {
  const std::vector<double> v{-1, 1};
  const Summary s = summarize(v);
  EXPECT_TRUE(s.stddev.has_value());
  EXPECT_FALSE(s.cv.has_value());
}

TEST(Summarize, RejectsEmptyAndNonFinite) {
  EXPECT_THROW(summarize(std::vector<double>{}), std::invalid_argument);
  EXPECT_THROW(summarize(std::vector<double>{1, NAN, 3}), std::invalid_argument);
  EXPECT_THROW(summarize(std::vector<double>{1, INFINITY}), std::invalid_argument);
}

TEST(BinomialHalf, CdfMatchesExactFractions) {
  // Exact: C(10,0)+C(10,1) = 11 over 2^10; C(50, <=17) summed = 18486790962201 over 2^50.
  EXPECT_NEAR(binomial_half_cdf(10, 1), 11.0 / 1024.0, 1e-15);
  EXPECT_NEAR(binomial_half_cdf(10, 2), 56.0 / 1024.0, 1e-15);
  EXPECT_NEAR(binomial_half_cdf(50, 17), 18486790962201.0 / 1125899906842624.0, 1e-14);
  EXPECT_DOUBLE_EQ(binomial_half_cdf(7, 7), 1.0);
  EXPECT_NEAR(binomial_half_cdf(1000, 499), 0.5 - 0.5 * 0.025225018178360804, 1e-12);
}

TEST(MedianCi, RanksForTenMatchTables) {
  // Binomial tables (e.g. Conover, Practical Nonparametric Statistics, table A3): for n = 10 the
  // 95% interval is [x(2), x(9)] with coverage 1 - 2 * 11/1024 = 0.9785.
  std::vector<double> v{30, 100, 10, 60, 90, 20, 50, 80, 40, 70};
  const Summary s = summarize(v);
  EXPECT_TRUE(s.median_ci.valid);
  EXPECT_EQ(s.median_ci.lower_rank, 2u);
  EXPECT_EQ(s.median_ci.upper_rank, 9u);
  EXPECT_DOUBLE_EQ(s.median_ci.low, 20);
  EXPECT_DOUBLE_EQ(s.median_ci.high, 90);
  EXPECT_NEAR(s.median_ci.coverage, 0.978515625, 1e-12);
}

TEST(MedianCi, RanksForFiftyMatchTables) {
  // n = 50: P(B <= 17) = 0.01642 <= 0.025 < P(B <= 18) = 0.03245 -> [x(18), x(33)], coverage 0.96716.
  std::vector<double> v;
  for (int i = 50; i >= 1; --i) v.push_back(i);
  const Summary s = summarize(v);
  EXPECT_EQ(s.median_ci.lower_rank, 18u);
  EXPECT_EQ(s.median_ci.upper_rank, 33u);
  EXPECT_DOUBLE_EQ(s.median_ci.low, 18);
  EXPECT_DOUBLE_EQ(s.median_ci.high, 33);
  EXPECT_NEAR(s.median_ci.coverage, 0.9671608624357315, 1e-12);
}

TEST(MedianCi, OtherLevels) {
  // 90% for n = 10: tail 0.05; P(B <= 1) = 0.0107 <= 0.05 < P(B <= 2) = 0.0547 -> still ranks 2, 9.
  // 50% for n = 10: tail 0.25; P(B <= 3) = 176/1024 = 0.172 <= 0.25 < P(B <= 4) = 0.377 -> 4, 7.
  std::vector<double> v{1, 2, 3, 4, 5, 6, 7, 8, 9, 10};
  EXPECT_EQ(median_ci_order_statistic(v, 0.90).lower_rank, 2u);
  const MedianCi half = median_ci_order_statistic(v, 0.50);
  EXPECT_EQ(half.lower_rank, 4u);
  EXPECT_EQ(half.upper_rank, 7u);
}

TEST(MedianCi, CoversTheTrueMedianAtLeastAtItsLevel) {
  // Simulation: exponential(1) has median ln 2. n = 20 gives ranks 6 and 15, coverage 0.9586; over
  // 4000 fixed-seed trials the hit rate stays within a few standard errors (0.003) of that.
  std::mt19937_64 rng(12345);
  std::exponential_distribution<double> dist(1.0);
  const double true_median = std::log(2.0);
  int hits = 0;
  const int trials = 4000;
  std::vector<double> v(20);
  for (int t = 0; t < trials; ++t) {
    for (double& x : v) x = dist(rng);
    std::sort(v.begin(), v.end());
    const MedianCi ci = median_ci_order_statistic(v);
    if (ci.low <= true_median && true_median <= ci.high) ++hits;
  }
  const double rate = static_cast<double>(hits) / trials;
  EXPECT_GT(rate, 0.945);
  EXPECT_LT(rate, 0.975);
}

// Audit find (2026-11-30): every resampled median lies in [min, max], which holds the median only with
// probability 1 - 2^(1-n): a bootstrap interval of 5 values cannot have 95% coverage and says so.
TEST(MedianCi, BootstrapOfFewValuesIsFlagged) {
  SummaryOptions opt;
  opt.bootstrap_resamples = 500;
  for (std::size_t n : {3u, 5u, 6u}) {
    std::vector<double> v;
    for (std::size_t i = 1; i <= n; ++i) v.push_back(double(i));
    const Summary s = summarize(v, opt);
    ASSERT_TRUE(s.median_ci_bootstrap.has_value());
    EXPECT_EQ(s.median_ci_bootstrap->valid, n >= 6) << n;
    EXPECT_EQ(s.median_ci.valid, n >= 6) << n;
  }
}

TEST(MedianCi, BootstrapIsDeterministicAndPlausible) {
  std::vector<double> v;
  for (int i = 1; i <= 50; ++i) v.push_back(i);
  SummaryOptions opt;
  opt.bootstrap_resamples = 2000;
  const Summary a = summarize(v, opt);
  const Summary b = summarize(v, opt);
  ASSERT_TRUE(a.median_ci_bootstrap.has_value());
  EXPECT_EQ(*a.median_ci_bootstrap, *b.median_ci_bootstrap);  // fixed seed
  const MedianCi& ci = *a.median_ci_bootstrap;
  EXPECT_EQ(ci.method, "bootstrap-percentile");
  EXPECT_TRUE(ci.valid);
  // The order-statistic interval is [18, 33]; the bootstrap one should be of the same size.
  EXPECT_LE(ci.low, a.median);
  EXPECT_GE(ci.high, a.median);
  EXPECT_GT(ci.low, 14.0);
  EXPECT_LT(ci.high, 37.0);
  EXPECT_GT(ci.high - ci.low, 5.0);

  // Another seed draws other resamples.
  opt.bootstrap_seed = 99;
  EXPECT_NE(summarize(v, opt).median_ci_bootstrap, a.median_ci_bootstrap);

  // A constant sample has a zero-width interval.
  const std::vector<double> c(10, 4.0);
  const MedianCi cc = median_ci_bootstrap(c, 100, 1);
  EXPECT_DOUBLE_EQ(cc.low, 4.0);
  EXPECT_DOUBLE_EQ(cc.high, 4.0);
}

TEST(Holm, FixedList) {
  // Sorted p: 0.005, 0.01, 0.03, 0.04 times 4, 3, 2, 1 = 0.02, 0.03, 0.06, 0.04; running max
  // -> 0.02, 0.03, 0.06, 0.06; back in input order. Same as R's p.adjust(..., "holm").
  const std::vector<double> p{0.01, 0.04, 0.03, 0.005};
  const std::vector<double> adj = holm_adjust(p);
  ASSERT_EQ(adj.size(), 4u);
  EXPECT_DOUBLE_EQ(adj[0], 0.03);
  EXPECT_DOUBLE_EQ(adj[1], 0.06);
  EXPECT_DOUBLE_EQ(adj[2], 0.06);
  EXPECT_DOUBLE_EQ(adj[3], 0.02);
}

TEST(Holm, CapsAtOneAndHandlesEdges) {
  // 0.5 * 2 = 1.0, then max(1.0, 0.6) = 1.0.
  const std::vector<double> adj = holm_adjust(std::vector<double>{0.6, 0.5});
  EXPECT_DOUBLE_EQ(adj[0], 1.0);
  EXPECT_DOUBLE_EQ(adj[1], 1.0);
  EXPECT_TRUE(holm_adjust(std::vector<double>{}).empty());
  EXPECT_DOUBLE_EQ(holm_adjust(std::vector<double>{0.2})[0], 0.2);
  EXPECT_THROW(holm_adjust(std::vector<double>{0.1, 1.5}), std::invalid_argument);
}

}  // namespace
}  // namespace hp
