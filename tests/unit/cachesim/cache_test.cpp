#include <gtest/gtest.h>

#include <random>

#include "cachesim/cache.hpp"
#include "reference_model.hpp"

namespace hp::cachesim {
namespace {

CacheConfig make(uint64_t size, uint32_t line, uint32_t sector, uint32_t ways, Replacement r = Replacement::lru,
                 uint32_t channels = 1, uint32_t interleave = 0) {
  CacheConfig c;
  c.size_bytes = size;
  c.line_bytes = line;
  c.sector_bytes = sector;
  c.ways = ways;
  c.replacement = r;
  c.channels = channels;
  c.channel_interleave_bytes = interleave;
  EXPECT_EQ(check_config(c), "");
  return c;
}

// Drives both caches with the same stream and compares every outcome, not only totals, so a wrong
// victim shows at the first access where it matters.
void compare(const CacheConfig& c, const std::vector<std::tuple<uint64_t, uint32_t, int>>& stream) {
  Cache cache(c);
  ref::RefCache ref(c);
  for (size_t i = 0; i < stream.size(); ++i) {
    auto [line, sectors, mode] = stream[i];
    Outcome o = mode == 0   ? cache.load(line, sectors)
                : mode == 1 ? cache.store(line, sectors)
                            : cache.update(line, sectors);
    ref::RefOutcome r = ref.access(line, sectors, mode);
    ASSERT_EQ(o.missing, r.missing) << "access " << i << " line " << line;
    ASSERT_EQ(o.line_hit, r.line_hit) << "access " << i;
    ASSERT_EQ(o.written_back_sectors, r.written_back) << "access " << i;
  }
  EXPECT_EQ(cache.flush_dirty_sectors(), ref.dirty_sectors());
}

std::vector<std::tuple<uint64_t, uint32_t, int>> random_stream(uint64_t seed, size_t n, uint64_t lines,
                                                               uint32_t full_mask, bool mixed) {
  std::mt19937_64 rng(seed);
  std::vector<std::tuple<uint64_t, uint32_t, int>> s;
  for (size_t i = 0; i < n; ++i) {
    // Skewed: mostly a hot region, sometimes anywhere, so hits, conflicts and evictions all occur.
    uint64_t line = (rng() % 4 == 0) ? rng() % lines : rng() % (lines / 8 + 1);
    uint32_t mask = full_mask == 1 ? 1u : uint32_t(rng() % full_mask) + 1;
    int mode = mixed ? int(rng() % 5 == 0 ? 1 + rng() % 2 : 0) : 0;
    s.emplace_back(line, mask, mode);
  }
  return s;
}

TEST(Cache, MatchesReferenceOnRandomTraces) {
  const std::vector<CacheConfig> configs = {
      make(16 << 10, 64, 64, 4),
      make(16 << 10, 64, 64, 4, Replacement::fifo),
      make(4 << 10, 128, 32, 2),
      make(8 << 10, 128, 32, 8, Replacement::fifo),
      make(1 << 10, 64, 64, 16),  // one set: fully associative
      make(64 << 10, 64, 64, 16, Replacement::lru, 16),
      make(48 << 10, 64, 64, 4, Replacement::lru, 3, 256),  // non-power-of-two channels, 4-line chunks
  };
  uint64_t seed = 1;
  for (const CacheConfig& c : configs) {
    SCOPED_TRACE(describe(c));
    Cache probe(c);
    compare(c, random_stream(seed++, 60000, c.lines() * 6, probe.full_mask(), true));
  }
}

TEST(Cache, MatchesReferenceOnAdversarialTraces) {
  const CacheConfig c = make(16 << 10, 64, 64, 4);
  const uint64_t sets = c.lines() / c.ways;
  std::vector<std::tuple<uint64_t, uint32_t, int>> s;
  // Cyclic sweep of ways+1 lines in one set: LRU misses every time.
  for (int rep = 0; rep < 50; ++rep)
    for (uint64_t k = 0; k <= c.ways; ++k) s.emplace_back(7 + k * sets, 1u, 0);
  // Exactly `ways` lines in one set: all hits after warm-up.
  for (int rep = 0; rep < 50; ++rep)
    for (uint64_t k = 0; k < c.ways; ++k) s.emplace_back(3 + k * sets, 1u, int(rep % 3 == 0));
  // Huge line numbers (high address bits) and line 0.
  for (uint64_t k = 0; k < 40; ++k) s.emplace_back((uint64_t(1) << 57) + k * sets, 1u, 2);
  for (int rep = 0; rep < 10; ++rep) s.emplace_back(0, 1u, 0);
  compare(c, s);
  CacheConfig f = c;
  f.replacement = Replacement::fifo;
  compare(f, s);
}

// The ordered engine (unsectored: recency-ordered 16- or 32-bit entries with a dirty bit) and the compact one
// (sectored: partial tags and a recency permutation) serve LRU/FIFO caches of up to 16 ways; every
// associativity they pad (to 4, 8 or 16 ways) must behave exactly like the reference.
TEST(Cache, CompactEngineMatchesReferenceAtEveryAssociativity) {
  uint64_t seed = 100;
  for (uint32_t ways = 1; ways <= 16; ++ways) {
    for (Replacement r : {Replacement::lru, Replacement::fifo}) {
      for (uint32_t sector : {64u, 16u}) {
        const CacheConfig c = make(uint64_t(64) * ways * 8, 64, sector, ways, r);  // 8 sets
        SCOPED_TRACE(describe(c));
        Cache probe(c);
        ASSERT_EQ(probe.engine(), sector != 64 ? Cache::Engine::compact
                                  : ways <= 4  ? Cache::Engine::ordered32
                                               : Cache::Engine::ordered16);
        compare(c, random_stream(seed++, 6000, c.lines() * 4, probe.full_mask(), true));
      }
    }
  }
  // More than 16 ways and random replacement use the general engine.
  EXPECT_FALSE(Cache(make(64 * 32, 64, 64, 32)).compact());
  EXPECT_FALSE(Cache(make(16 << 10, 64, 64, 4, Replacement::random)).compact());
}

// A line whose tag does not fit 32 bits switches a compact cache to the general engine mid-stream;
// the state carried over (contents, recency order, valid and dirty sectors) must be exact.
TEST(Cache, WideTagConvertsCompactStateExactly) {
  const std::vector<CacheConfig> configs = {
      make(4 << 20, 64, 64, 16, Replacement::lru, 16),         // vega56 L2
      make(16 << 10, 64, 64, 4),                               // vega56 L1
      make(128 << 10, 128, 32, 8, Replacement::fifo),          // sectored
      make(48 << 10, 64, 64, 4, Replacement::lru, 3, 256),     // non-power-of-two channels
      make(6 << 20, 128, 32, 16, Replacement::lru, 12, 1024),  // ga102-like L2
  };
  uint64_t seed = 300;
  for (const CacheConfig& c : configs) {
    SCOPED_TRACE(describe(c));
    Cache probe(c);
    auto s = random_stream(seed++, 30000, c.lines() * 3, probe.full_mask(), true);
    // Warm up on ordinary lines, then one line with a tag above 32 bits, then ordinary lines again
    // (which must find exactly the lines, order and dirt the compact engine left).
    s.insert(s.begin() + 20000, {(uint64_t(1) << 62) + 5, 1u, 1});
    compare(c, s);
    Cache x(c);
    for (size_t i = 0; i < 20000; ++i) x.load(std::get<0>(s[i]), std::get<1>(s[i]));
    EXPECT_TRUE(x.compact());
    x.load(uint64_t(1) << 62, 1);
    EXPECT_FALSE(x.compact());
  }
}

// The ordered engine keeps a dirty bit in the top bit of each entry, so 16-bit entries (sets of 8 or
// 16 ways) hold tags below 2^15 - 1 and 32-bit ones below 2^31 - 1: the first line with a wider tag
// (2^15 - 1 itself, not only 2^16 and up) widens the entries, the first beyond 32 bits converts to the
// general engine, each exactly (contents, order, dirt), and lines just below the limits stay put.
TEST(Cache, OrderedEngineTagLimitsAreExact) {
  for (const CacheConfig& c :
       {make(4 << 20, 64, 64, 16, Replacement::lru, 16), make(16 << 10, 64, 64, 4),
        make(48 << 10, 64, 64, 4, Replacement::fifo, 3, 256), make(16 << 10, 64, 64, 8, Replacement::fifo),
        make(36 << 10, 64, 64, 12, Replacement::lru, 3)}) {
    SCOPED_TRACE(describe(c));
    Cache x(c);
    const bool narrow = c.ways > 4;
    ASSERT_EQ(x.engine(), narrow ? Cache::Engine::ordered16 : Cache::Engine::ordered32);
    uint64_t dirty = 0;
    uint64_t limit16 = 0;
    if (narrow) {
      limit16 = x.ordered_line_limit();
      x.store(limit16 - 1, 1);  // dirty, so each conversion must carry the dirty bit
      ++dirty;
      EXPECT_EQ(x.engine(), Cache::Engine::ordered16);
      x.load(limit16, 1);
      ASSERT_EQ(x.engine(), Cache::Engine::ordered32);
    }
    const uint64_t limit32 = x.ordered_line_limit();
    EXPECT_GT(limit32, limit16);
    x.update(limit32 - 1, 1);
    ++dirty;
    EXPECT_EQ(x.engine(), Cache::Engine::ordered32);
    x.load(limit32, 1);
    EXPECT_EQ(x.engine(), Cache::Engine::general);
    if (narrow) {
      EXPECT_FALSE(x.load(limit16 - 1, 1).missing);
      EXPECT_FALSE(x.load(limit16, 1).missing);
    }
    EXPECT_FALSE(x.load(limit32 - 1, 1).missing);
    EXPECT_EQ(x.flush_dirty_sectors(), dirty);
    // The same transitions inside random streams, outcome by outcome against the reference.
    for (uint64_t seed : {500, 501}) {
      auto s = random_stream(seed, 20000, c.lines() * 3, x.full_mask(), true);
      if (narrow) {
        s.insert(s.begin() + 4000, {limit16 - 1, 1u, 1});
        s.insert(s.begin() + 8000, {limit16, 1u, 0});
      }
      s.insert(s.begin() + 10000, {limit32 - 1, 1u, 1});
      if (seed == 501) s.insert(s.begin() + 12000, {limit32, 1u, 2});
      compare(c, s);
    }
  }
}

TEST(Cache, LruEvictsLeastRecentlyUsed) {
  Cache c(make(128, 64, 64, 2));  // one set, two ways
  EXPECT_TRUE(c.load(1, 1).missing);
  EXPECT_TRUE(c.load(2, 1).missing);
  EXPECT_FALSE(c.load(1, 1).missing);  // 1 becomes most recent
  EXPECT_TRUE(c.load(3, 1).missing);   // evicts 2
  EXPECT_FALSE(c.load(1, 1).missing);
  EXPECT_TRUE(c.load(2, 1).missing);
}

TEST(Cache, FifoEvictsOldestInsertionDespiteHits) {
  Cache c(make(128, 64, 64, 2, Replacement::fifo));
  c.load(1, 1);
  c.load(2, 1);
  EXPECT_FALSE(c.load(1, 1).missing);  // hit does not refresh under FIFO
  c.load(3, 1);                        // evicts 1, the oldest insertion
  EXPECT_TRUE(c.load(1, 1).missing);
  EXPECT_TRUE(c.contains(3, 1));
}

TEST(Cache, RandomReplacementFillsEmptyWaysFirstAndIsSeeded) {
  CacheConfig cfg = make(256, 64, 64, 4, Replacement::random);
  Cache c(cfg);
  for (uint64_t l = 0; l < 4; ++l) c.load(l, 1);
  for (uint64_t l = 0; l < 4; ++l) EXPECT_TRUE(c.contains(l, 1)) << "empty way not used first";
  auto victims = [&](uint64_t seed) {
    CacheConfig s = cfg;
    s.seed = seed;
    Cache x(s);
    std::vector<int> present;
    for (uint64_t l = 0; l < 64; ++l) x.load(l, 1);
    for (uint64_t l = 0; l < 64; ++l) present.push_back(x.contains(l, 1));
    return present;
  };
  EXPECT_EQ(victims(5), victims(5));
  EXPECT_NE(victims(5), victims(6));
}

TEST(Cache, SectorsFillLazily) {
  Cache c(make(512, 128, 32, 4));  // one set, 4 sectors per line
  Outcome a = c.load(9, 0b0001);
  EXPECT_FALSE(a.line_hit);
  EXPECT_EQ(a.missing, 0b0001u);
  Outcome b = c.load(9, 0b0011);
  EXPECT_TRUE(b.line_hit);
  EXPECT_EQ(b.missing, 0b0010u);  // only the sector never fetched
  EXPECT_EQ(c.load(9, 0b0011).missing, 0u);
  EXPECT_FALSE(c.contains(9, 0b1000));
}

TEST(Cache, DirtySectorsAreWrittenBackOnEvictionAndFlush) {
  Cache c(make(128, 128, 32, 1));                  // one line
  EXPECT_EQ(c.store(1, 0b0110).missing, 0b0110u);  // write-validate: reported missing, nothing fetched
  EXPECT_EQ(c.load(1, 0b0010).missing, 0u);        // written sector is valid
  EXPECT_EQ(c.load(2, 0b0001).written_back_sectors, 2u);
  c.update(3, 0b1111);
  EXPECT_EQ(c.flush_dirty_sectors(), 4u);
  EXPECT_EQ(c.flush_dirty_sectors(), 0u);
}

TEST(Cache, ConfigChecksNameTheField) {
  CacheConfig c = make(16 << 10, 64, 64, 4);
  c.line_bytes = 48;
  EXPECT_NE(check_config(c).find("line_bytes"), std::string::npos);
  c = make(16 << 10, 64, 64, 4);
  c.size_bytes = 1000;
  EXPECT_NE(check_config(c).find("size_bytes"), std::string::npos);
  c = make(16 << 10, 64, 64, 4);
  c.sector_bytes = 128;
  EXPECT_NE(check_config(c).find("sector_bytes"), std::string::npos);
  c = make(16 << 10, 64, 64, 4);
  c.size_bytes = 3 * 64 * 4;  // 3 sets
  EXPECT_NE(check_config(c).find("power of two"), std::string::npos);
}

}  // namespace
}  // namespace hp::cachesim
