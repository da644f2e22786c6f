// Naive, obviously-correct reference caches for the tests: a std::list per set, front = most recent
// (LRU) or newest (FIFO), set index computed with plain division. Slow on purpose; nothing shared
// with the simulator's code but the CacheConfig it reads.
#pragma once

#include <bit>
#include <cstdint>
#include <list>
#include <vector>

#include "cachesim/cache.hpp"

namespace hp::cachesim::ref {

struct Line {
  uint64_t tag;
  uint32_t valid, dirty;
};

struct RefOutcome {
  uint32_t missing = 0;
  bool line_hit = false;
  uint32_t written_back = 0;
};

class RefCache {
 public:
  explicit RefCache(const CacheConfig& c) : c_(c) {
    channels_ = c.channels;
    sets_per_channel_ = c.size_bytes / (uint64_t(c.line_bytes) * c.ways * c.channels);
    interleave_lines_ = (c.channel_interleave_bytes ? c.channel_interleave_bytes : c.line_bytes) / c.line_bytes;
    sets_.resize(sets_per_channel_ * channels_);
  }
  uint64_t set_of(uint64_t line) const {
    const uint64_t chunk = line / interleave_lines_;
    const uint64_t channel = chunk % channels_;
    const uint64_t local = (chunk / channels_) * interleave_lines_ + line % interleave_lines_;
    return channel * sets_per_channel_ + local % sets_per_channel_;
  }
  // mode: 0 load (allocate, fill missing), 1 store (allocate, valid+dirty, no fetch), 2 update
  RefOutcome access(uint64_t line, uint32_t sectors, int mode) {
    auto& set = sets_[set_of(line)];
    RefOutcome o;
    for (auto it = set.begin(); it != set.end(); ++it) {
      if (it->tag != line) continue;
      o.line_hit = true;
      o.missing = sectors & ~it->valid;
      it->valid |= sectors;
      if (mode != 0) it->dirty |= sectors;
      if (c_.replacement == Replacement::lru) set.splice(set.begin(), set, it);
      return o;
    }
    o.missing = sectors;
    if (set.size() == c_.ways) {
      o.written_back = uint32_t(std::popcount(set.back().dirty));
      set.pop_back();
    }
    set.push_front(Line{line, sectors, mode != 0 ? sectors : 0u});
    return o;
  }
  bool contains(uint64_t line) const {
    for (const Line& l : sets_[set_of(line)])
      if (l.tag == line) return true;
    return false;
  }
  uint64_t dirty_sectors() const {
    uint64_t n = 0;
    for (const auto& s : sets_)
      for (const Line& l : s) n += uint64_t(std::popcount(l.dirty));
    return n;
  }

 private:
  CacheConfig c_;
  uint64_t channels_, sets_per_channel_, interleave_lines_;
  std::vector<std::list<Line>> sets_;
};

// Fully associative LRU of `lines` lines: misses of a line stream (for miss-ratio curves).
inline uint64_t fully_associative_misses(const std::vector<uint64_t>& stream, uint64_t lines) {
  std::list<uint64_t> stack;
  uint64_t misses = 0;
  for (uint64_t x : stream) {
    auto it = stack.begin();
    for (; it != stack.end(); ++it)
      if (*it == x) break;
    if (it == stack.end()) {
      ++misses;
      stack.push_front(x);
      if (stack.size() > lines) stack.pop_back();
    } else {
      stack.splice(stack.begin(), stack, it);
    }
  }
  return misses;
}

}  // namespace hp::cachesim::ref
