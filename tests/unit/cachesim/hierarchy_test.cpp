#include <gtest/gtest.h>

#include <array>

#include <random>
#include <span>
#include <string>
#include <vector>

#include "cachesim/hierarchy.hpp"
#include "reference_model.hpp"

namespace hp::cachesim {
namespace {

CacheConfig cfg(uint64_t size, uint32_t line, uint32_t sector, uint32_t ways, uint32_t channels = 1) {
  CacheConfig c;
  c.size_bytes = size;
  c.line_bytes = line;
  c.sector_bytes = sector;
  c.ways = ways;
  c.channels = channels;
  return c;
}

// The hierarchy's policies restated over reference caches, counting everything by hand.
struct RefHierarchy {
  std::vector<ref::RefCache> l1;
  ref::RefCache l2;
  uint32_t sector_bytes;
  HierarchyStats s;
  std::array<BufferStats, 256> b{};
  IssueResult last;  // outcome of the latest issue
  RefHierarchy(const CacheConfig& c1, uint32_t cus, const CacheConfig& c2)
      : l1(cus, ref::RefCache(c1)), l2(c2), sector_bytes(c2.sector_bytes) {}
  void issue(uint32_t cu, const Request& r) {
    uint32_t to_l2 = r.sectors;
    last = {};
    BufferStats& buf = b[r.buffer];
    if (r.kind == AccessKind::load) {
      ++buf.l1_requests;
      ++s.l1.requests;
      s.l1.sectors += std::popcount(r.sectors);
      auto o = l1[cu].access(r.line, r.sectors, 0);
      (o.line_hit ? s.l1.line_hits : s.l1.line_misses)++;
      s.l1.sector_misses += std::popcount(o.missing);
      s.l1.sector_hits += std::popcount(r.sectors) - std::popcount(o.missing);
      if (!o.missing) {
        ++s.l1.hits;
        return;
      }
      ++s.l1.misses;
      ++buf.l1_misses;
      last.l1_miss = true;
      to_l2 = o.missing;
    } else if (r.kind == AccessKind::store) {
      ++s.stores;
    } else {
      ++s.atomics;
    }
    ++s.l2.requests;
    ++buf.l2_requests;
    s.l2.sectors += std::popcount(to_l2);
    auto o = l2.access(r.line, to_l2, int(r.kind));
    (o.line_hit ? s.l2.line_hits : s.l2.line_misses)++;
    s.l2.sector_misses += std::popcount(o.missing);
    s.l2.sector_hits += std::popcount(to_l2) - std::popcount(o.missing);
    s.dram_write_bytes += uint64_t(o.written_back) * sector_bytes;
    if (!o.missing) {
      ++s.l2.hits;
      return;
    }
    ++s.l2.misses;
    ++buf.l2_misses;
    last.l2_miss = true;
    if (r.kind != AccessKind::store) {
      s.dram_read_bytes += uint64_t(std::popcount(o.missing)) * sector_bytes;
      buf.dram_read_bytes += uint64_t(std::popcount(o.missing)) * sector_bytes;
    }
  }
};

void expect_level(const LevelStats& a, const LevelStats& b, const char* name) {
  SCOPED_TRACE(name);
  EXPECT_EQ(a.requests, b.requests);
  EXPECT_EQ(a.hits, b.hits);
  EXPECT_EQ(a.misses, b.misses);
  EXPECT_EQ(a.line_hits, b.line_hits);
  EXPECT_EQ(a.line_misses, b.line_misses);
  EXPECT_EQ(a.sectors, b.sectors);
  EXPECT_EQ(a.sector_hits, b.sector_hits);
  EXPECT_EQ(a.sector_misses, b.sector_misses);
}

// batched: the requests go through Hierarchy::issue(span, cus, out) in batches of 1-3000 requests of
// mixed CUs (crossing its internal chunks), as Simulator issues them (out null for some batches).
// wide_at: the request with that index gets line wide_line, whose tag needs wider entries or no
// narrow engine at all (the caches it reaches widen or convert mid-stream, inside a batch when
// batched).
// avx2: let the two-round path use its AVX2 L2 code where the CPU has AVX2 (false: portable code).
void run_random(const CacheConfig& c1, const CacheConfig& c2, uint32_t cus, uint64_t seed, bool batched = false,
                int wide_at = -1, uint64_t wide_line = (uint64_t(1) << 45) + 3, bool avx2 = true) {
  Hierarchy h(c1, cus, c2);
  h.use_avx2(avx2);
  if (!avx2) {
    ASSERT_FALSE(h.avx2());
  }
  RefHierarchy r(c1, cus, c2);
  Cache probe(c1);
  std::mt19937_64 rng(seed);
  const uint64_t lines = c2.size_bytes / c2.line_bytes * 3;
  std::vector<Request> batch;
  std::vector<uint32_t> batch_cu;
  std::vector<IssueResult> out;
  size_t batch_size = 1;
  for (int i = 0; i < 80000; ++i) {
    Request q;
    q.line = rng() % 3 ? rng() % (lines / 16) : rng() % lines;
    if (i == wide_at) q.line = wide_line;
    q.sectors = probe.full_mask() == 1 ? 1u : uint32_t(rng() % probe.full_mask()) + 1;
    const uint64_t k = rng() % 10;
    q.kind = k < 7 ? AccessKind::load : k < 9 ? AccessKind::store : AccessKind::atomic;
    q.buffer = uint8_t(rng() % 4);
    const uint32_t cu = uint32_t(rng() % cus);
    if (batched) {
      batch.push_back(q);
      batch_cu.push_back(cu);
      if (batch.size() == batch_size || i == 79999) {
        const bool want = rng() % 4 != 0;
        out.assign(batch.size(), IssueResult{true, true});
        h.issue(std::span<const Request>(batch), std::span<const uint32_t>(batch_cu), want ? out.data() : nullptr);
        for (size_t k = 0; k < batch.size(); ++k) {
          r.issue(batch_cu[k], batch[k]);
          if (!want) continue;
          ASSERT_EQ(out[k].l1_miss, r.last.l1_miss) << "request " << i << " batch " << k;
          ASSERT_EQ(out[k].l2_miss, r.last.l2_miss) << "request " << i << " batch " << k;
        }
        batch.clear();
        batch_cu.clear();
        batch_size = rng() % 4 ? 1 + rng() % 40 : 1 + rng() % 3000;
      }
      continue;
    }
    const IssueResult got = h.issue(cu, q);
    r.issue(cu, q);
    ASSERT_EQ(got.l1_miss, r.last.l1_miss) << "request " << i;
    ASSERT_EQ(got.l2_miss, r.last.l2_miss) << "request " << i;
  }
  h.flush();
  r.s.dram_write_bytes += r.l2.dirty_sectors() * c2.sector_bytes;
  expect_level(h.stats().l1, r.s.l1, "L1");
  expect_level(h.stats().l2, r.s.l2, "L2");
  EXPECT_EQ(h.stats().stores, r.s.stores);
  EXPECT_EQ(h.stats().atomics, r.s.atomics);
  EXPECT_EQ(h.stats().dram_read_bytes, r.s.dram_read_bytes);
  EXPECT_EQ(h.stats().dram_write_bytes, r.s.dram_write_bytes);
  for (size_t k = 0; k < 256; ++k) {
    SCOPED_TRACE(k);
    EXPECT_EQ(h.buffers()[k].l1_requests, r.b[k].l1_requests);
    EXPECT_EQ(h.buffers()[k].l1_misses, r.b[k].l1_misses);
    EXPECT_EQ(h.buffers()[k].l2_requests, r.b[k].l2_requests);
    EXPECT_EQ(h.buffers()[k].l2_misses, r.b[k].l2_misses);
    EXPECT_EQ(h.buffers()[k].dram_read_bytes, r.b[k].dram_read_bytes);
  }
  uint64_t l1 = 0, l2 = 0;
  for (const BufferStats& b : h.buffers()) l1 += b.l1_requests, l2 += b.l2_misses;
  EXPECT_EQ(l1, h.stats().l1.requests);
  EXPECT_EQ(l2, h.stats().l2.misses);
}

TEST(Hierarchy, MatchesReferenceAmdLike) { run_random(cfg(4 << 10, 64, 64, 4), cfg(32 << 10, 64, 64, 16, 4), 4, 11); }

// vega56's shape (4-way L1s, 16-way L2 in 16 channels; the unsectored fast path), and FIFO.
TEST(Hierarchy, MatchesReferenceVegaShapedAndFifo) {
  run_random(cfg(16 << 10, 64, 64, 4), cfg(4 << 20, 64, 64, 16, 16), 8, 13);
  run_random(cfg(16 << 10, 64, 64, 4), cfg(4 << 20, 64, 64, 16, 16), 8, 18, true);
  run_random(cfg(16 << 10, 64, 64, 4), cfg(4 << 20, 64, 64, 16, 16), 8, 19, true, -1, 0, false);
  CacheConfig l1 = cfg(2 << 10, 64, 64, 8), l2 = cfg(64 << 10, 64, 64, 16, 4);
  l1.replacement = l2.replacement = Replacement::fifo;
  run_random(l1, l2, 3, 14);
  run_random(l1, l2, 3, 15, true);
  CacheConfig vl1 = cfg(16 << 10, 64, 64, 4), vl2 = cfg(4 << 20, 64, 64, 16, 16);
  vl1.replacement = vl2.replacement = Replacement::fifo;
  run_random(vl1, vl2, 8, 20, true);                // FIFO through the AVX2 L2 path where present
  run_random(vl1, vl2, 8, 21, true, -1, 0, false);  // and through the portable one
}

// A line too wide for the caches' entries in the middle of the stream: the caches it reaches widen
// their entries (16 to 32 bits: the L1 alone, which the other L1s follow, or the L1 and the L2) or
// convert to the general engine, inside a batch; the batch goes on one request at a time, the
// two-round path resumes with the new widths where it has code for them, and every count stays exact.
TEST(Hierarchy, WideLineMidBatchStaysExact) {
  // vega56's shape (32-bit 4-way L1s, 16-bit 16-way L2) and 8-way L1s that start at 16 bits too.
  const CacheConfig vega_l1 = cfg(16 << 10, 64, 64, 4), l2 = cfg(4 << 20, 64, 64, 16, 16);
  const CacheConfig l1_8 = cfg(16 << 10, 64, 64, 8);
  const uint64_t l2_wide = Cache(l2).ordered_line_limit() + 7;    // beyond 16-bit L2 tags
  const uint64_t l1_wide = Cache(l1_8).ordered_line_limit() + 7;  // beyond 16-bit L1 tags only
  ASSERT_LT(l1_wide, Cache(l2).ordered_line_limit());
  const uint64_t general = (uint64_t(1) << 45) + 3;  // beyond every narrow engine
  uint64_t seed = 16;
  for (const auto& [l1, line] : {std::pair{vega_l1, l2_wide}, std::pair{vega_l1, general}, std::pair{l1_8, l1_wide},
                                 std::pair{l1_8, l2_wide}, std::pair{l1_8, general}}) {
    SCOPED_TRACE(describe(l1) + ", line " + std::to_string(line));
    run_random(l1, l2, 8, seed++, true, 50000, line);
    run_random(l1, l2, 8, seed++, false, 50000, line);
    run_random(l1, l2, 8, seed++, true, 50000, line, false);  // the portable L2 code
  }
}

TEST(Hierarchy, MatchesReferenceSectored) {
  run_random(cfg(8 << 10, 128, 32, 8), cfg(64 << 10, 128, 32, 16, 2), 3, 12);
}

// Every set-width specialisation of the unsectored path (and the general ones: other way counts,
// random replacement, sectors), one request at a time and in batches.
TEST(Hierarchy, MatchesReferenceInEverySetWidthBatched) {
  const uint32_t widths[][2] = {{4, 16}, {4, 8}, {4, 4}, {8, 16}, {8, 8}, {16, 16}, {2, 16}, {12, 16}, {4, 2}};
  uint64_t seed = 40;
  for (const auto& w : widths) {
    SCOPED_TRACE(std::to_string(w[0]) + "-way L1, " + std::to_string(w[1]) + "-way L2");
    const CacheConfig l1 = cfg(uint64_t(w[0]) * 64 * 16, 64, 64, w[0]),
                      l2 = cfg(uint64_t(w[1]) * 64 * 64 * 4, 64, 64, w[1], 4);
    run_random(l1, l2, 3, ++seed, false);
    run_random(l1, l2, 3, ++seed, true);
    // vega56's shape has an AVX2 L2 path too (used where the CPU has AVX2): the portable one as well.
    if (w[0] == 4 && w[1] == 16) run_random(l1, l2, 3, ++seed, true, -1, 0, false);
  }
  run_random(cfg(8 << 10, 128, 32, 8), cfg(64 << 10, 128, 32, 16, 2), 3, 61, true);
  // Random replacement (seeded per CU, which the reference does not model): batched against one
  // request at a time.
  CacheConfig rl1 = cfg(4 << 10, 64, 64, 4), rl2 = cfg(64 << 10, 64, 64, 16, 4);
  rl1.replacement = rl2.replacement = Replacement::random;
  Hierarchy one(rl1, 3, rl2), steps(rl1, 3, rl2);
  std::mt19937_64 rng(62);
  std::vector<Request> step;
  std::vector<uint32_t> step_cu;
  std::vector<IssueResult> out;
  for (int i = 0; i < 20000; ++i) {
    step.clear();
    step_cu.clear();
    for (uint64_t k = 0, n = 1 + rng() % 10; k < n; ++k) {
      step.push_back({rng() % 8192, 1, rng() % 8 ? AccessKind::load : AccessKind::store, uint8_t(rng() % 3)});
      step_cu.push_back(uint32_t(rng() % 3));
    }
    out.assign(step.size(), {});
    steps.issue(std::span<const Request>(step), std::span<const uint32_t>(step_cu), out.data());
    for (size_t k = 0; k < step.size(); ++k) {
      const IssueResult e = one.issue(step_cu[k], step[k]);
      ASSERT_EQ(out[k].l1_miss, e.l1_miss);
      ASSERT_EQ(out[k].l2_miss, e.l2_miss);
    }
  }
  expect_level(steps.stats().l1, one.stats().l1, "L1");
  expect_level(steps.stats().l2, one.stats().l2, "L2");
  EXPECT_EQ(steps.stats().dram_read_bytes, one.stats().dram_read_bytes);
  EXPECT_EQ(steps.stats().dram_write_bytes, one.stats().dram_write_bytes);
}

TEST(Hierarchy, L1IsPrivatePerComputeUnit) {
  Hierarchy h(cfg(1 << 10, 64, 64, 4), 2, cfg(64 << 10, 64, 64, 16));
  EXPECT_TRUE(h.issue(0, {100, 1, AccessKind::load, 0}).l1_miss);
  EXPECT_FALSE(h.issue(0, {100, 1, AccessKind::load, 0}).l1_miss);
  IssueResult other = h.issue(1, {100, 1, AccessKind::load, 0});
  EXPECT_TRUE(other.l1_miss);   // CU 1's L1 never saw the line
  EXPECT_FALSE(other.l2_miss);  // but the shared L2 did
  EXPECT_EQ(h.stats().l2.requests, 2u);
}

TEST(Hierarchy, StoresWriteThroughWithoutAllocatingInL1) {
  Hierarchy h(cfg(1 << 10, 64, 64, 4), 1, cfg(64 << 10, 64, 64, 16));
  h.issue(0, {5, 1, AccessKind::store, 1});
  EXPECT_EQ(h.stats().l1.requests, 0u);
  EXPECT_EQ(h.stats().l2.requests, 1u);
  EXPECT_EQ(h.stats().dram_read_bytes, 0u);  // write-validate at the L2
  IssueResult r = h.issue(0, {5, 1, AccessKind::load, 1});
  EXPECT_TRUE(r.l1_miss);   // the store did not allocate in the L1
  EXPECT_FALSE(r.l2_miss);  // but the L2 holds the written line
  h.flush();
  EXPECT_EQ(h.stats().dram_write_bytes, 64u);
  EXPECT_EQ(h.buffers()[1].l2_requests, 2u);
}

TEST(Hierarchy, AtomicsBypassTheL1) {
  Hierarchy h(cfg(1 << 10, 64, 64, 4), 1, cfg(64 << 10, 64, 64, 16));
  IssueResult a = h.issue(0, {9, 1, AccessKind::atomic, 0});
  EXPECT_FALSE(a.l1_miss);
  EXPECT_TRUE(a.l2_miss);
  EXPECT_EQ(h.stats().dram_read_bytes, 64u);  // read-modify-write fetches the line
  EXPECT_TRUE(h.issue(0, {9, 1, AccessKind::load, 0}).l1_miss);
}

TEST(Hierarchy, BeginPassInvalidatesL1KeepsL2) {
  Hierarchy h(cfg(1 << 10, 64, 64, 4), 1, cfg(64 << 10, 64, 64, 16));
  h.issue(0, {3, 1, AccessKind::load, 0});
  h.begin_pass();
  EXPECT_EQ(h.stats().l1.requests, 0u);
  IssueResult r = h.issue(0, {3, 1, AccessKind::load, 0});
  EXPECT_TRUE(r.l1_miss);
  EXPECT_FALSE(r.l2_miss);
}

}  // namespace
}  // namespace hp::cachesim
