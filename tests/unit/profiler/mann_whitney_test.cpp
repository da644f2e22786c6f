// Mann-Whitney U test and Hodges-Lehmann shift against textbook values and brute-force enumeration.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "timing/stats.hpp"

namespace hp {
namespace {

TEST(MannWhitney, CompleteSeparationIsExact) {
  // All 20 = C(6,3) arrangements are equally likely under H0; only one has U = 0, so the two-sided
  // p is 2/20.
  const std::vector<double> x{1, 2, 3};
  const std::vector<double> y{4, 5, 6};
  const MannWhitneyResult r = mann_whitney_u(x, y);
  EXPECT_TRUE(r.exact);
  EXPECT_DOUBLE_EQ(r.u, 0.0);
  EXPECT_NEAR(r.p_value, 0.1, 1e-12);
  const MannWhitneyResult s = mann_whitney_u(y, x);  // symmetric: U = 9 = m*n, same p
  EXPECT_DOUBLE_EQ(s.u, 9.0);
  EXPECT_NEAR(s.p_value, 0.1, 1e-12);
  // 4 vs 4: 2 / C(8,4) = 2/70.
  EXPECT_NEAR(mann_whitney_u(std::vector<double>{1, 2, 3, 4}, std::vector<double>{5, 6, 7, 8}).p_value, 2.0 / 70.0,
              1e-12);
}

TEST(MannWhitney, HollanderWolfeExampleFromRDocs) {
  // R's ?wilcox.test example (Hollander & Wolfe 1973, p. 69): wilcox.test(x, y, alternative = "g")
  // gives W = 35, p = 0.1272 (exact). Enumerating the 3003 arrangements: 382 have U >= 35, so the
  // two-sided p is 2 * 382 / 3003 = 0.254412. R's conf.int estimate of the shift is 0.305.
  const std::vector<double> x{0.80, 0.83, 1.89, 1.04, 1.45, 1.38, 1.91, 1.64, 0.73, 1.46};
  const std::vector<double> y{1.15, 0.88, 0.90, 0.74, 1.21};
  const MannWhitneyResult r = mann_whitney_u(x, y, true);
  EXPECT_TRUE(r.exact);
  EXPECT_DOUBLE_EQ(r.u, 35.0);
  EXPECT_NEAR(r.p_value, 2.0 * 382.0 / 3003.0, 1e-12);
  EXPECT_NEAR(r.hodges_lehmann, 0.305, 1e-12);
  EXPECT_DOUBLE_EQ(mann_whitney_u(x, y).hodges_lehmann, 0.0) << "the shift is computed only when asked";
}

// Brute force: every way to place m x-ranks among m+n positions, U counted directly.
double brute_force_two_sided_p(std::size_t m, std::size_t n, std::size_t u_obs) {
  std::vector<bool> is_x(m + n, false);
  std::fill(is_x.end() - static_cast<std::ptrdiff_t>(m), is_x.end(), true);
  std::size_t total = 0, le = 0, ge = 0;
  do {
    std::size_t u = 0, ys = 0;
    for (bool b : is_x) {
      if (b)
        u += ys;
      else
        ++ys;
    }
    ++total;
    if (u <= u_obs) ++le;
    if (u >= u_obs) ++ge;
  } while (std::next_permutation(is_x.begin(), is_x.end()));
  const double half = static_cast<double>(m * n) / 2.0;
  const double tail = static_cast<double>(static_cast<double>(u_obs) > half ? ge : le) / static_cast<double>(total);
  return std::min(1.0, 2.0 * tail);
}

TEST(MannWhitney, ExactDistributionMatchesEnumeration) {
  // x takes the values of y shifted: every U from 0 to 20 for m = 4, n = 5.
  const std::vector<double> y{10, 20, 30, 40, 50};
  for (int shift = 0; shift <= 60; shift += 3) {
    const std::vector<double> x{5.5 + shift, 12.5 + shift, 17.5 + shift, 33.5 + shift};
    const MannWhitneyResult r = mann_whitney_u(x, y);
    ASSERT_TRUE(r.exact);
    EXPECT_NEAR(r.p_value, brute_force_two_sided_p(4, 5, static_cast<std::size_t>(r.u)), 1e-12) << "U = " << r.u;
  }
}

TEST(MannWhitney, TiesUseNormalApproximationWithTieCorrection) {
  // x = {1,2,2,3}, y = {2,3,4,5}. Mid-ranks: 1 -> 1; the three 2s -> 3; the two 3s -> 5.5; 4 -> 7;
  // 5 -> 8. R_x = 1 + 3 + 3 + 5.5 = 12.5, U = 12.5 - 10 = 2.5. Tie term (27-3) + (8-2) = 30.
  // sigma = sqrt(16/12 * (9 - 30/56)) = 3.3594217; z = (2.5 - 8 + 0.5) / sigma = -1.4883514;
  // p = 2 * Phi(z) = 0.1366582 (R: wilcox.test(x, y, exact = FALSE) with its default correction).
  const std::vector<double> x{1, 2, 2, 3};
  const std::vector<double> y{2, 3, 4, 5};
  const MannWhitneyResult r = mann_whitney_u(x, y);
  EXPECT_FALSE(r.exact);
  EXPECT_DOUBLE_EQ(r.u, 2.5);
  EXPECT_NEAR(r.z, -1.4883513944689681, 1e-9);
  EXPECT_NEAR(r.p_value, 0.13665824773814753, 1e-9);
}

TEST(MannWhitney, LargeSamplesUseNormalApproximation) {
  // x = odd numbers 1..119, y = even 2..120: U = 0 + 1 + ... + 59 = 1770, mn/2 = 1800,
  // sigma = sqrt(3600/12 * 121) = 190.52559; z = (-30 + 0.5) / sigma = -0.1548348; p = 0.8769515.
  std::vector<double> x, y;
  for (int i = 1; i <= 120; ++i) (i % 2 == 1 ? x : y).push_back(i);
  const MannWhitneyResult r = mann_whitney_u(x, y);
  EXPECT_FALSE(r.exact);
  EXPECT_DOUBLE_EQ(r.u, 1770.0);
  EXPECT_NEAR(r.p_value, 0.8769515201868247, 1e-9);
  // A clear shift is clearly detected.
  std::vector<double> shifted = y;
  for (double& v : shifted) v += 60;
  EXPECT_LT(mann_whitney_u(x, shifted).p_value, 1e-10);
}

TEST(MannWhitney, AllEqualGivesNoEvidence) {
  const std::vector<double> a(5, 3.0);
  const MannWhitneyResult r = mann_whitney_u(a, a, true);
  EXPECT_DOUBLE_EQ(r.u, 12.5);
  EXPECT_DOUBLE_EQ(r.p_value, 1.0);
  EXPECT_DOUBLE_EQ(r.hodges_lehmann, 0.0);
}

TEST(MannWhitney, RejectsEmpty) {
  EXPECT_THROW(mann_whitney_u(std::vector<double>{}, std::vector<double>{1}), std::invalid_argument);
  EXPECT_THROW(mann_whitney_u(std::vector<double>{1}, std::vector<double>{NAN}), std::invalid_argument);
}

TEST(HodgesLehmann, MedianOfPairwiseDifferences) {
  // x - y over {1,2} x {0,5}: 1, -4, 2, -3 -> sorted -4, -3, 1, 2 -> median -1.
  EXPECT_DOUBLE_EQ(hodges_lehmann_shift(std::vector<double>{1, 2}, std::vector<double>{0, 5}), -1.0);
  // A pure shift is recovered exactly.
  EXPECT_DOUBLE_EQ(hodges_lehmann_shift(std::vector<double>{11, 13, 17}, std::vector<double>{1, 3, 7}), 10.0);
}

// The interval is the k-th smallest and k-th largest pairwise difference, k from the exact U distribution:
// for 5 against 5 at 95%, k = 3 (2 P(U <= 2) = 8/252 <= 0.05 < 2 P(U <= 3) = 14/252), as R's
// wilcox.test(conf.int = TRUE) picks it.
TEST(HodgesLehmann, ConfidenceIntervalFromTheExactUDistribution) {
  const std::vector<double> y = {1, 2, 3, 4, 5}, x = {11, 12, 13, 14, 15};
  // x - y = 10 + (i - j): 6 once, 7 twice, 8 three times, ... 14 once.
  const ShiftCi s = hodges_lehmann_ci(x, y);
  EXPECT_DOUBLE_EQ(s.shift, 10.0);
  ASSERT_TRUE(s.ci.valid);
  EXPECT_EQ(s.ci.lower_rank, 3u);
  EXPECT_EQ(s.ci.upper_rank, 23u);
  EXPECT_DOUBLE_EQ(s.ci.low, 7.0);
  EXPECT_DOUBLE_EQ(s.ci.high, 13.0);
  EXPECT_NEAR(s.ci.coverage, 1.0 - 8.0 / 252.0, 1e-12);
  // Three against three: even the widest interval covers only 90%.
  EXPECT_FALSE(hodges_lehmann_ci(std::vector<double>{4, 5, 6}, std::vector<double>{1, 2, 3}).ci.valid);
  EXPECT_THROW(hodges_lehmann_ci(std::vector<double>{}, y), std::invalid_argument);
}

// Signed-rank test of paired differences, against values R gives: wilcox.test(1:5) p = 0.0625 (V = 15, the
// smallest p 5 pairs allow); wilcox.test(c(1, -2, 3, 4, 5, 6)) p = 0.09375 (V = 19: 3 of the 64 sign
// patterns have V <= 2); zeros dropped.
TEST(SignedRank, ExactPValuesAndDirection) {
  const SignedRankResult five = wilcoxon_signed_rank(std::vector<double>{1, 2, 3, 4, 5});
  EXPECT_TRUE(five.exact);
  EXPECT_DOUBLE_EQ(five.v, 15.0);
  EXPECT_DOUBLE_EQ(five.p_value, 0.0625);
  EXPECT_DOUBLE_EQ(signed_rank_min_p(5), 0.0625);
  const SignedRankResult six = wilcoxon_signed_rank(std::vector<double>{1, -2, 3, 4, 5, 6});
  EXPECT_DOUBLE_EQ(six.v, 19.0);
  EXPECT_NEAR(six.p_value, 6.0 / 64.0, 1e-15);
  const SignedRankResult negative = wilcoxon_signed_rank(std::vector<double>{-1, -2, -3, -4, -5, -6});
  EXPECT_DOUBLE_EQ(negative.v, 0.0);
  EXPECT_NEAR(negative.p_value, 2.0 / 64.0, 1e-15);
  const SignedRankResult zeros = wilcoxon_signed_rank(std::vector<double>{0, 0, 0});
  EXPECT_EQ(zeros.n, 0u);
  EXPECT_DOUBLE_EQ(zeros.p_value, 1.0);
  // A zero drops out and makes the test approximate, as in R.
  EXPECT_FALSE(wilcoxon_signed_rank(std::vector<double>{0, 1, 2, 3, 4, 5, 6}).exact);
}

// The paired interval is the k-th smallest and largest Walsh average: for 6 pairs at 95%, k = 1
// (2 P(V <= 0) = 2/64 <= 0.05 < 2 P(V <= 1) = 4/64).
TEST(HodgesLehmann, PairedConfidenceIntervalFromWalshAverages) {
  const ShiftCi s = hodges_lehmann_paired_ci(std::vector<double>{1, 2, 3, 4, 5, 6});
  EXPECT_DOUBLE_EQ(s.shift, 3.5);
  ASSERT_TRUE(s.ci.valid);
  EXPECT_EQ(s.ci.lower_rank, 1u);
  EXPECT_EQ(s.ci.upper_rank, 21u);
  EXPECT_DOUBLE_EQ(s.ci.low, 1.0);
  EXPECT_DOUBLE_EQ(s.ci.high, 6.0);
  EXPECT_NEAR(s.ci.coverage, 1.0 - 2.0 / 64.0, 1e-12);
  EXPECT_FALSE(hodges_lehmann_paired_ci(std::vector<double>{1, 2, 3, 4, 5}).ci.valid) << "5 pairs: at most 93.75%";
}

}  // namespace
}  // namespace hp
