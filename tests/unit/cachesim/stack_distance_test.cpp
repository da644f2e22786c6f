#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "cachesim/hierarchy.hpp"
#include "cachesim/stack_distance.hpp"
#include "reference_model.hpp"

namespace hp::cachesim {
namespace {

std::vector<uint64_t> stream(uint64_t seed, size_t n, uint64_t distinct) {
  std::mt19937_64 rng(seed);
  std::vector<uint64_t> s;
  for (size_t i = 0; i < n; ++i) {
    // Mixture of a small hot set, a sliding window (streaming) and uniform picks.
    const uint64_t k = rng() % 10;
    if (k < 4)
      s.push_back(rng() % 32);
    else if (k < 7)
      s.push_back(1000 + (i / 3 + rng() % 50) % distinct);
    else
      s.push_back(rng() % distinct * 7919);
  }
  return s;
}

TEST(StackDistance, OnePassCurveEqualsSeparateFullyAssociativeSimulations) {
  // 6000 distinct lines against a first capacity of 4096 times: compaction and growth both happen.
  const auto s = stream(1, 40000, 6000);
  StackDistance sd(64);
  for (uint64_t x : s) sd.access(x);
  const MissRatioCurve& c = sd.curve();
  EXPECT_EQ(c.accesses, s.size());
  for (uint64_t lines : {1ull, 2ull, 3ull, 7ull, 32ull, 33ull, 100ull, 512ull, 1000ull, 4096ull, 5000ull, 20000ull}) {
    SCOPED_TRACE(lines);
    EXPECT_EQ(c.misses(lines), ref::fully_associative_misses(s, lines));
    // And against the production cache configured fully associative (one set).
    CacheConfig fa{lines * 64, 64, 64, uint32_t(lines)};
    if (check_config(fa).empty() && lines <= 1024) {
      Cache cache(fa);
      uint64_t misses = 0;
      for (uint64_t x : s) misses += cache.load(x, 1).missing != 0;
      EXPECT_EQ(c.misses(lines), misses);
    }
  }
}

// Every single distance against a naive LRU stack, on a stream built to exercise each path of the
// implementation: short reuse (bitmap popcount), long reuse (Fenwick over blocks), repeated window
// compaction and growth, pages of consecutive lines and isolated lines with huge numbers.
TEST(StackDistance, EveryDistanceEqualsANaiveStack) {
  std::mt19937_64 rng(21);
  std::vector<uint64_t> s;
  for (size_t i = 0; i < 60000; ++i) {
    const uint64_t k = rng() % 16;
    if (k < 5)
      s.push_back(rng() % 48);  // hot
    else if (k < 9)
      s.push_back(5000 + (i / 2) % 9000);  // a sweep: long distances, cold lines, compactions
    else if (k < 12)
      s.push_back(rng() % 12000);
    else if (k < 14)
      s.push_back((rng() % 300) * 1000003ull);  // one line per page
    else
      s.push_back((uint64_t(1) << 59) + (rng() % 200) * (uint64_t(1) << 40));  // huge line numbers
  }
  StackDistance sd(64);
  std::vector<uint64_t> stack;  // most recent first
  for (size_t i = 0; i < s.size(); ++i) {
    const auto it = std::find(stack.begin(), stack.end(), s[i]);
    const uint64_t expected = it == stack.end() ? StackDistance::kCold : uint64_t(it - stack.begin());
    if (it != stack.end()) stack.erase(it);
    stack.insert(stack.begin(), s[i]);
    ASSERT_EQ(sd.access(s[i]), expected) << "access " << i << " line " << s[i];
  }
  EXPECT_EQ(sd.distinct_lines(), stack.size());
}

// The batched entry (which fetches host memory ahead) builds the same curve as access() per line.
TEST(StackDistance, BatchedAccessEqualsOneByOne) {
  const auto s = stream(3, 50000, 20000);
  for (double rate : {1.0, 0.25}) {
    StackDistance one(64, rate), batch(64, rate);
    for (uint64_t x : s) one.access(x);
    for (size_t i = 0, k = 0; i < s.size(); ++k) {  // uneven batches, short ones included
      const size_t len = std::min<size_t>(k % 3 == 0 ? 5 : 1000 + k, s.size() - i);
      batch.access(std::span<const uint64_t>(s.data() + i, len));
      i += len;
    }
    EXPECT_EQ(batch.curve().accesses, one.curve().accesses);
    EXPECT_EQ(batch.curve().cold, one.curve().cold);
    EXPECT_EQ(batch.curve().histogram, one.curve().histogram);
  }
}

// The histogram is counted in 32-bit working counts and published by curve(): it must equal the
// histogram of the returned distances, grown as documented (to max(d + 1, 2 * size) when a distance d
// falls past the end), also when curve() is read in between accesses.
TEST(StackDistance, PublishedHistogramEqualsTheReturnedDistances) {
  const auto s = stream(5, 60000, 30000);
  StackDistance sd;
  std::vector<uint64_t> hist;
  uint64_t cold = 0;
  for (size_t i = 0; i < s.size(); ++i) {
    const uint64_t d = sd.access(s[i]);
    if (d == StackDistance::kCold) {
      ++cold;
    } else {
      if (d >= hist.size()) hist.resize(std::max<uint64_t>(d + 1, hist.size() * 2), 0);
      ++hist[d];
    }
    if (i % 9973 == 0) {
      ASSERT_EQ(sd.curve().histogram, hist) << "after access " << i;
      ASSERT_EQ(sd.curve().cold, cold);
    }
  }
  EXPECT_EQ(sd.curve().histogram, hist);
  EXPECT_EQ(sd.curve().accesses, s.size());
  EXPECT_EQ(sd.curve().footprint_lines(), hist.size());
}

TEST(StackDistance, DistancesOfAHandTrace) {
  StackDistance sd;
  EXPECT_EQ(sd.access(1), StackDistance::kCold);
  EXPECT_EQ(sd.access(2), StackDistance::kCold);
  EXPECT_EQ(sd.access(3), StackDistance::kCold);
  EXPECT_EQ(sd.access(1), 2u);  // 2 and 3 since
  EXPECT_EQ(sd.access(1), 0u);
  EXPECT_EQ(sd.access(3), 1u);
  EXPECT_EQ(sd.access(2), 2u);
  EXPECT_EQ(sd.curve().cold, 3u);
  EXPECT_EQ(sd.curve().misses(2), 3u + 2u);  // distances 2 and 2 miss in two lines
}

TEST(StackDistance, HierarchyL2CurveMatchesItsRequestStream) {
  CacheConfig l1{1024, 64, 64, 2}, l2{16384, 64, 64, 4};
  Hierarchy h(l1, 2, l2);
  h.enable_mrc(true, true);
  std::mt19937_64 rng(5);
  std::vector<uint64_t> l2_stream;
  std::vector<std::vector<uint64_t>> l1_stream(2);
  Cache shadow0(l1), shadow1(l1);
  for (int i = 0; i < 20000; ++i) {
    const uint64_t line = rng() % 3 ? rng() % 64 : rng() % 4000;
    const uint32_t cu = uint32_t(rng() % 2);
    const bool store = rng() % 8 == 0;
    h.issue(cu, {line, 1, store ? AccessKind::store : AccessKind::load, 0});
    if (!store) {
      l1_stream[cu].push_back(line);
      if ((cu ? shadow1 : shadow0).load(line, 1).missing) l2_stream.push_back(line);
    } else {
      l2_stream.push_back(line);
    }
  }
  const MissRatioCurve c2 = h.l2_curve(), c1 = h.l1_curve();
  for (uint64_t lines : {1ull, 16ull, 256ull, 1024ull}) {
    EXPECT_EQ(c2.misses(lines), ref::fully_associative_misses(l2_stream, lines));
    EXPECT_EQ(c1.misses(lines),
              ref::fully_associative_misses(l1_stream[0], lines) + ref::fully_associative_misses(l1_stream[1], lines));
  }
}

TEST(StackDistance, ShardsApproximatesLargeCaches) {
  std::mt19937_64 rng(9);
  std::vector<uint64_t> s;
  // Power-law reuse over 200k lines.
  for (int i = 0; i < 600000; ++i) {
    const double u = double(rng() >> 11) / 9007199254740992.0;
    s.push_back(uint64_t(200000.0 * u * u * u));
  }
  StackDistance exact(64), sampled(64, 0.05);
  for (uint64_t x : s) exact.access(x), sampled.access(x);
  EXPECT_LT(sampled.curve().accesses, s.size() / 10);  // it really sampled
  EXPECT_GT(sampled.curve().accesses, s.size() / 40);
  for (uint64_t lines : {4096ull, 16384ull, 65536ull}) {
    SCOPED_TRACE(lines);
    EXPECT_NEAR(sampled.curve().miss_ratio(lines), exact.curve().miss_ratio(lines), 0.03);
  }
}

}  // namespace
}  // namespace hp::cachesim
