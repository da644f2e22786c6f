// A GPU's memory hierarchy below the coalescer: one L1 per compute unit and one shared, address-sliced
// L2, with the policies of GCN's vector L1 and of NVIDIA's sectored L1/L2 (docs/cache-model.md):
//   load    L1 lookup, allocate on miss; the missing sectors go to the L2, which allocates and reads
//           the sectors it lacks from DRAM.
//   store   write-through the L1 without allocating and without touching its state; written back at
//           the L2 (allocate, mark the sectors valid + dirty, no DRAM read: write-validate).
//   atomic  bypasses the L1 (atomics execute at the L2): read-modify-write at the L2.
// DRAM bytes: sectors read on L2 misses, and dirty sectors written back on eviction or flush.
#pragma once

#include <array>
#include <bit>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "cachesim/cache.hpp"
#include "cachesim/stack_distance.hpp"

namespace hp::cachesim {

enum class AccessKind : uint8_t { load = 0, store = 1, atomic = 2 };

// One coalesced request: a line (address >> line bits) and the sectors of it that lanes touched.
struct Request {
  uint64_t line;
  uint32_t sectors;
  AccessKind kind;
  uint8_t buffer;
};

// Counters of one level. `requests` are line requests; a request hits when all its sectors were
// present. Line hits/misses say whether the tag was present (a sectored line can hit its tag and
// still miss sectors); sector counts are the requested sectors.
struct LevelStats {
  uint64_t requests = 0, hits = 0, misses = 0;
  uint64_t line_hits = 0, line_misses = 0;
  uint64_t sectors = 0, sector_hits = 0, sector_misses = 0;
  double hit_rate() const { return requests ? double(hits) / double(requests) : 0.0; }
  void add(const LevelStats& o);
};

struct HierarchyStats {
  LevelStats l1;                     // loads only (stores and atomics do not look up the L1 state)
  LevelStats l2;                     // every request reaching the L2: L1 load misses, stores, atomics
  uint64_t stores = 0, atomics = 0;  // requests issued by the coalescer, besides l1.requests loads
  uint64_t dram_read_bytes = 0, dram_write_bytes = 0;
  void add(const HierarchyStats& o);
};

struct BufferStats {
  uint64_t l1_requests = 0, l1_misses = 0;
  uint64_t l2_requests = 0, l2_misses = 0;
  uint64_t dram_read_bytes = 0;
};

// Which levels missed for one request (per-invocation attribution).
struct IssueResult {
  bool l1_miss = false;
  bool l2_miss = false;
};

class Hierarchy {
 public:
  // l1 and l2 must pass check_config and share line and sector sizes (the L1 forwards its lines).
  Hierarchy(const CacheConfig& l1, uint32_t compute_units, const CacheConfig& l2);

  // Curves of the L1 load stream (each CU's own stack, merged) and of the L2 request stream.
  void enable_mrc(bool l1, bool l2, double sampling_rate = 1.0);

  IssueResult issue(uint32_t cu, const Request& r) {
    if (!sectored_) {
      // The set widths of the L1s and the L2 become constants of the code (picked at construction;
      // a cache that left the ordered engine is still handled: access1 checks it).
      switch (widths_) {                                        // codes: 0 unknown, 1/2/3 ordered sets of 4/8/16 ways
        case 1 * 4 + 3: return issue_unsectored<4, 16>(cu, r);  // vega56-like: 4-way L1, 16-way L2
        case 1 * 4 + 2: return issue_unsectored<4, 8>(cu, r);
        case 1 * 4 + 1: return issue_unsectored<4, 4>(cu, r);
        case 2 * 4 + 3: return issue_unsectored<8, 16>(cu, r);
        case 2 * 4 + 2: return issue_unsectored<8, 8>(cu, r);
        case 3 * 4 + 3: return issue_unsectored<16, 16>(cu, r);
        case 0 * 4 + 3: return issue_unsectored<0, 16>(cu, r);
        default: return issue_unsectored<0, 0>(cu, r);
      }
    }
    IssueResult res;
    uint32_t to_l2 = r.sectors;
    if (r.kind == AccessKind::load) {
      BufferStats& b = buffers_[r.buffer];
      const uint32_t n = sectors(r.sectors);
      ++stats_.l1.requests;
      ++b.l1_requests;
      stats_.l1.sectors += n;
      if (!l1_mrc_.empty()) feed_l1_mrc(cu, r.line);
      const Outcome o = l1_[cu].load(r.line, r.sectors);
      stats_.l1.line_hits += o.line_hit;
      stats_.l1.line_misses += !o.line_hit;
      const uint32_t m = sectors(o.missing);
      stats_.l1.sector_misses += m;
      stats_.l1.sector_hits += n - m;
      if (!o.missing) {
        ++stats_.l1.hits;
        return res;
      }
      ++stats_.l1.misses;
      ++b.l1_misses;
      res.l1_miss = true;
      to_l2 = o.missing;
    } else if (r.kind == AccessKind::store) {
      ++stats_.stores;
    } else {
      ++stats_.atomics;
    }
    res.l2_miss = issue_l2(r.line, to_l2, r.kind, r.buffer);
    return res;
  }

  // A batch of requests, in order, request i issued by compute unit cus[i]: the same as issue() on
  // each. Unsectored hierarchies whose caches use the ordered engine run it in two rounds per chunk
  // of requests: every L1 lookup, then the L2 accesses of the requests that missed (and of stores
  // and atomics). Each L1 and the L2 see their requests in the same order as one by one, and
  // nothing in one cache depends on another's state, so every count and curve is the same; the
  // rounds avoid a branch on each L1 outcome (close to a coin toss on ray-tracing traces) and the
  // host-side cost of switching between wave steps. `out` (may be null) receives each request's
  // IssueResult.
  void issue(std::span<const Request> rs, std::span<const uint32_t> cus, IssueResult* out);

  // Whether the two-round path may run its L2 accesses with AVX2 for vega56's shape (on by default
  // where the CPU has AVX2; results are the same, tests run both).
  void use_avx2(bool on);
  bool avx2() const { return avx2_; }

  // Start of a pass: L1s are invalidated (a barrier between dispatches does that on GPUs); the L2
  // keeps its contents and counters start from zero.
  void begin_pass();
  // Writes back every dirty L2 sector (counted in dram_write_bytes); end of a frame.
  void flush();

  // Unsectored hierarchies count per buffer only what does not follow from other counts (Counts);
  // the per-buffer figures and the level totals are derived here (a request is one sector: hits =
  // line hits = sector hits = requests - misses).
  HierarchyStats stats() const {
    HierarchyStats s = stats_;
    if (!sectored_) {
      for (const BufferStats& b : buffers()) {
        s.l1.requests += b.l1_requests;
        s.l1.misses += b.l1_misses;
        s.l2.requests += b.l2_requests;
        s.l2.misses += b.l2_misses;
        s.dram_read_bytes += b.dram_read_bytes;
      }
      s.dram_write_bytes += written_back_ * sector_bytes_;
      for (LevelStats* l : {&s.l1, &s.l2}) {
        l->hits = l->requests - l->misses;
        l->line_hits = l->sector_hits = l->hits;
        l->line_misses = l->sector_misses = l->misses;
        l->sectors = l->requests;
      }
    }
    return s;
  }
  std::array<BufferStats, 256> buffers() const {
    if (sectored_) return buffers_;
    std::array<BufferStats, 256> out{};
    for (size_t k = 0; k < out.size(); ++k) {
      const Counts& c = counts_[k];
      out[k].l1_requests = c.l1_requests;
      out[k].l1_misses = c.l1_misses;
      out[k].l2_requests = c.l1_misses + c.l2_direct;  // L1 load misses, stores, atomics
      out[k].l2_misses = c.l2_misses;
      // write-validate: a store miss reads nothing
      out[k].dram_read_bytes = (c.l2_misses - c.l2_store_misses) * sector_bytes_;
    }
    return out;
  }
  MissRatioCurve l1_curve() const;
  MissRatioCurve l2_curve() const;
  uint32_t compute_units() const { return uint32_t(l1_.size()); }
  const Cache& l1(uint32_t cu) const { return l1_[cu]; }
  const Cache& l2() const { return l2_; }

 private:
  // The same counts as the general path for one-sector lines, with fewer counters (see stats())
  // and no branch on the L2 outcome, which is close to a coin toss on ray-tracing traces.
  // S1, S2: the set widths of the L1s and of the L2 (ordered engine), 0 when not known.
  template <uint32_t S, int kOp>
  [[gnu::always_inline]] static Outcome access1(Cache& c, uint64_t line) {
    if constexpr (S != 0) {
      if (line < c.ordered_line_limit()) [[likely]]
        return c.template ordered_access<kOp, S>(line);
    }
    if constexpr (kOp == 0)
      return c.load(line, 1);
    else if constexpr (kOp == 1)
      return c.store(line, 1);
    else
      return c.update(line, 1);
  }
  template <uint32_t S1, uint32_t S2>
  [[gnu::always_inline]] IssueResult issue_unsectored(uint32_t cu, const Request& r) {
    IssueResult res;
    Counts& c = counts_[r.buffer];
    const AccessKind kind = r.kind;
    const uint64_t line = r.line;
    if (kind == AccessKind::load) {
      ++c.l1_requests;
      if (!l1_mrc_.empty()) feed_l1_mrc(cu, line);
      if (access1<S1, 0>(l1_[cu], line).line_hit) return res;
      ++c.l1_misses;
      res.l1_miss = true;
    } else {
      ++c.l2_direct;
      if (kind == AccessKind::store)
        ++stats_.stores;
      else
        ++stats_.atomics;
    }
    if (l2_mrc_) feed_l2_mrc(line);
    const Outcome o = kind == AccessKind::load    ? access1<S2, 0>(l2_, line)
                      : kind == AccessKind::store ? access1<S2, 1>(l2_, line)
                                                  : access1<S2, 2>(l2_, line);
    const uint32_t miss = o.missing;  // 0 or 1
    written_back_ += o.written_back_sectors;
    if (kind == AccessKind::store) c.l2_store_misses += miss;
    c.l2_misses += miss;
    res.l2_miss = miss;
    return res;
  }

  template <uint32_t S1, uint32_t S2>
  void issue_batch(std::span<const Request> rs, std::span<const uint32_t> cus, IssueResult* out);
  // Issues rs[0, k) in two rounds and returns k: n, or the first request whose line is not below
  // fast_limit_.
  template <uint32_t S1, typename T1, uint32_t S2, typename T2, bool kLru>
  size_t issue_chunk(const Request* rs, const uint32_t* cus, size_t n, IssueResult* out);
#if defined(__x86_64__) && defined(__GNUC__)
  // The same for vega56's shape (4-way 32-bit L1s, 16-way 16-bit L2) with the L2 in AVX2.
  template <bool kLru>
  [[gnu::target("avx2")]] size_t issue_chunk_avx2(const Request* rs, const uint32_t* cus, size_t n, IssueResult* out);
#endif
  // Both, with L2 the way round 2 reaches the L2.
  template <uint32_t S1, typename T1, uint32_t S2, typename T2, bool kLru, typename L2>
  size_t issue_chunk_impl(const Request* rs, const uint32_t* cus, size_t n, IssueResult* out);
  // fast_limit_: the lowest ordered_line_limit() of all caches (0 once one has left the ordered
  // engine); and the geometry and entries the two-round path uses.
  void refresh_fast_limit();

  // Curve accesses are queued and handed to StackDistance in batches, which fetches the host memory
  // of queued lines ahead; the order of each stream is kept, so the curves are the same. The queues
  // are drained before a curve is read (hence mutable: draining changes no observable result).
  static constexpr size_t kMrcBatch = 256;
  void feed_l1_mrc(uint32_t cu, uint64_t line) {
    std::vector<uint64_t>& q = l1_mrc_queue_[cu];
    q.push_back(line);
    if (q.size() == kMrcBatch) {
      l1_mrc_[cu]->access(std::span<const uint64_t>(q));
      q.clear();
    }
  }
  void feed_l2_mrc(uint64_t line) {
    l2_mrc_queue_.push_back(line);
    if (l2_mrc_queue_.size() == kMrcBatch) {
      l2_mrc_->access(std::span<const uint64_t>(l2_mrc_queue_));
      l2_mrc_queue_.clear();
    }
  }
  void drain_mrc() const;

  // Sectors in a mask; without sectors a mask is 0 or 1 and needs no counting.
  uint32_t sectors(uint32_t mask) const { return sectored_ ? count_bits(mask) : mask; }

  bool issue_l2(uint64_t line, uint32_t sectors, AccessKind kind, uint8_t buffer) {
    BufferStats& b = buffers_[buffer];
    const uint32_t n = this->sectors(sectors);
    ++stats_.l2.requests;
    ++b.l2_requests;
    stats_.l2.sectors += n;
    if (l2_mrc_) feed_l2_mrc(line);
    Outcome o = kind == AccessKind::load    ? l2_.load(line, sectors)
                : kind == AccessKind::store ? l2_.store(line, sectors)
                                            : l2_.update(line, sectors);
    stats_.l2.line_hits += o.line_hit;
    stats_.l2.line_misses += !o.line_hit;
    const uint32_t m = this->sectors(o.missing);
    stats_.l2.sector_misses += m;
    stats_.l2.sector_hits += n - m;
    stats_.dram_write_bytes += uint64_t(o.written_back_sectors) * sector_bytes_;
    if (!o.missing) {
      ++stats_.l2.hits;
      return false;
    }
    ++stats_.l2.misses;
    ++b.l2_misses;
    if (kind != AccessKind::store) {  // write-validate: a store miss reads nothing
      const uint64_t bytes = uint64_t(m) * sector_bytes_;
      stats_.dram_read_bytes += bytes;
      b.dram_read_bytes += bytes;
    }
    return true;
  }

  std::vector<Cache> l1_;
  Cache l2_;
  uint32_t sector_bytes_;
  bool sectored_;
  HierarchyStats stats_;
  uint64_t written_back_ = 0;  // unsectored: dirty lines written back by evictions (see stats())
  uint32_t widths_ = 0;        // unsectored: 4 * code(L1 set width) + code(L2 set width), see issue()
  uint64_t fast_limit_ = 0;    // the two-round path stops before a line at or above this
  // The two-round path: the caches' ordered geometry and entries (see refresh_fast_limit), and the
  // indices (in their chunk) of the requests that go on to the L2.
  Cache::OrderedGeometry l1_geometry_{}, l2_geometry_{};
  std::vector<void*> l1_entries_;
  void* l2_entries_ = nullptr;
  // Entry widths of the L1s and of the L2 (Cache::Engine ordered16 / ordered32) the path runs with.
  enum class EntryWidths : uint8_t { none, w16_16, w16_32, w32_16, w32_32 };
  EntryWidths entry_widths_ = EntryWidths::none;
  bool avx2_ = false;
  static constexpr size_t kChunk = 1024;
  std::vector<uint16_t> pending_;
  std::array<BufferStats, 256> buffers_{};  // sectored hierarchies
  // Unsectored hierarchies, per buffer: L2 requests are L1 misses + l2_direct (stores, atomics);
  // DRAM reads are the L2 misses that are not store misses, a sector each.
  struct Counts {
    uint64_t l1_requests = 0, l1_misses = 0, l2_direct = 0, l2_misses = 0, l2_store_misses = 0;
  };
  std::array<Counts, 256> counts_{};
  std::vector<std::unique_ptr<StackDistance>> l1_mrc_;
  std::unique_ptr<StackDistance> l2_mrc_;
  mutable std::vector<std::vector<uint64_t>> l1_mrc_queue_;
  mutable std::vector<uint64_t> l2_mrc_queue_;
};

}  // namespace hp::cachesim
