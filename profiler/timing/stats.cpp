#include "timing/stats.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>

namespace hp {
namespace {

void require_finite(std::span<const double> samples, const char* what) {
  if (samples.empty()) throw std::invalid_argument(std::string(what) + ": empty sample");
  for (double v : samples) {
    if (!std::isfinite(v)) throw std::invalid_argument(std::string(what) + ": non-finite value");
  }
}

// Median of a scratch buffer (reordered in place), type 7 (mean of the middle two for even n).
double median_in_place(std::vector<double>& v) {
  const std::size_t n = v.size();
  const std::size_t mid = n / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
  const double upper = v[mid];
  if (n % 2 == 1) return upper;
  const double lower = *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid));
  return lower + 0.5 * (upper - lower);
}

// Uniform index in [0, bound) from raw 64-bit draws, by rejection: std::uniform_int_distribution
// differs between standard libraries, and a fixed seed must give the same CI everywhere.
std::size_t draw_index(std::mt19937_64& rng, std::size_t bound) {
  const std::uint64_t b = bound;
  const std::uint64_t max = std::numeric_limits<std::uint64_t>::max();
  const std::uint64_t reject_from = max - max % b;
  std::uint64_t x = rng();
  while (x >= reject_from) x = rng();
  return static_cast<std::size_t>(x % b);
}

double binomial_half_pmf(std::size_t n, std::size_t k) {
  const double dn = static_cast<double>(n);
  const double dk = static_cast<double>(k);
  return std::exp(std::lgamma(dn + 1.0) - std::lgamma(dk + 1.0) - std::lgamma(dn - dk + 1.0) - dn * std::log(2.0));
}

// Null distribution of U for sample sizes m, n without ties, as probabilities indexed by U.
// Recurrence on the largest of the m+n values: it is an x with probability m/(m+n) and then beats
// all n y's, otherwise it is a y and adds nothing. Probabilities (not counts) keep every term
// positive and in range, so the tails the p-value needs carry no cancellation.
std::vector<double> exact_u_distribution(std::size_t m, std::size_t n) {
  // prev[j]: distribution for (i-1, j); cur[j]: for (i, j).
  std::vector<std::vector<double>> prev(n + 1, std::vector<double>{1.0});
  for (std::size_t i = 1; i <= m; ++i) {
    std::vector<std::vector<double>> cur(n + 1);
    cur[0] = {1.0};
    for (std::size_t j = 1; j <= n; ++j) {
      std::vector<double> d(i * j + 1, 0.0);
      const double px = static_cast<double>(i) / static_cast<double>(i + j);
      const double py = 1.0 - px;
      const std::vector<double>& a = prev[j];     // (i-1, j), shifted by j
      const std::vector<double>& b = cur[j - 1];  // (i, j-1)
      for (std::size_t u = 0; u < a.size(); ++u) d[u + j] += px * a[u];
      for (std::size_t u = 0; u < b.size(); ++u) d[u] += py * b[u];
      cur[j] = std::move(d);
    }
    prev = std::move(cur);
  }
  return prev[n];
}

// Null distribution of the signed-rank statistic V for n pairs, as probabilities indexed by V: each rank
// 1..n is positive with probability 1/2.
std::vector<double> exact_signed_rank_distribution(std::size_t n) {
  std::vector<double> p(n * (n + 1) / 2 + 1, 0.0);
  p[0] = 1.0;
  std::size_t top = 0;
  for (std::size_t r = 1; r <= n; ++r) {
    top += r;
    for (std::size_t v = top; v >= r; --v) p[v] = 0.5 * (p[v] + p[v - r]);
    for (std::size_t v = r; v-- > 0;) p[v] *= 0.5;
  }
  return p;
}

}  // namespace

double quantile_sorted(std::span<const double> sorted, double p) {
  if (sorted.empty()) throw std::invalid_argument("quantile: empty sample");
  if (!(p >= 0.0 && p <= 1.0)) throw std::invalid_argument("quantile: p outside [0, 1]");
  const double h = static_cast<double>(sorted.size() - 1) * p;
  const auto lo = static_cast<std::size_t>(std::floor(h));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (h - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

double quantile(std::span<const double> samples, double p) {
  std::vector<double> s(samples.begin(), samples.end());
  std::sort(s.begin(), s.end());
  return quantile_sorted(s, p);
}

double binomial_half_cdf(std::size_t n, std::size_t k) {
  if (k >= n) return 1.0;
  double sum = 0.0;
  for (std::size_t i = 0; i <= k; ++i) sum += binomial_half_pmf(n, i);
  return std::min(sum, 1.0);
}

MedianCi median_ci_order_statistic(std::span<const double> sorted, double level) {
  if (sorted.empty()) throw std::invalid_argument("median CI: empty sample");
  if (!(level > 0.0 && level < 1.0)) throw std::invalid_argument("median CI: level outside (0, 1)");
  const std::size_t n = sorted.size();
  const double tail = (1.0 - level) / 2.0;
  // Walk the lower tail: rank r is usable while P(B <= r-1) <= tail; keep r <= n+1-r.
  std::size_t rank = 0;
  double cum = 0.0;
  double cum_at_rank = 0.0;
  for (std::size_t j = 0; j + 1 <= (n + 1) / 2; ++j) {
    cum += binomial_half_pmf(n, j);
    if (cum > tail) break;
    rank = j + 1;
    cum_at_rank = cum;
  }
  MedianCi ci;
  ci.level = level;
  ci.method = "order-statistic";
  if (rank == 0) {
    // Too few samples for this level: the full range is the widest interval there is.
    ci.valid = false;
    ci.lower_rank = 1;
    ci.upper_rank = n;
    ci.low = sorted.front();
    ci.high = sorted.back();
    ci.coverage = 1.0 - 2.0 * binomial_half_pmf(n, 0);
    return ci;
  }
  ci.valid = true;
  ci.lower_rank = rank;
  ci.upper_rank = n + 1 - rank;
  ci.low = sorted[ci.lower_rank - 1];
  ci.high = sorted[ci.upper_rank - 1];
  ci.coverage = 1.0 - 2.0 * cum_at_rank;
  return ci;
}

MedianCi median_ci_bootstrap(std::span<const double> samples, std::size_t resamples, std::uint64_t seed, double level) {
  require_finite(samples, "bootstrap CI");
  if (resamples == 0) throw std::invalid_argument("bootstrap CI: zero resamples");
  if (!(level > 0.0 && level < 1.0)) throw std::invalid_argument("bootstrap CI: level outside (0, 1)");
  std::mt19937_64 rng(seed);
  std::vector<double> scratch(samples.size());
  std::vector<double> medians(resamples);
  for (std::size_t r = 0; r < resamples; ++r) {
    for (double& v : scratch) v = samples[draw_index(rng, samples.size())];
    medians[r] = median_in_place(scratch);
  }
  std::sort(medians.begin(), medians.end());
  const double tail = (1.0 - level) / 2.0;
  MedianCi ci;
  ci.level = level;
  ci.coverage = level;
  ci.method = "bootstrap-percentile";
  ci.low = quantile_sorted(medians, tail);
  ci.high = quantile_sorted(medians, 1.0 - tail);
  // Every resampled median lies within [min, max], which holds the true median only with probability
  // 1 - 2^(1-n): below the level (n < 6 at 95%) the interval cannot have its nominal coverage, so it is
  // flagged like the order-statistic CI.
  ci.valid = 1.0 - std::ldexp(1.0, 1 - int(std::min<std::size_t>(samples.size(), 64))) >= level;
  return ci;
}

Summary summarize(std::span<const double> samples, const SummaryOptions& options) {
  require_finite(samples, "summarize");
  std::vector<double> s(samples.begin(), samples.end());
  std::sort(s.begin(), s.end());
  const std::size_t n = s.size();
  Summary out;
  out.count = n;
  out.min = s.front();
  out.max = s.back();
  out.median = quantile_sorted(s, 0.5);
  out.p95 = quantile_sorted(s, 0.95);
  out.mean = std::accumulate(s.begin(), s.end(), 0.0) / static_cast<double>(n);
  if (n >= 2) {
    // Two-pass variance: frame times are large (1e6 ns) with small spread, where the one-pass
    // formula loses most of its digits.
    double ss = 0.0;
    for (double v : s) ss += (v - out.mean) * (v - out.mean);
    out.stddev = std::sqrt(ss / static_cast<double>(n - 1));
    if (out.mean != 0.0) out.cv = *out.stddev / out.mean;
  }
  out.median_ci = median_ci_order_statistic(s, options.ci_level);
  if (options.bootstrap_resamples > 0) {
    out.median_ci_bootstrap =
        median_ci_bootstrap(samples, options.bootstrap_resamples, options.bootstrap_seed, options.ci_level);
  }
  return out;
}

double normal_cdf(double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); }

double hodges_lehmann_shift(std::span<const double> x, std::span<const double> y) {
  require_finite(x, "Hodges-Lehmann x");
  require_finite(y, "Hodges-Lehmann y");
  std::vector<double> d;
  d.reserve(x.size() * y.size());
  for (double a : x)
    for (double b : y) d.push_back(a - b);
  return median_in_place(d);
}

namespace {

// The Hodges-Lehmann estimate (the median of `values`: pairwise differences or Walsh averages) and its
// interval [v_(k), v_(N+1-k)], which misses the true shift with probability 2 P(S <= k-1) for S the rank
// statistic of null distribution `dist`: the largest k whose two tails stay within 1 - level.
ShiftCi rank_interval(std::vector<double> values, const std::vector<double>& dist, double level, const char* method) {
  std::sort(values.begin(), values.end());
  ShiftCi out;
  out.shift = quantile_sorted(values, 0.5);
  out.ci.level = level;
  out.ci.method = method;
  const double alpha = 1.0 - level;
  double tail = 0.0;
  std::size_t k = 0;
  for (std::size_t s = 0; s < dist.size(); ++s) {
    if (2.0 * (tail + dist[s]) > alpha + 1e-12) break;
    tail += dist[s];
    k = s + 1;
  }
  if (k == 0) return out;
  out.ci.valid = true;
  out.ci.lower_rank = k;
  out.ci.upper_rank = values.size() + 1 - k;
  out.ci.low = values[k - 1];
  out.ci.high = values[values.size() - k];
  out.ci.coverage = 1.0 - 2.0 * tail;
  return out;
}

}  // namespace

SignedRankResult wilcoxon_signed_rank(std::span<const double> d) {
  require_finite(d, "signed-rank d");
  std::vector<double> x;
  for (double v : d)
    if (v != 0.0) x.push_back(v);
  SignedRankResult r;
  r.n = x.size();
  if (x.empty()) return r;
  // Mid-ranks of |x|.
  std::vector<std::size_t> order(x.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return std::abs(x[a]) < std::abs(x[b]); });
  std::vector<double> rank(x.size());
  bool ties = false;
  double tie_term = 0.0;
  for (std::size_t i = 0; i < order.size();) {
    std::size_t j = i;
    while (j + 1 < order.size() && std::abs(x[order[j + 1]]) == std::abs(x[order[i]])) ++j;
    const double t = double(j - i + 1);
    if (t > 1) {
      ties = true;
      tie_term += t * t * t - t;
    }
    for (std::size_t k = i; k <= j; ++k) rank[order[k]] = 0.5 * double(i + j) + 1.0;
    i = j + 1;
  }
  for (std::size_t i = 0; i < x.size(); ++i)
    if (x[i] > 0) r.v += rank[i];
  const double n = double(x.size());
  if (x.size() < 50 && !ties && r.n == d.size()) {
    r.exact = true;
    const std::vector<double> dist = exact_signed_rank_distribution(x.size());
    const auto v = static_cast<std::size_t>(r.v);
    double lower = 0.0, upper = 0.0;
    for (std::size_t k = 0; k <= v; ++k) lower += dist[k];
    for (std::size_t k = v; k < dist.size(); ++k) upper += dist[k];
    r.p_value = std::min(1.0, 2.0 * std::min(lower, upper));
    return r;
  }
  const double mean = n * (n + 1) / 4.0;
  const double var = n * (n + 1) * (2 * n + 1) / 24.0 - tie_term / 48.0;
  if (var <= 0) return r;
  const double diff = r.v - mean;
  const double z = (diff - (diff > 0 ? 0.5 : diff < 0 ? -0.5 : 0.0)) / std::sqrt(var);
  r.p_value = std::min(1.0, 2.0 * std::min(normal_cdf(z), normal_cdf(-z)));
  return r;
}

double signed_rank_min_p(std::size_t n) { return std::min(1.0, 2.0 * std::pow(0.5, double(n))); }

ShiftCi hodges_lehmann_paired_ci(std::span<const double> d, double level) {
  require_finite(d, "Hodges-Lehmann d");
  if (d.empty()) throw std::invalid_argument("Hodges-Lehmann: empty sample");
  if (d.size() >= 50) throw std::invalid_argument("Hodges-Lehmann paired CI: 50 or more values");
  if (!(level > 0.0 && level < 1.0)) throw std::invalid_argument("Hodges-Lehmann CI: level outside (0, 1)");
  std::vector<double> w;
  for (std::size_t i = 0; i < d.size(); ++i)
    for (std::size_t j = i; j < d.size(); ++j) w.push_back(0.5 * (d[i] + d[j]));
  return rank_interval(std::move(w), exact_signed_rank_distribution(d.size()), level, "hodges-lehmann-paired");
}

double odd_even_change(std::span<const double> in_order) {
  std::vector<double> odd, even;
  for (std::size_t i = 0; i < in_order.size(); ++i) {
    if (!(in_order[i] > 0.0)) throw std::invalid_argument("odd_even_change: a sample <= 0");
    (i % 2 ? odd : even).push_back(std::log(in_order[i]));
  }
  if (odd.empty() || even.empty()) return 0.0;
  return std::abs(std::exp(hodges_lehmann_shift(odd, even)) - 1.0);
}

ShiftCi hodges_lehmann_ci(std::span<const double> x, std::span<const double> y, double level) {
  require_finite(x, "Hodges-Lehmann x");
  require_finite(y, "Hodges-Lehmann y");
  if (x.empty() || y.empty()) throw std::invalid_argument("Hodges-Lehmann: empty sample");
  if (x.size() >= 50 || y.size() >= 50) throw std::invalid_argument("Hodges-Lehmann CI: 50 or more values a side");
  if (!(level > 0.0 && level < 1.0)) throw std::invalid_argument("Hodges-Lehmann CI: level outside (0, 1)");
  std::vector<double> d;
  d.reserve(x.size() * y.size());
  for (double a : x)
    for (double b : y) d.push_back(a - b);
  return rank_interval(std::move(d), exact_u_distribution(x.size(), y.size()), level, "hodges-lehmann");
}

MannWhitneyResult mann_whitney_u(std::span<const double> x, std::span<const double> y, bool with_shift) {
  require_finite(x, "Mann-Whitney x");
  require_finite(y, "Mann-Whitney y");
  const std::size_t m = x.size();
  const std::size_t n = y.size();
  const std::size_t total = m + n;

  // Mid-ranks of the pooled sample; tie groups feed the variance correction.
  std::vector<std::pair<double, bool>> pooled;  // value, is_x
  pooled.reserve(total);
  for (double v : x) pooled.emplace_back(v, true);
  for (double v : y) pooled.emplace_back(v, false);
  std::sort(pooled.begin(), pooled.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  double rank_sum_x = 0.0;
  double tie_term = 0.0;  // sum over tie groups of t^3 - t
  bool ties = false;
  for (std::size_t i = 0; i < total;) {
    std::size_t j = i;
    while (j < total && pooled[j].first == pooled[i].first) ++j;
    const double t = static_cast<double>(j - i);
    const double mid_rank = (static_cast<double>(i + 1) + static_cast<double>(j)) / 2.0;
    for (std::size_t k = i; k < j; ++k)
      if (pooled[k].second) rank_sum_x += mid_rank;
    if (j - i > 1) {
      ties = true;
      tie_term += t * t * t - t;
    }
    i = j;
  }

  MannWhitneyResult r;
  const double dm = static_cast<double>(m);
  const double dn = static_cast<double>(n);
  r.u = rank_sum_x - dm * (dm + 1.0) / 2.0;
  if (with_shift) r.hodges_lehmann = hodges_lehmann_shift(x, y);

  if (m < 50 && n < 50 && !ties) {
    r.exact = true;
    const std::vector<double> dist = exact_u_distribution(m, n);
    const auto u = static_cast<std::size_t>(std::llround(r.u));
    double tail = 0.0;
    if (r.u > dm * dn / 2.0) {
      for (std::size_t k = u; k < dist.size(); ++k) tail += dist[k];
    } else {
      for (std::size_t k = 0; k <= u; ++k) tail += dist[k];
    }
    r.p_value = std::min(1.0, 2.0 * tail);
    return r;
  }

  const double centered = r.u - dm * dn / 2.0;
  const double dt = static_cast<double>(total);
  const double sigma = std::sqrt(dm * dn / 12.0 * ((dt + 1.0) - tie_term / (dt * (dt - 1.0))));
  if (!(sigma > 0.0)) {
    // Every value equal: no evidence of any shift.
    r.p_value = 1.0;
    return r;
  }
  const double correction = centered > 0.0 ? 0.5 : (centered < 0.0 ? -0.5 : 0.0);
  r.z = (centered - correction) / sigma;
  r.p_value = std::min(1.0, 2.0 * std::min(normal_cdf(r.z), normal_cdf(-r.z)));
  return r;
}

double mann_whitney_min_p(std::size_t n, std::size_t m) {
  double c = 1.0;
  for (std::size_t i = 1; i <= std::min(n, m); ++i) c = c * double(n + m - std::min(n, m) + i) / double(i);
  return std::min(1.0, 2.0 / c);
}

std::vector<double> holm_adjust(std::span<const double> p_values) {
  const std::size_t m = p_values.size();
  for (double p : p_values) {
    if (!(p >= 0.0 && p <= 1.0)) throw std::invalid_argument("Holm: p-value outside [0, 1]");
  }
  std::vector<std::size_t> order(m);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return p_values[a] < p_values[b]; });
  std::vector<double> adjusted(m);
  double running = 0.0;
  for (std::size_t i = 0; i < m; ++i) {
    // The i-th smallest p is tested at alpha / (m - i); the running max keeps the step-down monotone.
    const double a = std::min(1.0, static_cast<double>(m - i) * p_values[order[i]]);
    running = std::max(running, a);
    adjusted[order[i]] = running;
  }
  return adjusted;
}

}  // namespace hp
