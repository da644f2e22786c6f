// One set-associative cache level: tags only (no data), sector valid and dirty masks per line.
//
// Speed is the point (over a hundred million lookups per second), so the state is flat arrays with a
// set's ways contiguous: tags, sector masks, and a 32-bit stamp per way. LRU stamps a way at every
// use, FIFO only at fill; the victim is the way with the oldest stamp (empty ways have stamp 0, so
// they fill first). A hit costs a tag scan and one store, a miss a scan of the stamps; nothing moves.
// Random replacement picks a victim with a seeded xorshift, preferring empty ways.
// Nothing allocates after construction.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

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

  const CacheConfig& config() const { return config_; }
  uint32_t line_shift() const { return line_shift_; }
  uint32_t sector_shift() const { return sector_shift_; }
  uint32_t full_mask() const { return full_mask_; }

  // Load: allocate on miss, fetch the missing requested sectors (lazy sector fill).
  Outcome load(uint64_t line, uint32_t sectors) { return access<kLoad>(line, sectors); }
  // Write-back store with write-validate: allocate, mark the sectors valid and dirty, fetch nothing.
  Outcome store(uint64_t line, uint32_t sectors) { return access<kStore>(line, sectors); }
  // Read-modify-write (atomics at the L2, write-allocate writes): allocate, fetch missing, mark dirty.
  Outcome update(uint64_t line, uint32_t sectors) { return access<kUpdate>(line, sectors); }
  // Presence of the sectors without any state change (write-through store probing an L1).
  bool contains(uint64_t line, uint32_t sectors) const;

  uint32_t set_index(uint64_t line) const {
    if (channels_ == 1) return uint32_t(line & set_mask_);
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
    return uint32_t(channel * sets_per_channel_ + (((rest << interleave_shift_) | within) & set_mask_));
  }

  // Hints the host CPU to fetch the line's set: replaying a known stream, the sets of upcoming
  // requests load in parallel instead of one host cache miss after another.
  void prefetch(uint64_t line) const {
    const size_t base = size_t(set_index(line)) * ways_per_set_;
    __builtin_prefetch(tags_.data() + base);
    __builtin_prefetch(stamp_.data() + base);
  }

  // Counts and clears dirty sectors (end-of-frame write-back).
  uint64_t flush_dirty_sectors();
  // Forgets every line (an L1 invalidated at a pipeline barrier).
  void invalidate();

 private:
  static constexpr uint64_t kEmpty = ~uint64_t(0);
  enum Op { kLoad, kStore, kUpdate };
  // Structure of arrays, a set's ways contiguous in each: the hit scan reads only tags (a 4-way set's
  // tags are 32 bytes, a 16-way set's two host cache lines).
  struct Meta {
    uint32_t valid;  // sector masks
    uint32_t dirty;
  };

  template <Op op>
  Outcome access(uint64_t line, uint32_t sectors) {
    const size_t base = size_t(set_index(line)) * ways_per_set_;
    const uint64_t* tags = tags_.data() + base;
    const uint32_t n = ways_per_set_;
    for (uint32_t i = 0; i < n; ++i) {
      if (tags[i] != line) continue;
      Meta& m = meta_[base + i];
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
    Meta& m = meta_[base + v];
    if (tags_[base + v] != kEmpty) o.written_back_sectors = uint32_t(std::popcount(m.dirty));
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

  CacheConfig config_;
  std::vector<uint64_t> tags_;   // line number (address >> line_shift); kEmpty when invalid
  std::vector<Meta> meta_;
  std::vector<uint32_t> stamp_;  // last use (LRU) or insertion (FIFO) time; 0 = never
  uint32_t clock_ = 0;
  uint32_t ways_per_set_ = 1;
  uint64_t set_mask_ = 0;  // of the sets within one channel
  uint32_t channels_ = 1;
  bool channel_pow2_ = true;
  uint32_t channel_shift_ = 0;
  uint32_t interleave_shift_ = 0;  // log2(interleave in lines)
  uint64_t interleave_mask_ = 0;
  uint64_t sets_per_channel_ = 1;
  uint32_t line_shift_ = 6, sector_shift_ = 6, full_mask_ = 1;
  Replacement replacement_ = Replacement::lru;
  uint64_t rng_ = 1;
};

}  // namespace hp::cachesim
