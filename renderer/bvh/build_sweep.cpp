// Exact top-down SAH: at every node, every split position between primitives sorted by centroid, on all
// three axes, with the same cost model as the binned build. It is the reference the binned build's cost is
// measured against. Three index lists, each presorted once by centroid along one axis, are kept sorted by
// stable partitioning at every node (the classic O(N log N) formulation), so a node costs O(N).
#include "bvh/build_common.hpp"

#include <algorithm>
#include <limits>
#include <memory>
#include <numeric>

namespace hp::bvh::detail {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

class SweepBuilder {
 public:
  SweepBuilder(std::span<const PrimRef> prims, const BuildParams& p) : prims_(prims), p_(p), forker_(p.threads) {
    const std::size_t n = prims.size();
    // Uninitialised on purpose: every node slot handed out is written before it is read.
    nodes_.reset(new gpu::BvhNode[std::max<std::size_t>(1, 2 * n)]);
    right_area_.resize(n);
    tmp_.resize(n);
    side_.resize(n);
  }

  PairTree run() {
    const uint32_t n = static_cast<uint32_t>(prims_.size());
    // Presort the three lists in parallel (one axis per worker); ties broken by slot for determinism.
    for (int a = 0; a < 3; ++a) {
      lists_[a].resize(n);
      std::iota(lists_[a].begin(), lists_[a].end(), 0u);
    }
    auto sort_axis = [&](int a) {
      std::sort(lists_[a].begin(), lists_[a].end(), [&](uint32_t x, uint32_t y) {
        const float cx = prims_[x].lo[a] + prims_[x].hi[a];
        const float cy = prims_[y].lo[a] + prims_[y].hi[a];
        return cx < cy || (cx == cy && x < y);
      });
    };
    {
      std::vector<std::thread> pool;
      for (int a = 1; a < 3 && a < p_.threads; ++a) pool.emplace_back(sort_axis, a);
      sort_axis(0);
      for (int a = static_cast<int>(pool.size()) + 1; a < 3; ++a) sort_axis(a);
      for (auto& t : pool) t.join();
    }
    glm::vec3 lo{kInf}, hi{-kInf};
    for (const auto& pr : prims_) {
      lo = glm::min(lo, pr.lo);
      hi = glm::max(hi, pr.hi);
    }
    build(0, 0, n, lo, hi, 0);
    tree_.nodes = std::move(nodes_);
    tree_.node_count = next_node_.load();
    tree_.order.resize(n);
    for (uint32_t i = 0; i < n; ++i) tree_.order[i] = prims_[lists_[0][i]].id;
    tree_.depth_limited_splits = depth_limited_.load();
    return std::move(tree_);
  }

 private:
  float centroid(uint32_t slot, int axis) const { return prims_[slot].lo[axis] + prims_[slot].hi[axis]; }

  void build(uint32_t index, uint32_t begin, uint32_t end, const glm::vec3& lo, const glm::vec3& hi, int depth) {
    const uint32_t n = end - begin;
    const auto leaf = [&] { nodes_[index] = make_leaf(lo, hi, begin, n); };
    if (n <= 1) return leaf();
    if (n <= p_.max_leaf && depth + 1 > p_.max_depth) return leaf();

    int best_axis = -1;
    uint32_t best_split = 0;  // first slot of the right child
    float best_cost = kInf;
    uint32_t best_imbalance = UINT32_MAX;
    for (int a = 0; a < 3; ++a) {
      const uint32_t* list = lists_[a].data();
      glm::vec3 blo{kInf}, bhi{-kInf};
      for (uint32_t i = end - 1; i > begin; --i) {
        blo = glm::min(blo, prims_[list[i]].lo);
        bhi = glm::max(bhi, prims_[list[i]].hi);
        right_area_[i] = static_cast<float>(end - i) * half_area(blo, bhi);
      }
      blo = glm::vec3(kInf);
      bhi = glm::vec3(-kInf);
      for (uint32_t i = begin; i + 1 < end; ++i) {
        blo = glm::min(blo, prims_[list[i]].lo);
        bhi = glm::max(bhi, prims_[list[i]].hi);
        const float cost = static_cast<float>(i + 1 - begin) * half_area(blo, bhi) + right_area_[i + 1];
        // Equal costs (e.g. identical boxes) go to the more balanced split: a shallower tree for free.
        const uint32_t imbalance = std::max(i + 1 - begin, end - i - 1);
        if (cost < best_cost || (cost == best_cost && imbalance < best_imbalance)) {
          best_cost = cost;
          best_axis = a;
          best_split = i + 1;
          best_imbalance = imbalance;
        }
      }
    }

    const float node_area = half_area(lo, hi);
    const float split_cost = p_.traversal_cost * node_area + best_cost;
    if (n <= p_.max_leaf && static_cast<float>(n) * node_area <= split_cost) return leaf();

    const uint32_t larger = std::max(best_split - begin, end - best_split);
    if (depth + 1 + levels_needed(larger, p_.max_leaf) > p_.max_depth) {
      if (n <= p_.max_leaf) return leaf();
      // Median split on the axis of largest centroid extent: halves the count, so it always fits.
      depth_limited_.fetch_add(1, std::memory_order_relaxed);
      float widest = -1.0f;
      for (int a = 0; a < 3; ++a) {
        const float ext = centroid(lists_[a][end - 1], a) - centroid(lists_[a][begin], a);
        if (ext > widest) {
          widest = ext;
          best_axis = a;
        }
      }
      best_split = begin + n / 2;
    }

    // Mark the sides, then stable-partition the other two lists so that all three stay sorted.
    const uint32_t* chosen = lists_[best_axis].data();
    glm::vec3 llo{kInf}, lhi{-kInf}, rlo{kInf}, rhi{-kInf};
    for (uint32_t i = begin; i < best_split; ++i) {
      side_[chosen[i]] = 0;
      llo = glm::min(llo, prims_[chosen[i]].lo);
      lhi = glm::max(lhi, prims_[chosen[i]].hi);
    }
    for (uint32_t i = best_split; i < end; ++i) {
      side_[chosen[i]] = 1;
      rlo = glm::min(rlo, prims_[chosen[i]].lo);
      rhi = glm::max(rhi, prims_[chosen[i]].hi);
    }
    for (int a = 0; a < 3; ++a) {
      if (a == best_axis) continue;
      uint32_t* list = lists_[a].data();
      uint32_t l = begin, r = begin;
      for (uint32_t i = begin; i < end; ++i) {
        const uint32_t slot = list[i];
        if (side_[slot] == 0) {
          list[l++] = slot;
        } else {
          tmp_[r++] = slot;
        }
      }
      std::copy(tmp_.begin() + begin, tmp_.begin() + r, list + l);
    }

    const uint32_t child = next_node_.fetch_add(2, std::memory_order_relaxed);
    nodes_[index] = make_interior(lo, hi, child, static_cast<uint32_t>(best_axis));
    forker_.fork_join(
        best_split - begin, [&, child](bool) { build(child, begin, best_split, llo, lhi, depth + 1); },
        [&, child] { build(child + 1, best_split, end, rlo, rhi, depth + 1); });
  }

  std::span<const PrimRef> prims_;
  BuildParams p_;
  Forker forker_;
  PairTree tree_;
  std::unique_ptr<gpu::BvhNode[]> nodes_;
  std::vector<uint32_t> lists_[3];
  std::vector<float> right_area_;  // indexed by list position: disjoint per subtree, so thread-safe
  std::vector<uint32_t> tmp_;      // same
  std::vector<uint8_t> side_;      // indexed by slot: a subtree's slots are its own
  std::atomic<uint32_t> next_node_{1};
  std::atomic<std::size_t> depth_limited_{0};
};

}  // namespace

PairTree build_full_sweep(std::span<const PrimRef> prims, const BuildParams& params) {
  return SweepBuilder(prims, params).run();
}

}  // namespace hp::bvh::detail
