#include "cachesim/stack_distance.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <ostream>

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
  keys_.assign(1 << 12, kEmptyKey);
  times_.assign(1 << 12, 0);
  table_mask_ = (1 << 12) - 1;
  capacity_ = 1 << 12;
  tree_.assign(capacity_ + 1, 0);
  owner_.assign(capacity_, 0);
}

uint32_t StackDistance::find_or_insert(uint64_t line, bool& inserted) {
  uint64_t h = mix(line) & table_mask_;
  while (true) {
    if (keys_[h] == line) {
      inserted = false;
      return uint32_t(h);
    }
    if (keys_[h] == kEmptyKey) {
      keys_[h] = line;
      inserted = true;
      ++table_used_;
      return uint32_t(h);
    }
    h = (h + 1) & table_mask_;
  }
}

void StackDistance::grow_table() {
  // Rehash into a table twice as large; owner_ (time -> slot) follows the moved slots.
  std::vector<uint64_t> old_keys = std::move(keys_);
  std::vector<uint32_t> old_times = std::move(times_);
  const uint64_t size = old_keys.size() * 2;
  keys_.assign(size, kEmptyKey);
  times_.assign(size, 0);
  table_mask_ = size - 1;
  for (size_t i = 0; i < old_keys.size(); ++i) {
    if (old_keys[i] == kEmptyKey) continue;
    uint64_t h = mix(old_keys[i]) & table_mask_;
    while (keys_[h] != kEmptyKey) h = (h + 1) & table_mask_;
    keys_[h] = old_keys[i];
    times_[h] = old_times[i];
    owner_[old_times[i]] = uint32_t(h);
  }
}

uint64_t StackDistance::prefix(uint32_t t) const {
  uint64_t s = 0;
  for (uint32_t i = t + 1; i > 0; i &= i - 1) s += tree_[i];
  return s;
}

void StackDistance::add(uint32_t t, int32_t delta) {
  for (uint32_t i = t + 1; i <= capacity_; i += i & (0u - i)) tree_[i] += uint32_t(delta);
}

void StackDistance::compact() {
  // Every live line keeps its latest time; renumber those times 0..live-1 in order (order is all
  // that distances depend on) and rebuild the tree. Capacity doubles when over half would be live,
  // so each compaction is paid for by at least capacity/2 accesses.
  uint32_t next = 0;
  for (uint32_t t = 0; t < now_; ++t) {
    const uint32_t slot = owner_[t];
    if (keys_[slot] != kEmptyKey && times_[slot] == t) {
      times_[slot] = next;
      owner_[next++] = slot;
    }
  }
  if (uint64_t(next) * 2 > capacity_) {
    capacity_ *= 2;
    owner_.resize(capacity_);
  }
  tree_.assign(capacity_ + 1, 0);
  for (uint32_t t = 0; t < next; ++t) tree_[t + 1] = 1;
  for (uint32_t i = 1; i <= capacity_; ++i) {  // O(n) Fenwick construction
    const uint32_t parent = i + (i & (0u - i));
    if (parent <= capacity_) tree_[parent] += tree_[i];
  }
  now_ = next;
}

uint64_t StackDistance::access(uint64_t line) {
  if (sampled_ && (mix(line ^ 0x5851F42D4C957F2Dull) >> 40) >= sample_threshold_) return kCold;
  ++curve_.accesses;
  if (now_ == capacity_) compact();
  if ((table_used_ + 1) * 2 > keys_.size()) grow_table();
  bool inserted = false;
  const uint32_t slot = find_or_insert(line, inserted);
  uint64_t distance = kCold;
  if (inserted) {
    ++live_;
    ++curve_.cold;
  } else {
    const uint32_t last = times_[slot];
    distance = live_ - prefix(last);  // live lines touched after `last`
    add(last, -1);
    const uint64_t bucket = sampled_ ? uint64_t(double(distance) * scale_) : distance;
    if (bucket >= curve_.histogram.size()) curve_.histogram.resize(std::max<uint64_t>(bucket + 1, curve_.histogram.size() * 2), 0);
    ++curve_.histogram[bucket];
  }
  times_[slot] = now_;
  owner_[now_] = slot;
  add(now_, +1);
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
