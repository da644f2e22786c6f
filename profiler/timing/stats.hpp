// Descriptive statistics and the rank tests the timing results and the regression gate use.
//
// Why no library: Debian 12 has no maintained C++ package with a Mann-Whitney test, Holm correction
// or an order-statistic median CI (scythestat, apophenia and oakleaf cover other ground), and the two
// distributions needed here are short and exact: the standard normal CDF is std::erfc, and the
// binomial(n, 1/2) CDF is a sum of exact pmfs. Boost.Math (libboost-dev, not installed) would only
// replace those two lines, so it is not worth a new dependency.
//
// Conventions (all durations are nanoseconds as double, but nothing here depends on the unit):
//  - quantile: Hyndman & Fan type 7 (R's default, NumPy's "linear"): h = (n-1)p on the sorted
//    sample, linear interpolation between x[floor(h)] and x[ceil(h)] (0-based).
//  - standard deviation: sample (n-1 denominator); absent for n < 2. CV = stddev / mean, absent when
//    the standard deviation is absent or the mean is 0.
//  - median CI: distribution-free, by order statistics (see median_ci_order_statistic).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace hp {

// A confidence interval of the median. `lower_rank`/`upper_rank` are the 1-based order statistics
// used (0 for the bootstrap). `coverage` is the interval's actual coverage probability (order
// statistic: exact under continuity, always >= level when `valid`; bootstrap: nominal level).
// `valid` is false when n is too small to reach `level` at all: the interval is then the full range
// [min, max] and `coverage` says what that range does reach (1 - 2^(1-n)).
struct MedianCi {
  double low = 0.0;
  double high = 0.0;
  double level = 0.95;
  double coverage = 0.0;
  std::size_t lower_rank = 0;
  std::size_t upper_rank = 0;
  bool valid = false;
  std::string method;  // "order-statistic" or "bootstrap-percentile"

  bool operator==(const MedianCi&) const = default;
};

struct Summary {
  std::size_t count = 0;
  double min = 0.0;
  double max = 0.0;
  double median = 0.0;
  double mean = 0.0;
  double p95 = 0.0;                             // type-7 quantile at 0.95
  std::optional<double> stddev;                 // sample (n-1); absent for n < 2
  std::optional<double> cv;                     // stddev / mean; absent with stddev or when mean == 0
  MedianCi median_ci;                           // order-statistic, 95%
  std::optional<MedianCi> median_ci_bootstrap;  // second method, when asked for

  bool operator==(const Summary&) const = default;
};

struct SummaryOptions {
  double ci_level = 0.95;
  // Bootstrap resamples for the second CI method; 0 turns it off. Percentile method, fixed seed, so
  // the same samples always give the same interval.
  std::size_t bootstrap_resamples = 0;
  std::uint64_t bootstrap_seed = 0x68796272696470ull;  // "hybridp"
};

// Type-7 quantile of an already sorted, non-empty sample; p in [0, 1].
double quantile_sorted(std::span<const double> sorted, double p);

// Type-7 quantile of any non-empty sample (copies and sorts).
double quantile(std::span<const double> samples, double p);

// Every field of Summary from a non-empty sample. Throws std::invalid_argument on an empty sample or
// a non-finite value (a NaN would silently corrupt the order statistics).
Summary summarize(std::span<const double> samples, const SummaryOptions& options = {});

// P(B <= k) for B ~ binomial(n, 1/2); exact to double rounding (pmfs summed from log-gamma).
double binomial_half_cdf(std::size_t n, std::size_t k);

// Distribution-free CI of the median: with B ~ binomial(n, 1/2), the largest rank r with
// P(B <= r-1) <= (1-level)/2 gives [x_(r), x_(n+1-r)] (1-based order statistics) with coverage
// 1 - 2 P(B <= r-1) >= level. For level 0.95 that needs n >= 6; below, no rank qualifies and the
// result is the full range with valid = false. `sorted` must be sorted and non-empty.
MedianCi median_ci_order_statistic(std::span<const double> sorted, double level = 0.95);

// Percentile bootstrap CI of the median with a fixed seed (mt19937_64, unbiased index draws by
// rejection, so it does not depend on the standard library's distributions). Non-empty sample.
MedianCi median_ci_bootstrap(std::span<const double> samples, std::size_t resamples, std::uint64_t seed,
                             double level = 0.95);

// Standard normal CDF.
double normal_cdf(double z);

// Two-sided Mann-Whitney U (Wilcoxon rank-sum) test, following R's wilcox.test(x, y) defaults:
// exact null distribution when both samples have fewer than 50 values and there are no ties;
// otherwise the normal approximation with tie correction and continuity correction.
struct MannWhitneyResult {
  double u = 0.0;        // U of x: pairs with x_i > y_j, plus half the tied pairs (R's W)
  double p_value = 1.0;  // two-sided
  bool exact = false;
  double z = 0.0;  // continuity-corrected z of the normal approximation; 0 when exact
  // Median of all x_i - y_j, the location shift of x relative to y: only with `with_shift` (it holds all
  // m * n differences: 800 MB for 10,000 frames a side), else 0.
  double hodges_lehmann = 0.0;
};

// Both samples non-empty and finite, else std::invalid_argument.
MannWhitneyResult mann_whitney_u(std::span<const double> x, std::span<const double> y, bool with_shift = false);

// The smallest two-sided p-value the exact U test can give with n and m samples and no ties: 2 / C(n+m, n).
// Where it exceeds alpha, no comparison of that size can be significant.
double mann_whitney_min_p(std::size_t n, std::size_t m);

// Hodges-Lehmann two-sample shift: median of the m*n differences x_i - y_j.
double hodges_lehmann_shift(std::span<const double> x, std::span<const double> y);

// Hodges-Lehmann shift of x relative to y with its distribution-free confidence interval: the k-th
// smallest and k-th largest of the m*n differences x_i - y_j, k from the exact null distribution of U
// (Bauer 1972; R's wilcox.test(conf.int = TRUE) for small samples), so that coverage >= level. Both
// samples under 50 values. `ci.valid` is false when the samples are too small for that level (no k >= 1
// reaches it): e.g. 3 against 3 for 95%.
struct ShiftCi {
  double shift = 0.0;
  MedianCi ci;  ///< low/high of the shift; lower_rank/upper_rank index the sorted differences (1-based)
};
ShiftCi hodges_lehmann_ci(std::span<const double> x, std::span<const double> y, double level = 0.95);

// Two-sided Wilcoxon signed-rank test of paired differences d (e.g. log b_r - log a_r per round),
// following R's wilcox.test(d): zeros dropped; the exact null distribution of V (the sum of the ranks of
// the positive differences) with fewer than 50 nonzero differences and no tied |d|, else the normal
// approximation with tie and continuity correction. p = 1 and n = 0 when every difference is zero.
struct SignedRankResult {
  double v = 0.0;        // sum of the ranks of the positive differences
  double p_value = 1.0;  // two-sided
  std::size_t n = 0;     // nonzero differences
  bool exact = false;
};
SignedRankResult wilcoxon_signed_rank(std::span<const double> d);

// The smallest two-sided p-value the exact signed-rank test can give with n pairs: 2 / 2^n.
double signed_rank_min_p(std::size_t n);

// One-sample Hodges-Lehmann estimate of the centre of d (the median of the Walsh averages
// (d_i + d_j) / 2, i <= j) with its distribution-free interval: the k-th smallest and largest Walsh
// averages, k from the exact signed-rank distribution (R's wilcox.test(d, conf.int = TRUE)), coverage >=
// level. Fewer than 50 values; ci.valid false when too few for that level (fewer than 6 at 95%).
ShiftCi hodges_lehmann_paired_ci(std::span<const double> d, double level = 0.95);

// A measured A/A of one series of positive samples taken in time order (interleaved rounds, alternating
// processes): |r - 1| for r the Hodges-Lehmann ratio of its odd-indexed to its even-indexed samples (the
// shift of their logarithms). Two halves interleaved in time, as two compared sides are: what the series
// moves without any change. 0 with fewer than 2 samples; std::invalid_argument for a sample <= 0.
double odd_even_change(std::span<const double> in_order);

// Holm's step-down adjustment (R's p.adjust(p, "holm")); the result is in the input's order.
// Reject hypothesis i at family-wise level alpha when adjusted[i] <= alpha.
std::vector<double> holm_adjust(std::span<const double> p_values);

}  // namespace hp
