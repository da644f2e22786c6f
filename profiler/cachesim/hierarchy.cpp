#include "cachesim/hierarchy.hpp"

#include <stdexcept>

namespace hp::cachesim {

void LevelStats::add(const LevelStats& o) {
  requests += o.requests;
  hits += o.hits;
  misses += o.misses;
  line_hits += o.line_hits;
  line_misses += o.line_misses;
  sectors += o.sectors;
  sector_hits += o.sector_hits;
  sector_misses += o.sector_misses;
}

void HierarchyStats::add(const HierarchyStats& o) {
  l1.add(o.l1);
  l2.add(o.l2);
  stores += o.stores;
  atomics += o.atomics;
  dram_read_bytes += o.dram_read_bytes;
  dram_write_bytes += o.dram_write_bytes;
}

Hierarchy::Hierarchy(const CacheConfig& l1, uint32_t compute_units, const CacheConfig& l2)
    : l2_(l2), sector_bytes_(l2.sector_bytes), sectored_(l2.sector_bytes != l2.line_bytes) {
  if (l1.line_bytes != l2.line_bytes || l1.sector_bytes != l2.sector_bytes)
    throw std::invalid_argument("L1 and L2 must share line and sector sizes");
  l1_.reserve(compute_units);
  for (uint32_t cu = 0; cu < compute_units; ++cu) {
    CacheConfig c = l1;
    c.seed = l1.seed + cu;  // random replacement: independent but reproducible streams per CU
    l1_.emplace_back(c);
  }
  // Set width codes for issue(): 0 other (general engine, sectored, ways not 4/8/16), 1/2/3 compact
  // sets of exactly 4/8/16 ways.
  auto code = [](const Cache& c) -> uint32_t {
    if (!c.compact() || c.sectored() || c.config().ways != c.stride()) return 0;
    return c.stride() == 4 ? 1 : c.stride() == 8 ? 2 : 3;
  };
  widths_ = (l1_.empty() ? 0 : code(l1_[0])) * 4 + code(l2_);
}

void Hierarchy::enable_mrc(bool l1, bool l2, double sampling_rate) {
  const uint32_t line = l2_.config().line_bytes;
  l1_mrc_.clear();
  if (l1)
    for (size_t cu = 0; cu < l1_.size(); ++cu) l1_mrc_.push_back(std::make_unique<StackDistance>(line, sampling_rate));
  l2_mrc_ = l2 ? std::make_unique<StackDistance>(line, sampling_rate) : nullptr;
  l1_mrc_queue_.assign(l1_mrc_.size(), {});
  for (auto& q : l1_mrc_queue_) q.reserve(kMrcBatch);
  l2_mrc_queue_.clear();
  l2_mrc_queue_.reserve(kMrcBatch);
}

void Hierarchy::drain_mrc() const {
  for (size_t cu = 0; cu < l1_mrc_.size(); ++cu) {
    l1_mrc_[cu]->access(std::span<const uint64_t>(l1_mrc_queue_[cu]));
    l1_mrc_queue_[cu].clear();
  }
  if (l2_mrc_) {
    l2_mrc_->access(std::span<const uint64_t>(l2_mrc_queue_));
    l2_mrc_queue_.clear();
  }
}

void Hierarchy::begin_pass() {
  for (Cache& c : l1_) c.invalidate();
  stats_ = {};
  buffers_ = {};
  written_back_ = 0;
  // Curves describe one pass too: restart them with the same settings.
  if (!l1_mrc_.empty() || l2_mrc_) {
    const bool l1 = !l1_mrc_.empty(), l2 = bool(l2_mrc_);
    const double rate = l2 ? l2_mrc_->sampling_rate() : l1_mrc_[0]->sampling_rate();
    enable_mrc(l1, l2, rate);
  }
}

void Hierarchy::flush() { stats_.dram_write_bytes += l2_.flush_dirty_sectors() * sector_bytes_; }

MissRatioCurve Hierarchy::l1_curve() const {
  drain_mrc();
  MissRatioCurve c;
  c.line_bytes = l2_.config().line_bytes;
  if (!l1_mrc_.empty()) c.sampling_rate = l1_mrc_[0]->curve().sampling_rate;
  for (const auto& m : l1_mrc_) c.merge(m->curve());
  return c;
}

MissRatioCurve Hierarchy::l2_curve() const {
  drain_mrc();
  if (l2_mrc_) return l2_mrc_->curve();
  MissRatioCurve c;
  c.line_bytes = l2_.config().line_bytes;
  return c;
}

}  // namespace hp::cachesim
