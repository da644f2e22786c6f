#include "cachesim/cache.hpp"

#include <algorithm>
#include <cstring>

namespace hp::cachesim {

namespace {
bool pow2(uint64_t v) { return v && !(v & (v - 1)); }
}  // namespace

const char* to_string(Replacement r) {
  switch (r) {
    case Replacement::lru: return "lru";
    case Replacement::fifo: return "fifo";
    case Replacement::random: return "random";
  }
  return "?";
}

std::string check_config(const CacheConfig& c) {
  auto n = [](uint64_t v) { return std::to_string(v); };
  if (!pow2(c.line_bytes)) return "line_bytes: " + n(c.line_bytes) + " is not a power of two";
  if (!pow2(c.sector_bytes)) return "sector_bytes: " + n(c.sector_bytes) + " is not a power of two";
  if (c.sector_bytes > c.line_bytes) return "sector_bytes: " + n(c.sector_bytes) + " exceeds line_bytes";
  if (c.line_bytes / c.sector_bytes > 32) return "sector_bytes: more than 32 sectors per line";
  if (c.ways == 0) return "ways: must be at least 1";
  if (c.channels == 0) return "channels: must be at least 1";
  if (c.size_bytes == 0) return "size_bytes: must be positive";
  // Bounds of the simulator, not of hardware (the largest GPU caches are a few hundred MiB): the tags of a
  // 1 GiB cache of 64-byte lines take ~256 MiB of host memory.
  if (c.size_bytes > kMaxCacheBytes) return "size_bytes: " + n(c.size_bytes) + " exceeds the limit of 1 GiB";
  if (c.line_bytes > 4096) return "line_bytes: " + n(c.line_bytes) + " exceeds the limit of 4096";
  if (c.ways > 4096) return "ways: " + n(c.ways) + " exceeds the limit of 4096";
  if (c.channels > 1024) return "channels: " + n(c.channels) + " exceeds the limit of 1024";
  const uint64_t per_channel_way = uint64_t(c.line_bytes) * c.ways * c.channels;
  if (c.size_bytes % per_channel_way != 0)
    return "size_bytes: " + n(c.size_bytes) +
           " is not divisible by line_bytes * ways * channels = " + n(per_channel_way);
  const uint64_t sets = c.size_bytes / per_channel_way;
  if (!pow2(sets)) return "size_bytes: gives " + n(sets) + " sets per channel, not a power of two";
  const uint32_t interleave = c.channel_interleave_bytes ? c.channel_interleave_bytes : c.line_bytes;
  if (!pow2(interleave) || interleave < c.line_bytes)
    return "channel_interleave_bytes: " + n(interleave) + " must be a power of two >= line_bytes";
  if (c.channels > 1 && uint64_t(interleave / c.line_bytes) > sets)
    return "channel_interleave_bytes: larger than one channel's sets";
  return {};
}

std::string describe(const CacheConfig& c) {
  auto size = [](uint64_t b) {
    if (b % (1 << 20) == 0) return std::to_string(b >> 20) + " MiB";
    if (b % 1024 == 0) return std::to_string(b >> 10) + " KiB";
    return std::to_string(b) + " B";
  };
  std::string s = size(c.size_bytes) + ", " + std::to_string(c.line_bytes) + " B lines";
  if (c.sector_bytes != c.line_bytes) s += " of " + std::to_string(c.sector_bytes) + " B sectors";
  s += ", " + std::to_string(c.ways) + "-way, " + to_string(c.replacement);
  if (c.channels > 1) s += ", " + std::to_string(c.channels) + " channels";
  return s;
}

Cache::Cache(const CacheConfig& config) : config_(config) {
  ways_per_set_ = config.ways;
  channels_ = config.channels;
  sets_per_channel_ = config.size_bytes / (uint64_t(config.line_bytes) * config.ways * config.channels);
  sets_ = uint32_t(sets_per_channel_ * channels_);
  plain_index_ = std::has_single_bit(channels_);
  // A plain index covers all sets; a sliced one the sets of one channel.
  const uint64_t indexed = plain_index_ ? sets_ : sets_per_channel_;
  set_mask_ = indexed - 1;
  set_bits_ = uint32_t(std::countr_zero(indexed));
  const uint32_t interleave = config.channel_interleave_bytes ? config.channel_interleave_bytes : config.line_bytes;
  interleave_shift_ = uint32_t(std::countr_zero(interleave / config.line_bytes));
  interleave_mask_ = (uint64_t(1) << interleave_shift_) - 1;
  line_shift_ = uint32_t(std::countr_zero(config.line_bytes));
  sector_shift_ = uint32_t(std::countr_zero(config.sector_bytes));
  const uint32_t sectors = config.line_bytes / config.sector_bytes;
  full_mask_ = sectors == 32 ? ~0u : (1u << sectors) - 1;
  sectored_ = sectors > 1;
  replacement_ = config.replacement;
  lru_ = replacement_ == Replacement::lru;
  rng_ = config.seed ? config.seed : 0x9E3779B97F4A7C15ull;  // xorshift must not start at 0
  if (replacement_ != Replacement::random && ways_per_set_ <= 16) {
    stride_ = ways_per_set_ <= 4 ? 4 : ways_per_set_ <= 8 ? 8 : 16;
    if (sectored_) {
      engine_ = Engine::compact;
      tag32_ = aligned_array<uint32_t>(size_t(sets_) * stride_);
      order_ = aligned_array<uint64_t>(sets_);
      meta_.assign(size_t(sets_) * stride_, Meta{0, 0});
    } else {
      // 16-bit entries halve the vectors of a set of 8 or 16 ways; a 4-way set is one vector of
      // 32-bit entries already, and its 16-bit form costs more instructions (half a vector).
      ordered16_limit_ = first_line_with_tag(kTagBits<uint16_t>);
      ordered32_limit_ = first_line_with_tag(kTagBits<uint32_t>);
      if (stride_ >= 8) {
        engine_ = Engine::ordered16;
        tag16_ = aligned_array<uint16_t>(size_t(sets_) * stride_);
      } else {
        engine_ = Engine::ordered32;
        tag32_ = aligned_array<uint32_t>(size_t(sets_) * stride_);
      }
    }
    init_small();
  } else {
    init_general();
  }
}

uint64_t Cache::first_line_with_tag(uint64_t tag) const {
  unsigned __int128 line = tag;
  if (plain_index_)
    line <<= set_bits_;
  else
    line = ((line << (set_bits_ - interleave_shift_)) * channels_) << interleave_shift_;
  return line > ~uint64_t(0) ? ~uint64_t(0) : uint64_t(line);
}

Cache::Cache(const Cache& o)
    : config_(o.config_),
      engine_(o.engine_),
      sectored_(o.sectored_),
      lru_(o.lru_),
      ways_per_set_(o.ways_per_set_),
      stride_(o.stride_),
      sets_(o.sets_),
      set_mask_(o.set_mask_),
      set_bits_(o.set_bits_),
      channels_(o.channels_),
      plain_index_(o.plain_index_),
      interleave_shift_(o.interleave_shift_),
      interleave_mask_(o.interleave_mask_),
      sets_per_channel_(o.sets_per_channel_),
      line_shift_(o.line_shift_),
      sector_shift_(o.sector_shift_),
      full_mask_(o.full_mask_),
      replacement_(o.replacement_),
      rng_(o.rng_),
      ordered16_limit_(o.ordered16_limit_),
      ordered32_limit_(o.ordered32_limit_),
      meta_(o.meta_),
      tags_(o.tags_),
      gmeta_(o.gmeta_),
      stamp_(o.stamp_),
      clock_(o.clock_) {
  if (o.tag16_) {
    tag16_ = aligned_array<uint16_t>(size_t(sets_) * stride_);
    std::memcpy(tag16_.get(), o.tag16_.get(), size_t(sets_) * stride_ * sizeof(uint16_t));
  }
  if (o.tag32_) {
    tag32_ = aligned_array<uint32_t>(size_t(sets_) * stride_);
    std::memcpy(tag32_.get(), o.tag32_.get(), size_t(sets_) * stride_ * sizeof(uint32_t));
  }
  if (o.order_) {
    order_ = aligned_array<uint64_t>(sets_);
    std::memcpy(order_.get(), o.order_.get(), size_t(sets_) * sizeof(uint64_t));
  }
}

Cache& Cache::operator=(const Cache& o) {
  if (this != &o) *this = Cache(o);
  return *this;
}

void Cache::init_small() {
  // Ordered: every entry empty (padding entries too: they are never shifted into, never match).
  if (engine_ == Engine::ordered16) {
    std::fill(tag16_.get(), tag16_.get() + size_t(sets_) * stride_, uint16_t(kTagBits<uint16_t>));
    return;
  }
  if (engine_ == Engine::ordered32) {
    std::fill(tag32_.get(), tag32_.get() + size_t(sets_) * stride_, kTagBits<uint32_t>);
    return;
  }
  std::fill(tag32_.get(), tag32_.get() + size_t(sets_) * stride_, kEmpty32);
  // Way 0 at the back (the first victim), then way 1, ...; unused positions 0xF.
  uint64_t order = ~uint64_t(0);
  for (uint32_t p = 0; p < ways_per_set_; ++p) {
    const uint64_t way = ways_per_set_ - 1 - p;
    order = (order & ~(uint64_t(0xF) << (4 * p))) | (way << (4 * p));
  }
  std::fill(order_.get(), order_.get() + sets_, order);
  std::fill(meta_.begin(), meta_.end(), Meta{0, 0});
}

void Cache::init_general() {
  const size_t ways = size_t(sets_) * ways_per_set_;
  tags_.assign(ways, kEmpty);
  gmeta_.assign(ways, Meta{0, 0});
  stamp_.assign(ways, 0);
  clock_ = 0;
}

uint64_t Cache::line_of(uint32_t set, uint64_t tag) const {
  if (plain_index_) return (tag << set_bits_) | set;
  const uint64_t channel = set / sets_per_channel_;
  const uint64_t in_channel = set % sets_per_channel_;
  const uint64_t within = in_channel & interleave_mask_;
  const uint64_t rest = (tag << (set_bits_ - interleave_shift_)) | (in_channel >> interleave_shift_);
  const uint64_t chunk = rest * channels_ + channel;
  return (chunk << interleave_shift_) | within;
}

void Cache::widen() {
  if (engine_ != Engine::ordered16) return;
  // Same positions, same dirty bits; the empty marker becomes the wider one.
  const size_t n = size_t(sets_) * stride_;
  tag32_ = aligned_array<uint32_t>(n);
  for (size_t i = 0; i < n; ++i) {
    const uint32_t t = tag16_[i] & kTagBits<uint16_t>, dirty = uint32_t(tag16_[i]) >> kDirtyShift<uint16_t>;
    tag32_[i] = t == kTagBits<uint16_t> ? kTagBits<uint32_t> : t | (dirty << kDirtyShift<uint32_t>);
  }
  tag16_.reset();
  engine_ = Engine::ordered32;
}

void Cache::to_general() {
  // Full lines, the same sector state, and stamps that order each set as the small engine did: the
  // most recent position gets the highest stamp, empty ways stamp 0; the clock starts above them
  // all, so every later access is newer than any converted one, as it would have been.
  widen();  // ordered16 → ordered32: one layout to read below
  const Engine from = engine_;
  init_general();
  for (uint32_t s = 0; s < sets_; ++s) {
    const uint32_t* tags = tag32_.get() + size_t(s) * stride_;
    for (uint32_t p = 0; p < ways_per_set_; ++p) {
      // Ordered: position p is entry p (kept in way p); compact: the way at position p.
      const uint32_t w = from == Engine::ordered32 ? p : uint32_t(order_[s] >> (4 * p)) & 0xF;
      const uint32_t t = tags[w];
      if (from == Engine::ordered32 ? t == kTagBits<uint32_t> : t == kEmpty32) continue;
      const size_t g = size_t(s) * ways_per_set_ + w;
      stamp_[g] = ways_per_set_ - p;
      if (from == Engine::ordered32) {
        tags_[g] = line_of(s, t & kTagBits<uint32_t>);
        gmeta_[g] = Meta{1u, t >> kDirtyShift<uint32_t>};
      } else {
        tags_[g] = line_of(s, t);
        gmeta_[g] = meta_[size_t(s) * stride_ + w];
      }
    }
  }
  clock_ = ways_per_set_;
  engine_ = Engine::general;
  tag32_.reset();
  order_.reset();
  meta_ = {};
}

namespace {
template <typename T>
bool ordered_holds(const T* e, uint32_t ways, uint32_t tag, uint32_t tag_bits) {
  for (uint32_t i = 0; i < ways; ++i)
    if ((e[i] & tag_bits) == tag) return true;
  return false;
}
}  // namespace

bool Cache::contains(uint64_t line, uint32_t sectors) const {
  if (engine_ == Engine::ordered16 || engine_ == Engine::ordered32) {
    if (line >= ordered_line_limit()) return false;  // never stored: the engine holds only narrow tags
    uint64_t tag;
    const size_t at = size_t(locate(line, tag)) * stride_;
    return engine_ == Engine::ordered16
               ? ordered_holds(tag16_.get() + at, ways_per_set_, uint32_t(tag), kTagBits<uint16_t>)
               : ordered_holds(tag32_.get() + at, ways_per_set_, uint32_t(tag), kTagBits<uint32_t>);
  }
  if (engine_ == Engine::compact) {
    uint64_t tag;
    const uint32_t set = locate(line, tag);
    if (tag >= kEmpty32) return false;  // never stored: the compact engine holds only narrow tags
    const uint32_t match = match_ways(tag32_.get() + size_t(set) * stride_, uint32_t(tag));
    if (!match) return false;
    return (sectors & ~meta_[size_t(set) * stride_ + uint32_t(std::countr_zero(match))].valid) == 0;
  }
  const size_t base = size_t(set_index(line)) * ways_per_set_;
  for (uint32_t i = 0; i < ways_per_set_; ++i)
    if (tags_[base + i] == line) return (sectors & ~gmeta_[base + i].valid) == 0;
  return false;
}

uint64_t Cache::flush_dirty_sectors() {
  uint64_t n = 0;
  if (engine_ == Engine::ordered16) {
    uint16_t* e = tag16_.get();
    for (size_t i = 0, end = size_t(sets_) * stride_; i < end; ++i) {
      n += uint32_t(e[i]) >> kDirtyShift<uint16_t>;
      e[i] = uint16_t(e[i] & kTagBits<uint16_t>);
    }
    return n;
  }
  if (engine_ == Engine::ordered32) {
    uint32_t* e = tag32_.get();
    for (size_t i = 0, end = size_t(sets_) * stride_; i < end; ++i) {
      n += e[i] >> kDirtyShift<uint32_t>;
      e[i] &= kTagBits<uint32_t>;
    }
    return n;
  }
  for (Meta& m : engine_ == Engine::compact ? meta_ : gmeta_) {
    n += count_bits(m.dirty);
    m.dirty = 0;
  }
  return n;
}

void Cache::renumber_stamps() {
  std::vector<uint32_t> order(ways_per_set_);
  for (size_t base = 0; base < stamp_.size(); base += ways_per_set_) {
    for (uint32_t i = 0; i < ways_per_set_; ++i) order[i] = i;
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return stamp_[base + a] < stamp_[base + b]; });
    for (uint32_t r = 0; r < ways_per_set_; ++r)
      if (stamp_[base + order[r]] != 0) stamp_[base + order[r]] = r + 1;  // empty ways stay 0
  }
  clock_ = ways_per_set_ + 1;
}

void Cache::invalidate() {
  if (engine_ != Engine::general) {
    init_small();
    return;
  }
  std::fill(tags_.begin(), tags_.end(), kEmpty);
  std::fill(gmeta_.begin(), gmeta_.end(), Meta{0, 0});
  std::fill(stamp_.begin(), stamp_.end(), 0u);
}

}  // namespace hp::cachesim
