// One set-associative cache level: tags only (no data), sector valid and dirty masks per line.
//
// Speed is the point (over a hundred million lookups per second on one host core), and a replay's
// time goes almost entirely to host cache misses on the tag arrays, so the state is kept as small
// and as contiguous per set as the configuration allows. Two engines give identical results:
//
//  - compact (LRU or FIFO, at most 16 ways, every tag seen so far below 2^32 - 1): a set is its
//    ways' 32-bit partial tags (the line number without the set-index bits), padded to 4, 8 or 16
//    ways and aligned so that a 16-way set is one 64-byte host line, compared four at a time; plus a
//    16-byte state word pair: the recency order of the ways as a permutation of 4-bit way numbers
//    (position 0 most recent, the last used position the victim) and, without sectors, one dirty bit
//    per way. LRU moves the used way to the front, FIFO only a filled one. Empty ways start at the
//    back in index order, so they fill first and lowest first, as in the general engine. A sectored
//    cache keeps valid/dirty sector masks per way in a separate array.
//  - general (random replacement, more than 16 ways, or a tag that does not fit 32 bits): full line
//    numbers, sector masks and a 32-bit stamp per way; the victim is the oldest stamp (empty ways
//    have stamp 0). A compact cache that meets a line whose tag does not fit converts itself, once,
//    to this engine, carrying its state over exactly (the recency order becomes stamps 1..ways).
// Nothing allocates after construction except that one conversion.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>
#include <memory>
#include <new>
#include <string>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace hp::cachesim {

enum class Replacement : uint8_t { lru, fifo, random };

struct CacheConfig {
  uint64_t size_bytes = 16 * 1024;
  uint32_t line_bytes = 64;
  uint32_t sector_bytes = 64;  // == line_bytes: no sectors
  uint32_t ways = 4;
  // Address slicing (L2 channels): consecutive chunks of channel_interleave_bytes go to consecutive
  // channels, each channel holding size_bytes / channels. 1 channel = a plain cache.
  uint32_t channels = 1;
  uint32_t channel_interleave_bytes = 0;  // 0: one line
  Replacement replacement = Replacement::lru;
  uint64_t seed = 1;  // random replacement only

  uint32_t sectors_per_line() const { return line_bytes / sector_bytes; }
  uint64_t lines() const { return size_bytes / line_bytes; }
};

// Empty when the configuration is possible, else "key: reason" naming the offending field.
std::string check_config(const CacheConfig& c);
// "16 KiB, 64 B lines, 4-way, LRU" style one-line description.
std::string describe(const CacheConfig& c);
const char* to_string(Replacement r);

// Population count without a library call: the default x86-64 target has no POPCNT instruction, and
// GCC then calls __popcountdi2 through the PLT, which cost more than a whole cache lookup here.
inline uint32_t count_bits(uint32_t x) {
#if defined(__POPCNT__) || !(defined(__x86_64__) || defined(__i386__))
  return uint32_t(std::popcount(x));
#else
  x = x - ((x >> 1) & 0x55555555u);
  x = (x & 0x33333333u) + ((x >> 2) & 0x33333333u);
  return (((x + (x >> 4)) & 0x0F0F0F0Fu) * 0x01010101u) >> 24;
#endif
}
inline uint32_t count_bits(uint64_t x) {
#if defined(__POPCNT__) || !(defined(__x86_64__) || defined(__i386__))
  return uint32_t(std::popcount(x));
#else
  x = x - ((x >> 1) & 0x5555555555555555ull);
  x = (x & 0x3333333333333333ull) + ((x >> 2) & 0x3333333333333333ull);
  return uint32_t((((x + (x >> 4)) & 0x0F0F0F0F0F0F0F0Full) * 0x0101010101010101ull) >> 56);
#endif
}

// What one access did: sectors of the request that were not present before it, whether the line's
// tag was present, and how many dirty sectors the eviction it caused wrote back.
struct Outcome {
  uint32_t missing = 0;
  bool line_hit = false;
  uint32_t written_back_sectors = 0;
};

class Cache {
 public:
  // The configuration must pass check_config.
  explicit Cache(const CacheConfig& config);
  Cache(const Cache& o);
  Cache& operator=(const Cache& o);
  Cache(Cache&&) noexcept = default;
  Cache& operator=(Cache&&) noexcept = default;

  const CacheConfig& config() const { return config_; }
  uint32_t line_shift() const { return line_shift_; }
  uint32_t sector_shift() const { return sector_shift_; }
  uint32_t full_mask() const { return full_mask_; }
  // Whether the compact engine is in use (for tests and benchmarks; results do not depend on it).
  bool compact() const { return compact_; }

  // `sectors` is always a non-empty subset of full_mask() (1 without sectors).
  // Load: allocate on miss, fetch the missing requested sectors (lazy sector fill).
  [[gnu::always_inline]] Outcome load(uint64_t line, uint32_t sectors) { return access<kLoad>(line, sectors); }
  // Write-back store with write-validate: allocate, mark the sectors valid and dirty, fetch nothing.
  [[gnu::always_inline]] Outcome store(uint64_t line, uint32_t sectors) { return access<kStore>(line, sectors); }
  // Read-modify-write (atomics at the L2, write-allocate writes): allocate, fetch missing, mark dirty.
  [[gnu::always_inline]] Outcome update(uint64_t line, uint32_t sectors) { return access<kUpdate>(line, sectors); }
  // The same as load (kOp 0), store (1) or update (2) of (line, 1), for a caller that has checked
  // once that the cache is unsectored with compact sets of exactly kStride ways (config().ways ==
  // stride() == kStride): the set width is a constant of the caller's code, not a branch per access.
  template <int kOp, uint32_t kStride>
  [[gnu::always_inline]] Outcome access_unsectored(uint64_t line) {
    if (compact_) [[likely]] {
      uint64_t tag;
      const uint32_t set = locate(line, tag);
      if (tag < kEmpty32) [[likely]] return compact_access<Op(kOp), false, kStride, kStride>(set, uint32_t(tag), 1);
    }
    return slow_access<Op(kOp)>(line, 1);
  }
  bool sectored() const { return sectored_; }
  uint32_t stride() const { return stride_; }  // compact engine: ways padded to 4, 8 or 16

  // Presence of the sectors without any state change (write-through store probing an L1).
  bool contains(uint64_t line, uint32_t sectors) const;

  uint32_t set_index(uint64_t line) const {
    uint64_t tag;
    return locate(line, tag);
  }

  // Hints the host CPU to fetch the line's set: replaying a known stream, the sets of upcoming
  // requests load in parallel instead of one host cache miss after another.
  void prefetch(uint64_t line) const {
    const size_t set = set_index(line);
    if (compact_) {
      __builtin_prefetch(tag32_.get() + set * stride_);
      __builtin_prefetch(state_.get() + set);
    } else {
      __builtin_prefetch(tags_.data() + set * ways_per_set_);
      __builtin_prefetch(stamp_.data() + set * ways_per_set_);
    }
  }

  // Counts and clears dirty sectors (end-of-frame write-back).
  uint64_t flush_dirty_sectors();
  // Forgets every line (an L1 invalidated at a pipeline barrier).
  void invalidate();

 private:
  static constexpr uint64_t kEmpty = ~uint64_t(0);
  static constexpr uint32_t kEmpty32 = ~0u;
  enum Op { kLoad, kStore, kUpdate };
  struct Meta {
    uint32_t valid;  // sector masks
    uint32_t dirty;
  };
  // Compact engine, per set: recency permutation (4 bits per position, position 0 most recent;
  // positions past the last way hold 0xF, which no searched way number equals) and dirty bits per
  // way (unsectored caches only; sectored ones keep Meta per way).
  struct alignas(16) SetState {
    uint64_t order;
    uint32_t dirty;
    uint32_t unused;
  };
  struct AlignedFree {
    void operator()(void* p) const { ::operator delete[](p, std::align_val_t(64)); }
  };
  template <typename T>
  using Aligned = std::unique_ptr<T[], AlignedFree>;
  template <typename T>
  static Aligned<T> aligned_array(size_t n) {
    return Aligned<T>(static_cast<T*>(::operator new[](n * sizeof(T), std::align_val_t(64))));
  }

  // Set of a line and the line's tag within that set (the line number without the set-index bits;
  // (set, tag) determines the line).
  [[gnu::always_inline]] uint32_t locate(uint64_t line, uint64_t& tag) const {
    if (channels_ == 1) {
      tag = line >> set_bits_;
      return uint32_t(line & set_mask_);
    }
    const uint64_t chunk = line >> interleave_shift_;
    const uint64_t within = line & interleave_mask_;
    uint64_t channel, rest;
    if (channel_pow2_) {
      channel = chunk & (channels_ - 1);
      rest = chunk >> channel_shift_;
    } else {
      channel = chunk % channels_;
      rest = chunk / channels_;
    }
    tag = rest >> (set_bits_ - interleave_shift_);
    return uint32_t((channel << set_bits_) | (((rest << interleave_shift_) | within) & set_mask_));
  }
  uint64_t line_of(uint32_t set, uint64_t tag) const;  // inverse of locate

  // Position (0 = most recent) of way w in a recency permutation.
  [[gnu::always_inline]] static uint32_t position_of(uint64_t order, uint32_t w) {
    const uint64_t x = order ^ (uint64_t(w) * 0x1111111111111111ull);  // w's nibble becomes 0
    // Lowest zero nibble of x (exact for the lowest; w occurs once among the used positions).
    const uint64_t z = (x - 0x1111111111111111ull) & ~x & 0x8888888888888888ull;
    return uint32_t(std::countr_zero(z)) >> 2;
  }
  [[gnu::always_inline]] static uint64_t move_to_front(uint64_t order, uint32_t pos, uint32_t w) {
    const uint64_t below = (uint64_t(1) << (4 * pos)) - 1;
    const uint64_t upto = below | (uint64_t(0xF) << (4 * pos));
    return (order & ~upto) | ((order & below) << 4) | w;
  }

  // The hot path (compact, unsectored) is small enough to inline into the caller; sectored sets,
  // the general engine and the conversion to it stay out of line.
  template <Op op>
  [[gnu::always_inline]] Outcome access(uint64_t line, uint32_t sectors) {
    if (compact_) {
      uint64_t tag;
      const uint32_t set = locate(line, tag);
      if (tag < kEmpty32) [[likely]] {
        const uint32_t t = uint32_t(tag);
        if (!sectored_) [[likely]] {
          if (stride_ == 4) return compact_access<op, false, 4>(set, t, sectors);
          if (stride_ == 8) return compact_access<op, false, 8>(set, t, sectors);
          return compact_access<op, false, 16>(set, t, sectors);
        }
        return sectored_access<op>(set, t, sectors);
      }
    }
    return slow_access<op>(line, sectors);
  }
  template <Op op>
  [[gnu::noinline]] Outcome sectored_access(uint32_t set, uint32_t t, uint32_t sectors) {
    if (stride_ == 4) return compact_access<op, true, 4>(set, t, sectors);
    if (stride_ == 8) return compact_access<op, true, 8>(set, t, sectors);
    return compact_access<op, true, 16>(set, t, sectors);
  }
  template <Op op>
  [[gnu::noinline]] Outcome slow_access(uint64_t line, uint32_t sectors) {
    if (compact_) to_general();  // only reached with a tag that does not fit 32 bits
    return general_access<op>(line, sectors);
  }

  // Bit i set when way i of the set holds `tag` (padding ways hold kEmpty32, never a real tag).
  // The set's width is a template argument so the comparison unrolls.
  template <uint32_t kStride>
  [[gnu::always_inline]] static uint32_t match_ways(const uint32_t* tags, uint32_t tag) {
#if defined(__SSE2__)
    const __m128i key = _mm_set1_epi32(int(tag));
    uint32_t m = 0;
    for (uint32_t c = 0; c < kStride; c += 4) {
      const __m128i t = _mm_load_si128(reinterpret_cast<const __m128i*>(tags + c));
      m |= uint32_t(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(t, key)))) << c;
    }
    return m;
#else
    uint32_t m = 0;
    for (uint32_t i = 0; i < kStride; ++i) m |= uint32_t(tags[i] == tag) << i;
    return m;
#endif
  }
  uint32_t match_ways(const uint32_t* tags, uint32_t tag) const {
    return stride_ == 4 ? match_ways<4>(tags, tag) : stride_ == 8 ? match_ways<8>(tags, tag) : match_ways<16>(tags, tag);
  }

  // kWays: the number of ways when the caller knows it (then == kStride), else 0: read at run time.
  template <Op op, bool sectored, uint32_t kStride, uint32_t kWays = 0>
  [[gnu::always_inline]] Outcome compact_access(uint32_t set, uint32_t tag, uint32_t sectors) {
    uint32_t* tags = tag32_.get() + size_t(set) * kStride;
    SetState& st = state_[set];
    const uint32_t match = match_ways<kStride>(tags, tag);
    Outcome o;
    if (match) {
      const uint32_t w = uint32_t(std::countr_zero(match));
      o.line_hit = true;
      if constexpr (sectored) {
        Meta& m = meta_[size_t(set) * kStride + w];
        o.missing = sectors & ~m.valid;
        m.valid |= sectors;
        if constexpr (op != kLoad) m.dirty |= sectors;
      } else {
        // Without sectors a present line is wholly valid.
        if constexpr (op != kLoad) st.dirty |= 1u << w;
      }
      if (lru_) st.order = move_to_front(st.order, position_of(st.order, w), w);
      return o;
    }
    o.missing = sectors;
    const uint32_t last = (kWays ? kWays : ways_per_set_) - 1;
    const uint32_t v = uint32_t(st.order >> (4 * last)) & 0xF;
    st.order = move_to_front(st.order, last, v);
    if constexpr (sectored) {
      Meta& m = meta_[size_t(set) * kStride + v];
      if (tags[v] != kEmpty32) o.written_back_sectors = count_bits(m.dirty);
      m = Meta{sectors, op == kLoad ? 0u : sectors};
    } else {
      o.written_back_sectors = (st.dirty >> v) & 1u;  // an empty way is never dirty
      if constexpr (op == kLoad)
        st.dirty &= ~(1u << v);
      else
        st.dirty |= 1u << v;
    }
    tags[v] = tag;
    return o;
  }

  template <Op op>
  Outcome general_access(uint64_t line, uint32_t sectors) {
    const size_t base = size_t(set_index(line)) * ways_per_set_;
    const uint64_t* tags = tags_.data() + base;
    const uint32_t n = ways_per_set_;
    for (uint32_t i = 0; i < n; ++i) {
      if (tags[i] != line) continue;
      Meta& m = gmeta_[base + i];
      Outcome o;
      o.line_hit = true;
      o.missing = sectors & ~m.valid;
      m.valid |= sectors;
      if constexpr (op != kLoad) m.dirty |= sectors;
      if (replacement_ == Replacement::lru) stamp_[base + i] = tick();
      return o;
    }
    Outcome o;
    o.missing = sectors;
    uint32_t v = 0;
    if (replacement_ != Replacement::random) {
      // Oldest stamp: least recently used (LRU) or first inserted (FIFO); empty ways have stamp 0.
      const uint32_t* st = stamp_.data() + base;
      uint32_t best = st[0];
      for (uint32_t i = 1; i < n; ++i)
        if (st[i] < best) best = st[i], v = i;
    } else {
      v = n;
      for (uint32_t i = 0; i < n; ++i)
        if (tags[i] == kEmpty) {
          v = i;
          break;
        }
      if (v == n) {
        rng_ ^= rng_ << 13;
        rng_ ^= rng_ >> 7;
        rng_ ^= rng_ << 17;
        v = uint32_t(rng_ % n);
      }
    }
    Meta& m = gmeta_[base + v];
    if (tags_[base + v] != kEmpty) o.written_back_sectors = count_bits(m.dirty);
    tags_[base + v] = line;
    m = Meta{sectors, op == kLoad ? 0u : sectors};
    stamp_[base + v] = tick();
    return o;
  }

  // Access clock for LRU/FIFO stamps. Before it would wrap, every set's stamps are replaced by their
  // ranks (order is all that matters), so 32-bit stamps stay exact on any trace length.
  uint32_t tick() {
    if (clock_ == ~0u) renumber_stamps();
    return ++clock_;
  }
  void renumber_stamps();
  void init_compact();
  void init_general();
  void to_general();  // converts the compact state, exactly

  CacheConfig config_;
  bool compact_ = false, sectored_ = false, lru_ = true;
  uint32_t ways_per_set_ = 1;
  uint32_t stride_ = 4;  // compact: ways padded to 4, 8 or 16
  uint32_t sets_ = 1;
  uint64_t set_mask_ = 0;  // of the sets within one channel
  uint32_t set_bits_ = 0;  // log2(sets per channel)
  uint32_t channels_ = 1;
  bool channel_pow2_ = true;
  uint32_t channel_shift_ = 0;
  uint32_t interleave_shift_ = 0;  // log2(interleave in lines)
  uint64_t interleave_mask_ = 0;
  uint64_t sets_per_channel_ = 1;
  uint32_t line_shift_ = 6, sector_shift_ = 6, full_mask_ = 1;
  Replacement replacement_ = Replacement::lru;
  uint64_t rng_ = 1;

  // Compact engine.
  Aligned<uint32_t> tag32_;    // sets_ * stride_ partial tags, kEmpty32 when invalid or padding
  Aligned<SetState> state_;    // sets_
  std::vector<Meta> meta_;     // sectored only: sets_ * stride_

  // General engine.
  std::vector<uint64_t> tags_;   // line number (address >> line_shift); kEmpty when invalid
  std::vector<Meta> gmeta_;
  std::vector<uint32_t> stamp_;  // last use (LRU) or insertion (FIFO) time; 0 = never
  uint32_t clock_ = 0;
};

}  // namespace hp::cachesim
