// Miss-ratio curves by LRU stack distance: one pass over an access stream gives the miss count of a
// fully associative LRU cache of EVERY size, because LRU is a stack algorithm (Mattson et al., 1970):
// an access hits in a cache of C lines exactly when fewer than C distinct other lines were touched
// since the previous access to the same line.
//
// StackDistance computes that distance exactly (Olken, 1981: count the distinct lines touched since
// the line's previous access), laid out for the host's caches, since a replay's time goes to host
// cache misses:
//  - every line's latest access time lives in a page of 16 consecutive lines (one 64-byte host
//    line), found through a small open-addressed table of pages; GPU buffers are dense, so the
//    pages of a trace take 4 bytes per line instead of a hash slot per line.
//  - a bitmap over access times holds a 1 at the latest time of every line seen (a line's older
//    times are cleared), so the distance of a re-access is the number of 1s after its previous time:
//    a popcount of the bitmap words when that time is recent, else the 1s left in its 512-time block
//    plus a Fenwick tree over the counts of whole blocks (a few KiB, so it stays in the host's L1).
//  - times are renumbered (compacted) to ranks when the window fills; each line's new time is its
//    rank, read off the same bitmap, so memory stays proportional to the lines seen, not accesses.
//
// SHARDS (Waldspurger et al., FAST 2015) is the sampled option: only lines whose hash falls under
// rate * 2^24 are tracked and their distances scaled by 1/rate. Cheaper for very large footprints,
// accurate only for caches much larger than 1/rate lines (see docs/cache-model.md).
#pragma once

#include <cstdint>
#include <iosfwd>
#include <span>
#include <string>
#include <vector>

namespace hp::cachesim {

// Histogram of stack distances, in lines. Miss counts of any fully associative LRU size follow.
struct MissRatioCurve {
  uint32_t line_bytes = 64;
  double sampling_rate = 1.0;       // 1: exact; < 1: SHARDS estimate
  uint64_t accesses = 0;            // tracked accesses (sampled ones for SHARDS)
  uint64_t cold = 0;                // first accesses to a line (misses at every size)
  std::vector<uint64_t> histogram;  // histogram[d]: re-accesses at distance d (hit iff d < lines)

  // Misses of a fully associative LRU cache holding `lines` lines (tracked accesses, unscaled).
  uint64_t misses(uint64_t lines) const;
  double miss_ratio(uint64_t lines) const { return accesses ? double(misses(lines)) / double(accesses) : 0.0; }
  // Largest distance seen + 1: beyond this size only cold misses remain.
  uint64_t footprint_lines() const { return histogram.size(); }
  void merge(const MissRatioCurve& other);  // sums histograms (per-CU L1 curves -> one L1 curve)
};

class StackDistance {
 public:
  static constexpr uint64_t kCold = ~uint64_t(0);

  // sampling_rate 1.0 = exact; (0, 1) = SHARDS fixed-rate sampling.
  explicit StackDistance(uint32_t line_bytes = 64, double sampling_rate = 1.0);

  // Records an access to a line (line number, not byte address); returns its exact distance in
  // tracked lines, kCold for a first access, or kCold too for an access the sampler skipped.
  uint64_t access(uint64_t line);

  // The same as access() on each line in order, with the host memory of upcoming lines fetched
  // ahead (their page-table slot, then their page), so the random accesses of consecutive lines
  // overlap instead of waiting one after another.
  void access(std::span<const uint64_t> lines);

  // The curve so far (its histogram is copied out of the 32-bit working counts when it changed).
  const MissRatioCurve& curve() const {
    if (histogram_stale_) publish_histogram();
    return curve_;
  }
  double sampling_rate() const { return curve_.sampling_rate; }
  uint64_t distinct_lines() const { return live_; }

 private:
  static constexpr uint32_t kPageBits = 4;   // 16 lines' times per page: one 64-byte host line
  static constexpr uint32_t kBlockBits = 9;  // 512 times per Fenwick block: 8 bitmap words

  uint32_t* page_of(uint64_t line);
  void prefetch_page(uint64_t line) const;  // the line's page, created (all "never seen") when new
  void grow_pages();
  void compact();
  // kHw: count bits with the POPCNT instruction (only called where the host has it; see
  // access()): the far-distance path counts up to 8 bitmap words per access.
  template <bool kHw>
  uint64_t ones_after(uint32_t t) const;  // set bits of the bitmap at times > t
  void tree_add(uint32_t block, int32_t delta);
  uint64_t tree_prefix(uint32_t block) const;  // ones in blocks [0, block]
  void rebuild_tree();

  template <bool kHw>
  uint64_t access_one(uint64_t line);
  template <bool kHw>
  void access_batch(std::span<const uint64_t> lines);
  uint64_t access_hw(uint64_t line);                      // access_one<true>, compiled for POPCNT
  void access_batch_hw(std::span<const uint64_t> lines);  // access_batch<true>, likewise
  bool hw_popcount_ = false;
  uint32_t* new_page(uint64_t key);
  void count_distance(uint64_t bucket);
  void publish_histogram() const;

  // curve_.histogram is published from counts_ (+ carry_) by curve(): the working histogram takes 4
  // bytes per distance instead of 8, and it is the one structure of this class that every re-access
  // touches at a random place (its distance), so it should be as small as possible.
  mutable MissRatioCurve curve_;
  mutable bool histogram_stale_ = false;
  // Each increment is deferred by kPending accesses, its bucket fetched meanwhile (sums commute;
  // the histogram's growth is decided at once, so its length is unchanged); curve() flushes them.
  static constexpr uint32_t kPending = 16;
  mutable std::vector<uint32_t> counts_;  // low 32 bits of each bucket, sized as curve_.histogram will be
  mutable std::vector<uint64_t> carry_;   // multiples of 2^32 carried out of counts_ (empty until one wraps)
  mutable uint64_t pending_[kPending];    // buckets still to count, kCold = none
  mutable uint32_t pending_next_ = 0;
  void count_now(uint64_t bucket) const {
    if (++counts_[bucket] == 0) [[unlikely]] {  // wrapped: carry 2^32 into the wide part
      if (carry_.size() <= bucket) carry_.resize(counts_.size(), 0);
      carry_[bucket] += uint64_t(1) << 32;
    }
  }
  uint64_t sample_threshold_;  // hash < threshold (of 2^24) is tracked
  bool sampled_ = false;
  double scale_ = 1.0;

  // Pages: key (line >> kPageBits) -> index into times_, open addressing, at most half full.
  struct PageSlot {
    uint64_t key;
    uint64_t page;  // offset of the page's first entry in times_
  };
  std::vector<PageSlot> page_table_;
  uint64_t page_mask_ = 0, pages_ = 0;
  uint64_t last_key_ = ~uint64_t(0), last_page_ = 0;  // consecutive accesses often share a page
  std::vector<uint32_t> times_;                       // per line: latest access time + 1, 0 = never seen

  std::vector<uint64_t> bits_;  // bitmap over times [0, capacity)
  std::vector<uint32_t> tree_;  // Fenwick tree, 1-based, over block counts
  uint32_t capacity_ = 0, now_ = 0;
  uint64_t live_ = 0;
};

// CSV "level,size_bytes,lines,miss_ratio" at each power-of-two size and the midpoint between powers,
// from one line up to the footprint (plus one row past it).
void write_mrc_csv(std::ostream& out, const std::string& level, const MissRatioCurve& curve);

}  // namespace hp::cachesim
