#include "cachesim/stack_distance.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <iterator>
#include <ostream>

#include "cachesim/cache.hpp"  // count_bits

namespace hp::cachesim {

namespace {

constexpr uint64_t kEmptyKey = ~uint64_t(0);

uint64_t mix(uint64_t x) {  // splitmix64 finaliser: spreads line numbers for hashing and sampling
  x ^= x >> 30;
  x *= 0xBF58476D1CE4E5B9ull;
  x ^= x >> 27;
  x *= 0x94D049BB133111EBull;
  x ^= x >> 31;
  return x;
}

// The default x86-64 target has no POPCNT; a host that has it (checked once at run time) runs the
// same code compiled for it. Results do not depend on which.
#if (defined(__x86_64__) || defined(__i386__)) && !defined(__POPCNT__)
#define HP_SD_HW_TARGET [[gnu::target("popcnt")]]
bool host_has_popcount() {
  static const bool has = __builtin_cpu_supports("popcnt");
  return has;
}
#else
#define HP_SD_HW_TARGET
bool host_has_popcount() { return false; }  // count_bits already is the instruction, or none exists
#endif

template <bool kHw>
[[gnu::always_inline]] inline uint32_t bits(uint64_t x) {
  if constexpr (kHw)
    return uint32_t(__builtin_popcountll(x));
  else
    return count_bits(x);
}

}  // namespace

uint64_t MissRatioCurve::misses(uint64_t lines) const {
  uint64_t m = cold;
  for (uint64_t d = lines; d < histogram.size(); ++d) m += histogram[d];
  return m;
}

void MissRatioCurve::merge(const MissRatioCurve& other) {
  accesses += other.accesses;
  cold += other.cold;
  if (histogram.size() < other.histogram.size()) histogram.resize(other.histogram.size(), 0);
  for (size_t d = 0; d < other.histogram.size(); ++d) histogram[d] += other.histogram[d];
}

StackDistance::StackDistance(uint32_t line_bytes, double sampling_rate) {
  curve_.line_bytes = line_bytes;
  curve_.sampling_rate = sampling_rate;
  sampled_ = sampling_rate < 1.0;
  sample_threshold_ = uint64_t(std::max(0.0, sampling_rate) * double(1 << 24));
  scale_ = sampled_ ? 1.0 / sampling_rate : 1.0;
  hw_popcount_ = host_has_popcount();
  std::fill(std::begin(pending_), std::end(pending_), kCold);
  page_table_.assign(1 << 8, PageSlot{kEmptyKey, 0});
  page_mask_ = (1 << 8) - 1;
  capacity_ = 1 << 12;
  bits_.assign(capacity_ / 64, 0);
  tree_.assign((capacity_ >> kBlockBits) + 1, 0);
}

void StackDistance::grow_pages() {
  std::vector<PageSlot> old = std::move(page_table_);
  page_table_.assign(old.size() * 2, PageSlot{kEmptyKey, 0});
  page_mask_ = page_table_.size() - 1;
  for (const PageSlot& s : old) {
    if (s.key == kEmptyKey) continue;
    uint64_t h = mix(s.key) & page_mask_;
    while (page_table_[h].key != kEmptyKey) h = (h + 1) & page_mask_;
    page_table_[h] = s;
  }
}

uint32_t* StackDistance::page_of(uint64_t line) {
  const uint64_t key = line >> kPageBits;
  if (key == last_key_) return times_.data() + last_page_;
  uint64_t h = mix(key) & page_mask_;
  while (true) {
    const PageSlot& s = page_table_[h];
    if (s.key == key) break;
    if (s.key == kEmptyKey) return new_page(key);
    h = (h + 1) & page_mask_;
  }
  last_key_ = key;
  last_page_ = page_table_[h].page;
  return times_.data() + last_page_;
}

uint32_t* StackDistance::new_page(uint64_t key) {
  if ((pages_ + 1) * 2 > page_table_.size()) grow_pages();
  uint64_t h = mix(key) & page_mask_;
  while (page_table_[h].key != kEmptyKey) h = (h + 1) & page_mask_;
  PageSlot& s = page_table_[h];
  s.key = key;
  s.page = times_.size();
  times_.resize(times_.size() + (size_t(1) << kPageBits), 0);
  ++pages_;
  last_key_ = key;
  last_page_ = s.page;
  return times_.data() + last_page_;
}

void StackDistance::prefetch_page(uint64_t line) const {
  // Only finds pages that exist; a new page is made by access() itself.
  const uint64_t key = line >> kPageBits;
  uint64_t h = mix(key) & page_mask_;
  for (int probe = 0; probe < 4; ++probe, h = (h + 1) & page_mask_) {
    const PageSlot& s = page_table_[h];
    if (s.key == key) {
      __builtin_prefetch(times_.data() + s.page + (line & ((uint64_t(1) << kPageBits) - 1)), 1);
      return;
    }
    if (s.key == kEmptyKey) return;
  }
}

void StackDistance::access(std::span<const uint64_t> lines) {
  if (hw_popcount_)
    access_batch_hw(lines);
  else
    access_batch<false>(lines);
}

HP_SD_HW_TARGET void StackDistance::access_batch_hw(std::span<const uint64_t> lines) { access_batch<true>(lines); }

template <bool kHw>
[[gnu::always_inline]] inline void StackDistance::access_batch(std::span<const uint64_t> lines) {
  // Two stages: the table slot kFar lines ahead, then (its slot now cached) the page kNear ahead.
  constexpr size_t kFar = 16, kNear = 8;
  const size_t n = lines.size();
  if (sampled_) {  // most lines are skipped after one hash: nothing worth fetching ahead
    for (uint64_t line : lines) access_one<kHw>(line);
    return;
  }
  for (size_t i = 0; i < n; ++i) {
    if (i + kFar < n) __builtin_prefetch(page_table_.data() + (mix(lines[i + kFar] >> kPageBits) & page_mask_));
    if (i + kNear < n) prefetch_page(lines[i + kNear]);
    access_one<kHw>(lines[i]);
  }
}

void StackDistance::count_distance(uint64_t bucket) {  // a bucket past the end: grow as before
  const size_t size = std::max<uint64_t>(bucket + 1, counts_.size() * 2);
  counts_.resize(size, 0);
}

void StackDistance::publish_histogram() const {
  for (uint64_t& p : pending_) {
    if (p != kCold) count_now(p);
    p = kCold;
  }
  curve_.histogram.resize(counts_.size());
  for (size_t d = 0; d < counts_.size(); ++d) curve_.histogram[d] = counts_[d] + (d < carry_.size() ? carry_[d] : 0);
  histogram_stale_ = false;
}

uint64_t StackDistance::tree_prefix(uint32_t block) const {
  uint64_t s = 0;
  for (uint32_t i = block + 1; i > 0; i &= i - 1) s += tree_[i];
  return s;
}

void StackDistance::tree_add(uint32_t block, int32_t delta) {
  const uint32_t n = uint32_t(tree_.size() - 1);
  for (uint32_t i = block + 1; i <= n; i += i & (0u - i)) tree_[i] += uint32_t(delta);
}

void StackDistance::rebuild_tree() {
  const uint32_t n = capacity_ >> kBlockBits, words = 1u << (kBlockBits - 6);
  tree_.assign(n + 1, 0);
  for (uint32_t b = 0; b < n; ++b)
    for (uint32_t k = 0; k < words; ++k) tree_[b + 1] += count_bits(bits_[size_t(b) * words + k]);
  for (uint32_t i = 1; i <= n; ++i) {  // O(n) Fenwick construction
    const uint32_t parent = i + (i & (0u - i));
    if (parent <= n) tree_[parent] += tree_[i];
  }
}

template <bool kHw>
[[gnu::always_inline]] inline uint64_t StackDistance::ones_after(uint32_t t) const {
  const uint32_t w = t >> 6;
  // (2 << 63) wraps to 0, and the mask to all ones: nothing after bit 63 in this word.
  uint64_t n = bits<kHw>(bits_[w] & ~((uint64_t(2) << (t & 63)) - 1));
  const uint32_t last_word = (now_ - 1) >> 6;
  constexpr uint32_t kWordsPerBlock = 1u << (kBlockBits - 6);
  if (last_word - w <= kWordsPerBlock) {  // recent: count the words up to now directly
    for (uint32_t k = w + 1; k <= last_word; ++k) n += bits<kHw>(bits_[k]);
    return n;
  }
  const uint32_t b = t >> kBlockBits;
  for (uint32_t k = w + 1; k < (b + 1) * kWordsPerBlock; ++k) n += bits<kHw>(bits_[k]);
  return n + (live_ - tree_prefix(b));  // every live line has exactly one 1
}

void StackDistance::compact() {
  // Every seen line keeps a 1 at its latest time; its new time is the rank of that 1 (order is all
  // that distances depend on). Capacity doubles when over half would be live, so each compaction
  // is paid for by at least capacity/2 accesses.
  const size_t words = bits_.size();
  std::vector<uint32_t> before(words);
  uint32_t ones = 0;
  for (size_t k = 0; k < words; ++k) {
    before[k] = ones;
    ones += count_bits(bits_[k]);
  }
  for (uint32_t& v : times_) {
    if (v == 0) continue;
    const uint32_t t = v - 1;
    v = before[t >> 6] + count_bits(bits_[t >> 6] & ((uint64_t(1) << (t & 63)) - 1)) + 1;
  }
  if (uint64_t(ones) * 2 > capacity_) capacity_ *= 2;
  bits_.assign(capacity_ / 64, 0);
  for (uint32_t k = 0; k < ones / 64; ++k) bits_[k] = ~uint64_t(0);
  if (ones % 64) bits_[ones / 64] = (uint64_t(1) << (ones % 64)) - 1;
  rebuild_tree();
  now_ = ones;
}

uint64_t StackDistance::access(uint64_t line) {
  // A skipped line (SHARDS) returns here, before the dispatch (access_one checks again: same answer).
  if (sampled_ && (mix(line ^ 0x5851F42D4C957F2Dull) >> 40) >= sample_threshold_) return kCold;
  return hw_popcount_ ? access_hw(line) : access_one<false>(line);
}

HP_SD_HW_TARGET uint64_t StackDistance::access_hw(uint64_t line) { return access_one<true>(line); }

template <bool kHw>
[[gnu::always_inline]] inline uint64_t StackDistance::access_one(uint64_t line) {
  if (sampled_ && (mix(line ^ 0x5851F42D4C957F2Dull) >> 40) >= sample_threshold_) return kCold;
  ++curve_.accesses;
  if (now_ == capacity_) compact();
  uint32_t& slot = page_of(line)[line & ((uint64_t(1) << kPageBits) - 1)];
  uint64_t distance = kCold;
  if (slot == 0) {
    ++live_;
    ++curve_.cold;
  } else {
    const uint32_t last = slot - 1;
    distance = ones_after<kHw>(last);  // live lines touched after `last`
    bits_[last >> 6] &= ~(uint64_t(1) << (last & 63));
    tree_add(last >> kBlockBits, -1);
    const uint64_t bucket = sampled_ ? uint64_t(double(distance) * scale_) : distance;
    histogram_stale_ = true;
    if (bucket >= counts_.size()) [[unlikely]]
      count_distance(bucket);  // grows only
    __builtin_prefetch(counts_.data() + bucket, 1);
    uint64_t& p = pending_[pending_next_];
    pending_next_ = (pending_next_ + 1) % kPending;
    if (p != kCold) count_now(p);
    p = bucket;
  }
  slot = now_ + 1;
  bits_[now_ >> 6] |= uint64_t(1) << (now_ & 63);
  tree_add(now_ >> kBlockBits, +1);
  ++now_;
  return distance;
}

void write_mrc_csv(std::ostream& out, const std::string& level, const MissRatioCurve& c) {
  // Trailing zero buckets (from doubling the histogram) do not extend the footprint.
  uint64_t footprint = c.histogram.size();
  while (footprint > 0 && c.histogram[footprint - 1] == 0) --footprint;
  std::vector<uint64_t> sizes;
  for (uint64_t p = 1; p <= std::max<uint64_t>(footprint, 1) * 2; p *= 2) {
    sizes.push_back(p);
    if (p >= 2) sizes.push_back(p + p / 2);
  }
  std::sort(sizes.begin(), sizes.end());
  // Suffix sums once, so the whole curve costs O(footprint).
  std::vector<uint64_t> suffix(footprint + 1, 0);
  for (uint64_t d = footprint; d-- > 0;) suffix[d] = suffix[d + 1] + c.histogram[d];
  for (uint64_t lines : sizes) {
    const uint64_t m = c.cold + (lines < footprint ? suffix[lines] : 0);
    const double ratio = c.accesses ? double(m) / double(c.accesses) : 0.0;
    out << level << ',' << lines * c.line_bytes << ',' << lines << ',' << ratio << '\n';
  }
}

}  // namespace hp::cachesim
