#include "cachesim/cache.hpp"

#include <algorithm>

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
  const uint64_t per_channel_way = uint64_t(c.line_bytes) * c.ways * c.channels;
  if (c.size_bytes % per_channel_way != 0)
    return "size_bytes: " + n(c.size_bytes) + " is not divisible by line_bytes * ways * channels = " +
           n(per_channel_way);
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
  set_mask_ = sets_per_channel_ - 1;
  channel_pow2_ = std::has_single_bit(channels_);
  channel_shift_ = channel_pow2_ ? uint32_t(std::countr_zero(channels_)) : 0;
  const uint32_t interleave = config.channel_interleave_bytes ? config.channel_interleave_bytes : config.line_bytes;
  interleave_shift_ = uint32_t(std::countr_zero(interleave / config.line_bytes));
  interleave_mask_ = (uint64_t(1) << interleave_shift_) - 1;
  line_shift_ = uint32_t(std::countr_zero(config.line_bytes));
  sector_shift_ = uint32_t(std::countr_zero(config.sector_bytes));
  const uint32_t sectors = config.line_bytes / config.sector_bytes;
  full_mask_ = sectors == 32 ? ~0u : (1u << sectors) - 1;
  replacement_ = config.replacement;
  rng_ = config.seed ? config.seed : 0x9E3779B97F4A7C15ull;  // xorshift must not start at 0
  const size_t ways = size_t(sets_per_channel_ * channels_) * ways_per_set_;
  tags_.assign(ways, kEmpty);
  meta_.assign(ways, Meta{0, 0});
  stamp_.assign(ways, 0);
}

bool Cache::contains(uint64_t line, uint32_t sectors) const {
  const size_t base = size_t(set_index(line)) * ways_per_set_;
  for (uint32_t i = 0; i < ways_per_set_; ++i)
    if (tags_[base + i] == line) return (sectors & ~meta_[base + i].valid) == 0;
  return false;
}

uint64_t Cache::flush_dirty_sectors() {
  uint64_t n = 0;
  for (Meta& m : meta_) {
    n += uint64_t(std::popcount(m.dirty));
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
  std::fill(tags_.begin(), tags_.end(), kEmpty);
  std::fill(meta_.begin(), meta_.end(), Meta{0, 0});
  std::fill(stamp_.begin(), stamp_.end(), 0u);
}

}  // namespace hp::cachesim
