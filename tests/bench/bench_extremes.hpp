// The fastest and the slowest repetition of a row, beside Google Benchmark's mean, median and stddev.
//
// With --benchmark_repetitions=N a row registered through with_extremes() also prints `<row>_min` and
// `<row>_max`: each statistic is applied to the time column and to every counter alike, so the best time is
// the `_min` row's time and the best rate (rays=, Mtri/s) the `_max` row's. On a host whose speed switches
// between a fast and a slow state for seconds at a time, the median of a few repetitions lands in either
// state, while the best of ten is the fast state's speed and repeated within about 1% there
// (docs/gpu-passes.md, "Best of ten repetitions").
#pragma once

#include <benchmark/benchmark.h>

#include <algorithm>
#include <vector>

namespace hp::bench {

inline benchmark::internal::Benchmark* with_extremes(benchmark::internal::Benchmark* b) {
  return b->ComputeStatistics("min", [](const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); })
      ->ComputeStatistics("max", [](const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); });
}

}  // namespace hp::bench
