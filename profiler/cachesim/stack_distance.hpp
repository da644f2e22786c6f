// Miss-ratio curves by LRU stack distance: one pass over an access stream gives the miss count of a
// fully associative LRU cache of EVERY size, because LRU is a stack algorithm (Mattson et al., 1970):
// an access hits in a cache of C lines exactly when fewer than C distinct other lines were touched
// since the previous access to the same line.
//
// StackDistance computes that distance exactly in O(log n) per access (Olken, 1981): a Fenwick tree
// over access times holds a 1 at the latest access time of every line seen so far, so the distance
// of a re-access is the number of 1s after the line's previous time. Times are renumbered (compacted)
// when the tree fills, so memory stays proportional to the number of distinct lines, not accesses.
//
// SHARDS (Waldspurger et al., FAST 2015) is the sampled option: only lines whose hash falls under
// rate * 2^24 are tracked and their distances scaled by 1/rate. Cheaper for very large footprints,
// accurate only for caches much larger than 1/rate lines (see docs/cache-model.md).
#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

namespace hp::cachesim {

// Histogram of stack distances, in lines. Miss counts of any fully associative LRU size follow.
struct MissRatioCurve {
  uint32_t line_bytes = 64;
  double sampling_rate = 1.0;  // 1: exact; < 1: SHARDS estimate
  uint64_t accesses = 0;       // tracked accesses (sampled ones for SHARDS)
  uint64_t cold = 0;           // first accesses to a line (misses at every size)
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

  const MissRatioCurve& curve() const { return curve_; }
  uint64_t distinct_lines() const { return live_; }

 private:
  uint32_t find_or_insert(uint64_t line, bool& inserted);
  void grow_table();
  void compact();
  uint64_t prefix(uint32_t t) const;  // live entries with time <= t
  void add(uint32_t t, int32_t delta);

  MissRatioCurve curve_;
  uint64_t sample_threshold_;  // hash < threshold (of 2^24) is tracked
  bool sampled_ = false;
  double scale_ = 1.0;

  // Open-addressed hash: line -> slot; slot holds the line's latest time.
  std::vector<uint64_t> keys_;
  std::vector<uint32_t> times_;
  uint64_t table_mask_ = 0, table_used_ = 0;

  std::vector<uint32_t> tree_;    // Fenwick tree, 1-based, over times [0, capacity)
  std::vector<uint32_t> owner_;   // time -> slot in the hash table (for compaction)
  uint32_t capacity_ = 0, now_ = 0;
  uint64_t live_ = 0;
};

// CSV "level,size_bytes,lines,miss_ratio" at each power-of-two size and the midpoint between powers,
// from one line up to the footprint (plus one row past it).
void write_mrc_csv(std::ostream& out, const std::string& level, const MissRatioCurve& curve);

}  // namespace hp::cachesim
