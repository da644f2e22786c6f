#include "cachesim/hierarchy.hpp"

#include <algorithm>
#include <stdexcept>
#include <type_traits>

namespace hp::cachesim {

void LevelStats::add(const LevelStats& o) {
  requests += o.requests;
  hits += o.hits;
  misses += o.misses;
  line_hits += o.line_hits;
  line_misses += o.line_misses;
  sectors += o.sectors;
  sector_hits += o.sector_hits;
  sector_misses += o.sector_misses;
}

void HierarchyStats::add(const HierarchyStats& o) {
  l1.add(o.l1);
  l2.add(o.l2);
  stores += o.stores;
  atomics += o.atomics;
  dram_read_bytes += o.dram_read_bytes;
  dram_write_bytes += o.dram_write_bytes;
}

Hierarchy::Hierarchy(const CacheConfig& l1, uint32_t compute_units, const CacheConfig& l2)
    : l2_(l2), sector_bytes_(l2.sector_bytes), sectored_(l2.sector_bytes != l2.line_bytes) {
  if (l1.line_bytes != l2.line_bytes || l1.sector_bytes != l2.sector_bytes)
    throw std::invalid_argument("L1 and L2 must share line and sector sizes");
  l1_.reserve(compute_units);
  for (uint32_t cu = 0; cu < compute_units; ++cu) {
    CacheConfig c = l1;
    c.seed = l1.seed + cu;  // random replacement: independent but reproducible streams per CU
    l1_.emplace_back(c);
  }
  // Set width codes for issue(): 0 other (general or compact engine, ways not 4/8/16, sets not
  // indexed by the low line bits), 1/2/3 ordered sets of exactly 4/8/16 ways.
  auto code = [](const Cache& c) -> uint32_t {
    if (c.ordered_line_limit() == 0 || c.config().ways != c.stride() || !c.plain_index()) return 0;
    return c.stride() == 4 ? 1 : c.stride() == 8 ? 2 : 3;
  };
  widths_ = (l1_.empty() ? 0 : code(l1_[0])) * 4 + code(l2_);
  pending_.resize(kChunk);
  use_avx2(true);
  refresh_fast_limit();
}

void Hierarchy::refresh_fast_limit() {
  // The L1s share one entry width (the two-round path reads them with one type): once one has
  // widened, the others widen too (exact; results never depend on the width).
  bool any32 = false;
  for (const Cache& c : l1_) any32 |= c.engine() == Cache::Engine::ordered32;
  if (any32)
    for (Cache& c : l1_) c.widen();
  fast_limit_ = l2_.ordered_line_limit();
  l1_entries_.clear();
  for (Cache& c : l1_) {
    fast_limit_ = std::min(fast_limit_, c.ordered_line_limit());
    l1_entries_.push_back(c.ordered_entries());
  }
  if (!l1_.empty()) l1_geometry_ = l1_[0].ordered_geometry();
  l2_geometry_ = l2_.ordered_geometry();
  l2_entries_ = l2_.ordered_entries();
  // Entry widths (L1s, L2) of the two-round path; caches that left the ordered engines go one
  // request at a time.
  using E = Cache::Engine;
  const E e1 = l1_.empty() ? E::general : l1_[0].engine(), e2 = l2_.engine();
  const bool o1 = e1 == E::ordered16 || e1 == E::ordered32, o2 = e2 == E::ordered16 || e2 == E::ordered32;
  entry_widths_ = !o1 || !o2           ? EntryWidths::none
                  : e1 == E::ordered16 ? (e2 == E::ordered16 ? EntryWidths::w16_16 : EntryWidths::w16_32)
                                       : (e2 == E::ordered16 ? EntryWidths::w32_16 : EntryWidths::w32_32);
  if (entry_widths_ == EntryWidths::none) fast_limit_ = 0;
}

void Hierarchy::issue(std::span<const Request> rs, std::span<const uint32_t> cus, IssueResult* out) {
  if (!sectored_) {
    switch (widths_) {
      case 1 * 4 + 3: return issue_batch<4, 16>(rs, cus, out);  // vega56-like: 4-way L1, 16-way L2
      case 1 * 4 + 2: return issue_batch<4, 8>(rs, cus, out);
      case 1 * 4 + 1: return issue_batch<4, 4>(rs, cus, out);
      case 2 * 4 + 3: return issue_batch<8, 16>(rs, cus, out);
      case 2 * 4 + 2: return issue_batch<8, 8>(rs, cus, out);
      case 3 * 4 + 3: return issue_batch<16, 16>(rs, cus, out);
      default: break;
    }
  }
  for (size_t i = 0; i < rs.size(); ++i) {
    const IssueResult res = issue(cus[i], rs[i]);
    if (out) out[i] = res;
  }
}

template <uint32_t S1, uint32_t S2>
void Hierarchy::issue_batch(std::span<const Request> rs, std::span<const uint32_t> cus, IssueResult* out) {
  for (size_t begin = 0; begin < rs.size(); begin += kChunk) {
    const size_t n = std::min(kChunk, rs.size() - begin);
    const Request* r = rs.data() + begin;
    const uint32_t* c = cus.data() + begin;
    IssueResult* o = out ? out + begin : nullptr;
    // LRU on both levels (the usual case) is a constant of the code; FIFO reads the flag.
    const bool lru = l1_geometry_.lru && l2_geometry_.lru;
    auto two_rounds = [&]<typename T1, typename T2>() -> size_t {
      // 16-bit entries only serve sets of 8 or 16 ways (Cache): other pairs never occur.
      if constexpr ((sizeof(T1) == 4 || S1 >= 8) && (sizeof(T2) == 4 || S2 >= 8))
        return lru ? issue_chunk<S1, T1, S2, T2, true>(r, c, n, o) : issue_chunk<S1, T1, S2, T2, false>(r, c, n, o);
      else
        return 0;
    };
    size_t done = 0;
    switch (entry_widths_) {
      case EntryWidths::w16_16: done = two_rounds.template operator()<uint16_t, uint16_t>(); break;
      case EntryWidths::w16_32: done = two_rounds.template operator()<uint16_t, uint32_t>(); break;
      case EntryWidths::w32_16:
#if defined(__x86_64__) && defined(__GNUC__)
        if constexpr (S1 == 4 && S2 == 16) {  // vega56's shape
          if (avx2_) {
            done = lru ? issue_chunk_avx2<true>(r, c, n, o) : issue_chunk_avx2<false>(r, c, n, o);
            break;
          }
        }
#endif
        done = two_rounds.template operator()<uint32_t, uint16_t>();
        break;
      case EntryWidths::w32_32: done = two_rounds.template operator()<uint32_t, uint32_t>(); break;
      case EntryWidths::none: break;
    }
    if (done == n) continue;
    // Request `done` has a line whose tag one of the caches cannot hold in its current entries (or
    // the two-round path is off): the rest of the chunk goes one by one (widening or converting that
    // cache), then the path is set up again for the caches' new engines.
    for (size_t i = done; i < n; ++i) {
      const IssueResult res = issue(c[i], r[i]);
      if (o) o[i] = res;
    }
    refresh_fast_limit();
  }
}

namespace {
// How round 2 reaches the L2: the portable code, or AVX2 for 16-way sets of 16-bit entries.
struct L2Portable {
  template <int kOp, typename T, uint32_t S, bool kLru>
  [[gnu::always_inline]] static Outcome access(const Cache::OrderedGeometry& g, T* entries, uint64_t line) {
    return Cache::ordered_access<kOp, T, S, kLru>(g, entries, line);
  }
};
#if defined(__x86_64__) && defined(__GNUC__)
struct L2Avx2 {
  template <int kOp, typename T, uint32_t S, bool kLru>
  [[gnu::target("avx2")]] static Outcome access(const Cache::OrderedGeometry& g, T* entries, uint64_t line) {
    static_assert(S == 16 && std::is_same_v<T, uint16_t>);
    return Cache::ordered_access16x16_avx2<kOp, kLru>(g, entries, line);
  }
};
const bool kCpuHasAvx2 = __builtin_cpu_supports("avx2");
#else
const bool kCpuHasAvx2 = false;
#endif
}  // namespace

void Hierarchy::use_avx2(bool on) { avx2_ = on && kCpuHasAvx2; }

// The wrappers inline the chunk's code into themselves, the AVX2 one compiled for AVX2.
template <uint32_t S1, typename T1, uint32_t S2, typename T2, bool kLru>
size_t Hierarchy::issue_chunk(const Request* rs, const uint32_t* cus, size_t n, IssueResult* out) {
  return issue_chunk_impl<S1, T1, S2, T2, kLru, L2Portable>(rs, cus, n, out);
}

#if defined(__x86_64__) && defined(__GNUC__)
template <bool kLru>
[[gnu::target("avx2")]] size_t Hierarchy::issue_chunk_avx2(const Request* rs, const uint32_t* cus, size_t n,
                                                           IssueResult* out) {
  return issue_chunk_impl<4, uint32_t, 16, uint16_t, kLru, L2Avx2>(rs, cus, n, out);
}
#endif

template <uint32_t S1, typename T1, uint32_t S2, typename T2, bool kLru, typename L2>
[[gnu::always_inline]] inline size_t Hierarchy::issue_chunk_impl(const Request* rs, const uint32_t* cus, size_t n,
                                                                 IssueResult* out) {
  // Round 1: the L1 lookups, in order; every request that goes on to the L2 is queued (written
  // always, kept by advancing the count only when it goes on: no branch on the outcome). It stops
  // before a line too wide for a cache's current entries; round 2 then completes the requests
  // before it.
  uint16_t* pending = pending_.data();
  size_t queued = 0;
  const bool l1_curves = !l1_mrc_.empty();
  const Cache::OrderedGeometry g1 = l1_geometry_, g2 = l2_geometry_;
  void* const* l1_entries = l1_entries_.data();
  T2* const l2_entries = static_cast<T2*>(l2_entries_);
  const uint64_t limit = fast_limit_;
  size_t done = 0;
  for (; done < n; ++done) {
    const size_t i = done;
    const Request& r = rs[i];
    const uint64_t line = r.line;
    if (line >= limit) [[unlikely]]
      break;
    uint32_t to_l2 = 1;
    Counts& c = counts_[r.buffer];
    if (r.kind == AccessKind::load) {
      ++c.l1_requests;
      if (l1_curves) feed_l1_mrc(cus[i], line);
      // Only loads reach an L1 (stores write through it, atomics bypass it): nothing in it is dirty.
      to_l2 = Cache::ordered_access<0, T1, S1, kLru, true>(g1, static_cast<T1*>(l1_entries[cus[i]]), line).missing;
      c.l1_misses += to_l2;
      if (out) out[i] = IssueResult{to_l2 != 0, false};
    } else {
      ++c.l2_direct;
      if (r.kind == AccessKind::store)
        ++stats_.stores;
      else
        ++stats_.atomics;
      if (out) out[i] = IssueResult{false, false};
    }
    pending[queued] = uint16_t(i);
    queued += to_l2;
  }
  // Round 2: the L2, in the same order as one by one.
  const bool l2_curve = l2_mrc_ != nullptr;
  uint64_t written_back = 0;
  constexpr size_t kAhead = 8;  // host prefetch of the L2 set that many accesses ahead
  for (size_t k = 0; k < std::min(queued, kAhead); ++k)
    __builtin_prefetch(l2_entries + size_t(rs[pending[k]].line & g2.set_mask) * S2);
  for (size_t k = 0; k < queued; ++k) {
    if (k + kAhead < queued) __builtin_prefetch(l2_entries + size_t(rs[pending[k + kAhead]].line & g2.set_mask) * S2);
    const uint32_t i = pending[k];
    const Request& r = rs[i];
    const uint64_t line = r.line;
    Counts& c = counts_[r.buffer];
    if (l2_curve) feed_l2_mrc(line);
    Outcome o;
    if (r.kind == AccessKind::load) {
      o = L2::template access<0, T2, S2, kLru>(g2, l2_entries, line);
    } else if (r.kind == AccessKind::store) {
      o = L2::template access<1, T2, S2, kLru>(g2, l2_entries, line);
      c.l2_store_misses += o.missing;
    } else {
      o = L2::template access<2, T2, S2, kLru>(g2, l2_entries, line);
    }
    c.l2_misses += o.missing;  // 0 or 1
    written_back += o.written_back_sectors;
    if (out) out[i].l2_miss = o.missing != 0;
  }
  written_back_ += written_back;
  return done;
}

void Hierarchy::enable_mrc(bool l1, bool l2, double sampling_rate) {
  const uint32_t line = l2_.config().line_bytes;
  l1_mrc_.clear();
  if (l1)
    for (size_t cu = 0; cu < l1_.size(); ++cu) l1_mrc_.push_back(std::make_unique<StackDistance>(line, sampling_rate));
  l2_mrc_ = l2 ? std::make_unique<StackDistance>(line, sampling_rate) : nullptr;
  l1_mrc_queue_.assign(l1_mrc_.size(), {});
  for (auto& q : l1_mrc_queue_) q.reserve(kMrcBatch);
  l2_mrc_queue_.clear();
  l2_mrc_queue_.reserve(kMrcBatch);
}

void Hierarchy::drain_mrc() const {
  for (size_t cu = 0; cu < l1_mrc_.size(); ++cu) {
    l1_mrc_[cu]->access(std::span<const uint64_t>(l1_mrc_queue_[cu]));
    l1_mrc_queue_[cu].clear();
  }
  if (l2_mrc_) {
    l2_mrc_->access(std::span<const uint64_t>(l2_mrc_queue_));
    l2_mrc_queue_.clear();
  }
}

void Hierarchy::begin_pass() {
  for (Cache& c : l1_) c.invalidate();
  stats_ = {};
  buffers_ = {};
  counts_ = {};
  written_back_ = 0;
  // Curves describe one pass too: restart them with the same settings.
  if (!l1_mrc_.empty() || l2_mrc_) {
    const bool l1 = !l1_mrc_.empty(), l2 = bool(l2_mrc_);
    const double rate = l2 ? l2_mrc_->sampling_rate() : l1_mrc_[0]->sampling_rate();
    enable_mrc(l1, l2, rate);
  }
}

void Hierarchy::flush() { stats_.dram_write_bytes += l2_.flush_dirty_sectors() * sector_bytes_; }

MissRatioCurve Hierarchy::l1_curve() const {
  drain_mrc();
  MissRatioCurve c;
  c.line_bytes = l2_.config().line_bytes;
  if (!l1_mrc_.empty()) c.sampling_rate = l1_mrc_[0]->curve().sampling_rate;
  for (const auto& m : l1_mrc_) c.merge(m->curve());
  return c;
}

MissRatioCurve Hierarchy::l2_curve() const {
  drain_mrc();
  if (l2_mrc_) return l2_mrc_->curve();
  MissRatioCurve c;
  c.line_bytes = l2_.config().line_bytes;
  return c;
}

}  // namespace hp::cachesim
