// One set-associative cache level: tags only (no data), sector valid and dirty masks per line.
//
// Speed is the point (well over a hundred million lookups per second on one host core), so the state
// is kept as small and as contiguous per set as the configuration allows, and the common case runs
// without a data-dependent branch. Three engines give identical results:
//
//  - ordered (unsectored, LRU or FIFO, at most 16 ways): a set is its lines' partial tags (the line
//    number without the set-index bits) in recency order (LRU; insertion order for FIFO), most recent
//    first, padded to 4, 8 or 16 entries with an empty marker and aligned to their size. The top bit
//    of an entry is the line's dirty bit. Sets of 8 or 16 ways have 16-bit entries while every tag
//    seen is below 2^15 - 1 (a 16-way set is then 32 bytes: two SSE registers); the first wider tag
//    widens them, once and exactly, to 32 bits (tags below 2^31 - 1; a 16-way set is one 64-byte
//    host line), which sets of 4 ways have from the start. A lookup compares the set 8 or 4 entries at a time; a hit at position p (or a miss, p =
//    the last way) shifts positions 0..p-1 down by one and writes the line at the front, which drops
//    the victim: one masked vector shift, the same instructions for a hit and a miss. Empty entries
//    sit at the back, so they fill first.
//  - compact (sectored, LRU or FIFO, at most 16 ways, tags below 2^32 - 1): the ways' partial tags
//    in way order, a 64-bit recency permutation of 4-bit way numbers per set (position 0 most
//    recent, the last used position the victim), and valid/dirty sector masks per way. LRU moves
//    the used way to the front, FIFO only a filled one. Empty ways start at the back in index order,
//    so they fill first and lowest first, as in the general engine.
//  - general (random replacement, more than 16 ways, or a tag too wide for the others): full line
//    numbers, sector masks and a 32-bit stamp per way; the victim is the oldest stamp (empty ways
//    have stamp 0). An ordered or compact cache that meets a line whose tag does not fit any of their
//    widths converts itself, once, to this engine, carrying its state over exactly (the recency order
//    becomes stamps 1..ways).
// A power-of-two number of L2 channels only renumbers the sets (the channel and the set within it
// are fixed bit fields of the line number), so such a cache indexes its sets by the low line bits.
// Nothing allocates after construction except those conversions.
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
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
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

// The largest cache the simulator accepts (size_bytes), with at most 4096-byte lines, 4096 ways, 1024 channels.
inline constexpr uint64_t kMaxCacheBytes = uint64_t(1) << 30;

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

namespace detail {
// Rows p = 0..15: entries 1..p all ones (the entries a move of position p to the front shifts).
template <typename T>
struct alignas(64) ShiftMasks {
  T row[16][16];
};
template <typename T>
constexpr ShiftMasks<T> make_shift_masks() {
  ShiftMasks<T> t{};
  for (uint32_t p = 0; p < 16; ++p)
    for (uint32_t lane = 1; lane <= p; ++lane) t.row[p][lane] = T(~T(0));
  return t;
}
}  // namespace detail

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
  enum class Engine : uint8_t { ordered16, ordered32, compact, general };
  // The engine in use (for tests and benchmarks; results do not depend on it).
  Engine engine() const { return engine_; }
  // Whether an engine with narrow tags (ordered or compact) is in use.
  bool compact() const { return engine_ != Engine::general; }
  bool sectored() const { return sectored_; }
  uint32_t stride() const { return stride_; }  // ordered and compact engines: ways padded to 4, 8 or 16

  // `sectors` is always a non-empty subset of full_mask() (1 without sectors).
  // Load: allocate on miss, fetch the missing requested sectors (lazy sector fill).
  [[gnu::always_inline]] Outcome load(uint64_t line, uint32_t sectors) { return access<kLoad>(line, sectors); }
  // Write-back store with write-validate: allocate, mark the sectors valid and dirty, fetch nothing.
  [[gnu::always_inline]] Outcome store(uint64_t line, uint32_t sectors) { return access<kStore>(line, sectors); }
  // Read-modify-write (atomics at the L2, write-allocate writes): allocate, fetch missing, mark dirty.
  [[gnu::always_inline]] Outcome update(uint64_t line, uint32_t sectors) { return access<kUpdate>(line, sectors); }

  // For a caller replaying many unsectored requests through caches of one shape (Hierarchy). With an
  // ordered engine and config().ways == stride() == kStride checked once, the set width is a
  // constant of its code. Lines below ordered_line_limit() have tags the current entries hold; for
  // them ordered_access is the same as load (kOp 0), store (1) or update (2) of (line, 1).
  uint64_t ordered_line_limit() const {
    return engine_ == Engine::ordered16 ? ordered16_limit_ : engine_ == Engine::ordered32 ? ordered32_limit_ : 0;
  }
  template <int kOp, uint32_t kStride>
  [[gnu::always_inline]] Outcome ordered_access(uint64_t line) {
    uint64_t tag;
    const size_t at = size_t(locate(line, tag)) * kStride;
    if constexpr (kStride >= 8) {  // 16-bit entries only serve 8 and 16 ways
      if (engine_ == Engine::ordered16)
        return ordered_set_access<Op(kOp), uint16_t, kStride>(tag16_.get() + at, uint32_t(tag), kStride - 1, lru_);
    }
    return ordered_set_access<Op(kOp), uint32_t, kStride>(tag32_.get() + at, uint32_t(tag), kStride - 1, lru_);
  }
  // The same without a call per request: the geometry of a cache whose sets are indexed by the low
  // line bits (plain_index()), read once, and its entries (T: uint16_t under ordered16, uint32_t under
  // ordered32), which stay put until the engine changes. ordered_access(geometry, entries, line) on a
  // line below ordered_line_limit() is ordered_access(line). kLru: the caller checked that g.lru is
  // set; kClean: the caller only ever loads through this cache (nothing in it is dirty).
  struct OrderedGeometry {
    uint64_t set_mask;
    uint32_t set_bits;
    bool lru;
  };
  bool plain_index() const { return plain_index_; }
  OrderedGeometry ordered_geometry() const { return {set_mask_, set_bits_, lru_}; }
  void* ordered_entries() {
    return engine_ == Engine::ordered16   ? static_cast<void*>(tag16_.get())
           : engine_ == Engine::ordered32 ? static_cast<void*>(tag32_.get())
                                          : nullptr;
  }
  template <int kOp, typename T, uint32_t kStride, bool kLru = false, bool kClean = false>
  [[gnu::always_inline]] static Outcome ordered_access(const OrderedGeometry& g, T* entries, uint64_t line) {
    return ordered_set_access<Op(kOp), T, kStride, kLru, kClean>(entries + size_t(line & g.set_mask) * kStride,
                                                                 uint32_t(line >> g.set_bits), kStride - 1, g.lru);
  }
#if defined(__x86_64__) && defined(__GNUC__)
  // ordered_access<kOp, uint16_t, 16, kLru> with AVX2: a 16-way set of 16-bit entries is one 256-bit
  // register. Only for a caller compiled for AVX2 (gnu::target("avx2")) that checked the CPU.
  template <int kOp, bool kLru>
  [[gnu::target("avx2"), gnu::always_inline]] static Outcome ordered_access16x16_avx2(const OrderedGeometry& g,
                                                                                      uint16_t* entries,
                                                                                      uint64_t line) {
    uint16_t* e = entries + size_t(line & g.set_mask) * 16;
    const uint32_t tag = uint32_t(line >> g.set_bits);
    const __m256i x = _mm256_load_si256(reinterpret_cast<const __m256i*>(e));
    const __m256i key = _mm256_set1_epi16(short(tag));
    const __m256i eq = _mm256_cmpeq_epi16(_mm256_and_si256(x, _mm256_set1_epi16(short(kTagBits<uint16_t>))), key);
    const uint32_t match = uint32_t(_mm256_movemask_epi8(eq));  // two bits per entry
    const uint32_t miss = match == 0;
    const uint32_t p = uint32_t(std::countr_zero(match | (1u << 30))) >> 1;  // the hit, or entry 15
    const uint32_t old = e[p];
    Outcome o;
    o.missing = miss;
    o.line_hit = !miss;
    o.written_back_sectors = miss & (old >> 15);
    if (!kLru && !g.lru) [[unlikely]] {
      if (!miss) {
        if constexpr (kOp != kLoad) e[p] = uint16_t(old | 0x8000u);
        return o;
      }
    }
    const uint32_t dirty = kOp == kLoad ? (old >> 15) & (miss ^ 1u) : 1u;
    // x moved up one entry across the two 128-bit halves, blended into entries 1..p, front written.
    const __m256i shifted = _mm256_alignr_epi8(x, _mm256_permute2x128_si256(x, x, 0x08), 14);
    const __m256i m = _mm256_load_si256(reinterpret_cast<const __m256i*>(kShiftMask<uint16_t>.row[p]));
    __m256i y = _mm256_blendv_epi8(x, shifted, m);
    const __m256i first = _mm256_setr_epi16(-1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0);
    y = _mm256_blendv_epi8(y, _mm256_set1_epi16(short(tag | (dirty << 15))), first);
    _mm256_store_si256(reinterpret_cast<__m256i*>(e), y);
    return o;
  }
#endif
  // Makes an ordered16 cache ordered32 (exactly; a caller that wants several caches in one width).
  void widen();

  // Presence of the sectors without any state change (write-through store probing an L1).
  bool contains(uint64_t line, uint32_t sectors) const;

  uint32_t set_index(uint64_t line) const {
    uint64_t tag;
    return locate(line, tag);
  }

  // Counts and clears dirty sectors (end-of-frame write-back).
  uint64_t flush_dirty_sectors();
  // Forgets every line (an L1 invalidated at a pipeline barrier).
  void invalidate();

 private:
  static constexpr uint64_t kEmpty = ~uint64_t(0);
  static constexpr uint32_t kEmpty32 = ~0u;  // compact engine: an empty or padding way
  // Ordered engine, per entry width: the tag bits (also the empty or padding entry: no tag reaches
  // it) and the dirty bit above them.
  template <typename T>
  static constexpr uint32_t kTagBits = sizeof(T) == 2 ? 0x7FFFu : 0x7FFFFFFFu;
  template <typename T>
  static constexpr uint32_t kDirtyShift = sizeof(T) * 8 - 1;
  enum Op { kLoad, kStore, kUpdate };
  struct Meta {
    uint32_t valid;  // sector masks
    uint32_t dirty;
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
    if (plain_index_) [[likely]] {
      tag = line >> set_bits_;
      return uint32_t(line & set_mask_);
    }
    const uint64_t chunk = line >> interleave_shift_;
    const uint64_t within = line & interleave_mask_;
    const uint64_t channel = chunk % channels_;
    const uint64_t rest = chunk / channels_;
    tag = rest >> (set_bits_ - interleave_shift_);
    return uint32_t((channel << set_bits_) | (((rest << interleave_shift_) | within) & set_mask_));
  }
  uint64_t line_of(uint32_t set, uint64_t tag) const;  // inverse of locate

  template <typename T>
  static constexpr detail::ShiftMasks<T> kShiftMask = detail::make_shift_masks<T>();

  // The ordered engine on one set's entries `e` (T: 16- or 32-bit entries): `tag` below kTagBits<T>,
  // `last` the last way (ways - 1); kLru: lru is known to be set; kClean: no entry is dirty and op is
  // a load. Without branches on the outcome under LRU.
  template <Op op, typename T, uint32_t kStride, bool kLru = false, bool kClean = false>
  [[gnu::always_inline]] static Outcome ordered_set_access(T* e, uint32_t tag, uint32_t last, bool lru) {
    static_assert(!kClean || op == kLoad);
    constexpr bool k16 = sizeof(T) == 2;
    static_assert(!k16 || kStride >= 8, "16-bit entries serve sets of 8 or 16 ways");
    constexpr uint32_t kShift = kDirtyShift<T>;
#if defined(__SSE2__)
    // Vectors of 8 (16-bit) or 4 (32-bit) entries.
    constexpr uint32_t kVec = kStride * sizeof(T) / 16;
    const __m128i key = k16 ? _mm_set1_epi16(short(tag)) : _mm_set1_epi32(int(tag));
    const __m128i tag_bits = k16 ? _mm_set1_epi16(short(kTagBits<T>)) : _mm_set1_epi32(int(kTagBits<T>));
    __m128i x[kVec], eq[kVec];
    for (uint32_t v = 0; v < kVec; ++v) {
      x[v] = _mm_load_si128(reinterpret_cast<const __m128i*>(e) + v);
      const __m128i t = kClean ? x[v] : _mm_and_si128(x[v], tag_bits);
      eq[v] = k16 ? _mm_cmpeq_epi16(t, key) : _mm_cmpeq_epi32(t, key);
    }
    // One bit per entry: the comparison masks (all ones or zeros) narrowed by saturating packs.
    uint32_t match;
    if constexpr (k16) {
      match = uint32_t(_mm_movemask_epi8(_mm_packs_epi16(eq[0], kVec > 1 ? eq[kVec - 1] : _mm_setzero_si128())));
    } else if constexpr (kVec == 1) {
      match = uint32_t(_mm_movemask_ps(_mm_castsi128_ps(eq[0])));
    } else if constexpr (kVec == 2) {
      match = uint32_t(_mm_movemask_epi8(_mm_packs_epi16(_mm_packs_epi32(eq[0], eq[1]), _mm_setzero_si128())));
    } else {
      match =
          uint32_t(_mm_movemask_epi8(_mm_packs_epi16(_mm_packs_epi32(eq[0], eq[1]), _mm_packs_epi32(eq[2], eq[3]))));
    }
#else
    uint32_t match = 0;
    for (uint32_t i = 0; i < kStride; ++i) match |= uint32_t((e[i] & kTagBits<T>) == tag) << i;
#endif
    const uint32_t miss = match == 0;
    const uint32_t p = uint32_t(std::countr_zero(match | (1u << last)));  // the hit, or the victim
    const uint32_t old = kClean ? 0u : uint32_t(e[p]);
    Outcome o;
    o.missing = miss;
    o.line_hit = !miss;
    o.written_back_sectors = miss & (old >> kShift);  // an empty entry is never dirty
    if (!kLru && !lru) [[unlikely]] {
      if (!miss) {  // FIFO: a hit keeps the order; a store or update only dirties the line
        if constexpr (op != kLoad) e[p] = T(old | (1u << kShift));
        return o;
      }
    }
    const uint32_t dirty = op == kLoad ? (old >> kShift) & (miss ^ 1u) : 1u;
    const uint32_t front = tag | (dirty << kShift);
#if defined(__SSE2__)
    // Entries 1..p take their predecessor's value: x shifted by one entry across the vectors.
    const T* mask = kShiftMask<T>.row[p];
    for (uint32_t v = kVec; v-- > 0;) {
      __m128i shifted = _mm_slli_si128(x[v], sizeof(T));
      if (v > 0) shifted = _mm_or_si128(shifted, _mm_srli_si128(x[v - 1], 16 - sizeof(T)));
      const __m128i m = _mm_load_si128(reinterpret_cast<const __m128i*>(mask) + v);
      x[v] = _mm_or_si128(_mm_and_si128(m, shifted), _mm_andnot_si128(m, x[v]));
    }
    if constexpr (k16)
      x[0] = _mm_insert_epi16(x[0], int(front), 0);
    else
      x[0] = _mm_castps_si128(_mm_move_ss(_mm_castsi128_ps(x[0]), _mm_castsi128_ps(_mm_cvtsi32_si128(int(front)))));
    for (uint32_t v = 0; v < kVec; ++v) _mm_store_si128(reinterpret_cast<__m128i*>(e) + v, x[v]);
#else
    for (uint32_t i = p; i > 0; --i) e[i] = e[i - 1];
    e[0] = T(front);
#endif
    return o;
  }

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

  // The ordered engine is small enough to inline into the caller; the compact (sectored) and general
  // engines and the conversion to the latter stay out of line.
  template <Op op>
  [[gnu::always_inline]] Outcome access(uint64_t line, uint32_t sectors) {
    if (engine_ == Engine::ordered16 && line < ordered16_limit_) [[likely]]
      return ordered_dispatch<op, uint16_t>(tag16_.get(), line);
    if (engine_ == Engine::ordered32 && line < ordered32_limit_) [[likely]]
      return ordered_dispatch<op, uint32_t>(tag32_.get(), line);
    return slow_access<op>(line, sectors);
  }
  template <Op op, typename T>
  [[gnu::always_inline]] Outcome ordered_dispatch(T* entries, uint64_t line) {
    uint64_t tag;
    T* e = entries + size_t(locate(line, tag)) * stride_;
    const uint32_t last = ways_per_set_ - 1;
    if constexpr (sizeof(T) == 4) {  // 16-bit entries only serve 8 and 16 ways
      if (stride_ == 4) return ordered_set_access<op, T, 4>(e, uint32_t(tag), last, lru_);
    }
    if (stride_ == 8) return ordered_set_access<op, T, 8>(e, uint32_t(tag), last, lru_);
    return ordered_set_access<op, T, 16>(e, uint32_t(tag), last, lru_);
  }
  template <Op op>
  [[gnu::noinline]] Outcome slow_access(uint64_t line, uint32_t sectors) {
    if (engine_ == Engine::compact) {
      uint64_t tag;
      const uint32_t set = locate(line, tag);
      if (tag < kEmpty32) {
        if (stride_ == 4) return compact_access<op, 4>(set, uint32_t(tag), sectors);
        if (stride_ == 8) return compact_access<op, 8>(set, uint32_t(tag), sectors);
        return compact_access<op, 16>(set, uint32_t(tag), sectors);
      }
    }
    if (engine_ == Engine::ordered16 && line < ordered32_limit_) {  // a tag too wide for 16 bits only
      widen();
      return ordered_dispatch<op, uint32_t>(tag32_.get(), line);
    }
    if (engine_ != Engine::general) to_general();  // a tag that no narrow engine holds
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
    return stride_ == 4   ? match_ways<4>(tags, tag)
           : stride_ == 8 ? match_ways<8>(tags, tag)
                          : match_ways<16>(tags, tag);
  }

  // The compact engine (sectored caches).
  template <Op op, uint32_t kStride>
  Outcome compact_access(uint32_t set, uint32_t tag, uint32_t sectors) {
    uint32_t* tags = tag32_.get() + size_t(set) * kStride;
    uint64_t& order = order_[set];
    const uint32_t match = match_ways<kStride>(tags, tag);
    Outcome o;
    if (match) {
      const uint32_t w = uint32_t(std::countr_zero(match));
      o.line_hit = true;
      Meta& m = meta_[size_t(set) * kStride + w];
      o.missing = sectors & ~m.valid;
      m.valid |= sectors;
      if constexpr (op != kLoad) m.dirty |= sectors;
      if (lru_) order = move_to_front(order, position_of(order, w), w);
      return o;
    }
    o.missing = sectors;
    const uint32_t last = ways_per_set_ - 1;
    const uint32_t v = uint32_t(order >> (4 * last)) & 0xF;
    order = move_to_front(order, last, v);
    Meta& m = meta_[size_t(set) * kStride + v];
    if (tags[v] != kEmpty32) o.written_back_sectors = count_bits(m.dirty);
    m = Meta{sectors, op == kLoad ? 0u : sectors};
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
  void init_small();  // the ordered or compact engine's empty state
  void init_general();
  void to_general();  // converts the ordered or compact state, exactly
  // The first line whose tag is at least `tag` (saturated; locate's tag grows with the line).
  uint64_t first_line_with_tag(uint64_t tag) const;

  CacheConfig config_;
  Engine engine_ = Engine::general;
  bool sectored_ = false, lru_ = true;
  uint32_t ways_per_set_ = 1;
  uint32_t stride_ = 4;  // compact: ways padded to 4, 8 or 16
  uint32_t sets_ = 1;
  uint64_t set_mask_ = 0;  // of the sets within one channel
  uint32_t set_bits_ = 0;  // log2(sets per channel)
  uint32_t channels_ = 1;
  bool plain_index_ = true;        // one channel or a power of two: the set is the low line bits
  uint32_t interleave_shift_ = 0;  // log2(interleave in lines)
  uint64_t interleave_mask_ = 0;
  uint64_t sets_per_channel_ = 1;
  uint32_t line_shift_ = 6, sector_shift_ = 6, full_mask_ = 1;
  Replacement replacement_ = Replacement::lru;
  uint64_t rng_ = 1;

  // Ordered and compact engines.
  Aligned<uint16_t> tag16_;                             // ordered16: sets_ * stride_ entries
  Aligned<uint32_t> tag32_;                             // sets_ * stride_ entries (ordered32) or partial tags (compact)
  uint64_t ordered16_limit_ = 0, ordered32_limit_ = 0;  // the first lines whose tags 16 / 32-bit entries cannot hold
  // Compact engine.
  Aligned<uint64_t> order_;  // sets_ recency permutations
  std::vector<Meta> meta_;   // sets_ * stride_

  // General engine.
  std::vector<uint64_t> tags_;  // line number (address >> line_shift); kEmpty when invalid
  std::vector<Meta> gmeta_;
  std::vector<uint32_t> stamp_;  // last use (LRU) or insertion (FIFO) time; 0 = never
  uint32_t clock_ = 0;
};

}  // namespace hp::cachesim
