// Top-down binned SAH (Wald 2007, "On fast construction of SAH-based bounding volume hierarchies"; pbrt's
// BVHAggregate): primitives are binned by centroid along the axis of largest centroid extent, the best bin
// boundary is chosen by t_trav + (N_A*S_A + N_B*S_B)/S against the leaf cost N, and the range is
// partitioned in place. Each node costs one binning pass and one partition pass over its primitives: the
// children's bounds and centroid bounds come out of the bins, so no extra pass recomputes them.
#include "bvh/build_common.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace hp::bvh::detail {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

/// Bounds of a primitive range and of its (doubled) centroids.
struct RangeInfo {
  glm::vec3 lo{kInf}, hi{-kInf};
  glm::vec3 clo{kInf}, chi{-kInf};
  uint32_t begin = 0, end = 0;

  void grow(const PrimRef& p) {
    lo = glm::min(lo, p.lo);
    hi = glm::max(hi, p.hi);
    const glm::vec3 c = p.lo + p.hi;
    clo = glm::min(clo, c);
    chi = glm::max(chi, c);
  }
  void grow(const RangeInfo& o) {
    lo = glm::min(lo, o.lo);
    hi = glm::max(hi, o.hi);
    clo = glm::min(clo, o.clo);
    chi = glm::max(chi, o.chi);
  }
};

struct Bin {
  RangeInfo info;  // begin/end unused; info.end counts the primitives
};

/// Per-thread scratch, allocated once per worker so that nodes allocate nothing.
struct Scratch {
  std::vector<RangeInfo> bins;
  std::vector<uint32_t> counts;
  std::vector<float> right_cost;  // N_B * S_B for the split after bin i
};

RangeInfo range_info(std::span<const PrimRef> prims, uint32_t begin, uint32_t end) {
  RangeInfo r;
  for (uint32_t i = begin; i < end; ++i) r.grow(prims[i]);
  r.begin = begin;
  r.end = end;
  return r;
}

class BinnedBuilder {
public:
  BinnedBuilder(std::span<PrimRef> prims, const BuildParams& p)
      : prims_(prims), p_(p), forker_(p.threads) {
    tree_.nodes.resize(std::max<std::size_t>(1, 2 * prims.size()));
  }

  PairTree run() {
    RangeInfo root;
    // The root pass is the only serial full pass; split it across the workers.
    std::vector<RangeInfo> parts(std::max(1, p_.threads));
    Forker::parallel_chunks(prims_.size(), p_.threads, [&](std::size_t b, std::size_t e, std::size_t c) {
      parts[c] = range_info(prims_, static_cast<uint32_t>(b), static_cast<uint32_t>(e));
    });
    for (const auto& part : parts) root.grow(part);
    root.begin = 0;
    root.end = static_cast<uint32_t>(prims_.size());
    Scratch scratch = make_scratch();
    build(0, root, 0, scratch);
    tree_.nodes.resize(next_node_.load());
    tree_.order.resize(prims_.size());
    for (std::size_t i = 0; i < prims_.size(); ++i) tree_.order[i] = prims_[i].id;
    tree_.depth_limited_splits = depth_limited_.load();
    return std::move(tree_);
  }

private:
  Scratch make_scratch() const {
    Scratch s;
    s.bins.resize(p_.buckets);
    s.counts.resize(p_.buckets);
    s.right_cost.resize(p_.buckets);
    return s;
  }

  void make_leaf_node(uint32_t index, const RangeInfo& r) {
    tree_.nodes[index] = make_leaf(r.lo, r.hi, r.begin, r.end - r.begin);
  }

  /// Splits [begin, end) at its middle after ordering by centroid along `axis` (a median split); when all
  /// centroids coincide the order is arbitrary and this is a plain count split. Either way each child has
  /// at most ceil(N/2) primitives, which is what the depth bound relies on.
  void median_split(const RangeInfo& r, int axis, RangeInfo& left, RangeInfo& right) {
    const uint32_t mid = r.begin + (r.end - r.begin) / 2;
    std::nth_element(prims_.begin() + r.begin, prims_.begin() + mid, prims_.begin() + r.end,
                     [axis](const PrimRef& a, const PrimRef& b) {
                       return a.lo[axis] + a.hi[axis] < b.lo[axis] + b.hi[axis];
                     });
    left = range_info(prims_, r.begin, mid);
    right = range_info(prims_, mid, r.end);
  }

  void build(uint32_t index, const RangeInfo& r, int depth, Scratch& s) {
    const uint32_t n = r.end - r.begin;
    if (n <= 1) return make_leaf_node(index, r);

    // A split puts its children at depth + 1; with n <= max_leaf a leaf is always allowed instead.
    const bool may_split_small = depth + 1 <= p_.max_depth;
    if (n <= p_.max_leaf && !may_split_small) return make_leaf_node(index, r);

    const glm::vec3 cext = r.chi - r.clo;
    int axis = 0;
    if (cext.y > cext[axis]) axis = 1;
    if (cext.z > cext[axis]) axis = 2;

    RangeInfo left, right;
    const float extent = cext[axis];
    const float scale = static_cast<float>(p_.buckets) / extent;
    if (!(extent > 0.0f) || !std::isfinite(scale)) {
      // All centroids coincide (or their spread underflows the bin scale): no spatial split exists.
      if (n <= p_.max_leaf) return make_leaf_node(index, r);
      median_split(r, axis, left, right);
      return finish_interior(index, r, axis, left, right, depth, s);
    }

    // Binning.
    const int nb = p_.buckets;
    for (int b = 0; b < nb; ++b) {
      s.bins[b] = RangeInfo{};
      s.counts[b] = 0;
    }
    const float cmin = r.clo[axis];
    const auto bin_of = [&](const PrimRef& pr) {
      const int b = static_cast<int>((pr.lo[axis] + pr.hi[axis] - cmin) * scale);
      return std::min(b, nb - 1);
    };
    for (uint32_t i = r.begin; i < r.end; ++i) {
      const PrimRef& pr = prims_[i];
      const int b = bin_of(pr);
      s.bins[b].grow(pr);
      ++s.counts[b];
    }

    // Sweep from the right for N_B * S_B, then from the left for the total.
    {
      RangeInfo acc;
      uint32_t count = 0;
      for (int b = nb - 1; b > 0; --b) {
        acc.grow(s.bins[b]);
        count += s.counts[b];
        s.right_cost[b - 1] = count ? static_cast<float>(count) * half_area(acc.lo, acc.hi) : 0.0f;
      }
    }
    int best = -1;
    float best_cost = kInf;
    uint32_t best_left_count = 0;
    {
      RangeInfo acc;
      uint32_t count = 0;
      for (int b = 0; b < nb - 1; ++b) {
        acc.grow(s.bins[b]);
        count += s.counts[b];
        if (count == 0 || count == n) continue;
        const float cost = static_cast<float>(count) * half_area(acc.lo, acc.hi) + s.right_cost[b];
        if (cost < best_cost) {
          best_cost = cost;
          best = b;
          best_left_count = count;
        }
      }
    }

    // Compare in units of the node's area times cost (no division, so a zero-area node stays finite).
    const float node_area = half_area(r.lo, r.hi);
    const float split_cost = p_.traversal_cost * node_area + best_cost;
    const float leaf_cost = static_cast<float>(n) * node_area;
    if (n <= p_.max_leaf && (best < 0 || leaf_cost <= split_cost)) return make_leaf_node(index, r);

    const uint32_t larger_child = best < 0 ? n : std::max(best_left_count, n - best_left_count);
    if (best < 0 || depth + 1 + levels_needed(larger_child, p_.max_leaf) > p_.max_depth) {
      // The SAH split could not be finished within the depth left (or there is none): a median split
      // halves the count, which always fits because this node's own range did.
      if (n <= p_.max_leaf) return make_leaf_node(index, r);
      depth_limited_.fetch_add(best >= 0 ? 1 : 0, std::memory_order_relaxed);
      median_split(r, axis, left, right);
      return finish_interior(index, r, axis, left, right, depth, s);
    }

    PrimRef* mid = std::partition(prims_.data() + r.begin, prims_.data() + r.end,
                                  [&](const PrimRef& pr) { return bin_of(pr) <= best; });
    for (int b = 0; b < nb; ++b) (b <= best ? left : right).grow(s.bins[b]);
    left.begin = r.begin;
    left.end = static_cast<uint32_t>(mid - prims_.data());
    right.begin = left.end;
    right.end = r.end;
    finish_interior(index, r, axis, left, right, depth, s);
  }

  void finish_interior(uint32_t index, const RangeInfo& r, int axis, const RangeInfo& left,
                       const RangeInfo& right, int depth, Scratch& s) {
    const uint32_t child = next_node_.fetch_add(2, std::memory_order_relaxed);
    tree_.nodes[index] = make_interior(r.lo, r.hi, child, static_cast<uint32_t>(axis));
    forker_.fork_join(
        left.end - left.begin,
        [&, child](bool on_new_thread) {
          if (on_new_thread) {
            Scratch own = make_scratch();
            build(child, left, depth + 1, own);
          } else {
            build(child, left, depth + 1, s);
          }
        },
        [&, child] { build(child + 1, right, depth + 1, s); });
  }

  std::span<PrimRef> prims_;
  BuildParams p_;
  Forker forker_;
  PairTree tree_;
  std::atomic<uint32_t> next_node_{1};
  std::atomic<std::size_t> depth_limited_{0};
};

}  // namespace

PairTree build_binned(std::span<PrimRef> prims, const BuildParams& params) {
  return BinnedBuilder(prims, params).run();
}

}  // namespace hp::bvh::detail
