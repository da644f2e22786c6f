// Replays a Dinero IV text trace through one L1 and one L2 with Dinero IV's accounting, so a trace
// exported by `hybridprof trace --export-din` (or any Dinero trace) gives numbers comparable with
// `dineroIV -l1-dsize 16k -l1-dbsize 64 -l1-dassoc 4 -l2-usize 4m -l2-ubsize 64 -l2-uassoc 16`:
//   - every access is split into the L1 blocks it spans: each block is one demand fetch;
//   - L1: LRU, write-allocate, write-back (Dinero's defaults); a write miss fetches the block;
//   - L2 demand fetches are the L1 misses: each missing L1 block asks the L2 for the L2 blocks it
//     covers (one when L2 blocks are at least as large), typed by the access that missed;
//   - levels are non-inclusive; dirty L1 evictions are counted as copies back and, unlike Dinero, are
//     not replayed into the L2 (so L2 fetches stay exactly the L1 misses).
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>

#include "cachesim/cache.hpp"
#include "cachesim/stack_distance.hpp"
#include "trace/din.hpp"

namespace hp::cachesim {

struct DinLevelStats {
  uint64_t fetches = 0, read_fetches = 0, write_fetches = 0;
  uint64_t misses = 0, read_misses = 0, write_misses = 0;
  double miss_ratio() const { return fetches ? double(misses) / double(fetches) : 0.0; }
};

struct DinResult {
  DinLevelStats l1, l2;
  uint64_t l1_copies_back = 0;        // dirty L1 blocks evicted
  MissRatioCurve l1_curve, l2_curve;  // when requested
};

// Parses "SIZE:LINE:ASSOC" (SIZE with optional k/m/g suffix, e.g. 16k:64:4); throws InputError
// naming `option` when malformed or impossible.
CacheConfig parse_cache_spec(const std::string& spec, const std::string& option);

// The replay as a stream: access() batches in file order, result() at any point. replay_din is one
// call of access() on the whole span.
class DinReplay {
 public:
  DinReplay(const CacheConfig& l1, const CacheConfig& l2, bool curves = false);
  void access(std::span<const trace::DinAccess> accesses);
  DinResult result() const;

 private:
  Cache l1_, l2_;
  bool curves_;
  StackDistance sd1_, sd2_;
  DinResult r_;
};

DinResult replay_din(std::span<const trace::DinAccess> accesses, const CacheConfig& l1, const CacheConfig& l2,
                     bool curves = false);

// Streams a Dinero file through the replay: one thread parses (trace::DinReader: a fixed 1 MiB read
// buffer) into four batches of kDinBatch accesses that this thread replays in file order, so memory is
// fixed (about 2 MiB besides the caches' state) whatever the file's size. `references` receives the
// accesses replayed. Errors are the parser's "FILE:LINE: reason" InputError.
inline constexpr size_t kDinBatch = 16384;
DinResult replay_din_file(const std::filesystem::path& path, const CacheConfig& l1, const CacheConfig& l2, bool curves,
                          uint64_t& references);

}  // namespace hp::cachesim
