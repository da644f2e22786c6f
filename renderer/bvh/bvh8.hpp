// An 8-wide view of a built Bvh for tracing rays on the CPU fast: eight child boxes per node tested in two
// SSE groups of four, triangles in packets of four tested at once, children visited nearest first. Eight
// children rather than four halve the dependent node fetches of an incoherent ray, which is what it spends
// its time waiting for on trees larger than the caches (docs/bvh-performance.md).
//
// Same answers as the binary reference (traverse.hpp): the slab test and the watertight test are the
// reference's operations lane for lane, the boxes are the binary tree's boxes, and a box is pruned only when
// the reference's own test with the current closest t would prune it. Closest hit: the smallest t, ties to
// the smallest scene index, so the hit (prim, t, u, v) is bit for bit the reference's (up to the coplanar
// ties of traverse.hpp, where the visiting order decides). Any hit: a miss
// exactly when the reference misses; when both hit, some hit in range, not necessarily the reference's
// triangle (the first found depends on the visiting order).
//
// The counters differ from the binary traversal's (a wide node is one visit, a packet four tests): the GPU
// comparisons, which check nodes visited per ray, use the binary traversal.
#pragma once

#include "bvh/bvh.hpp"
#include "bvh/traverse.hpp"

#include <cstdint>
#include <span>
#include <vector>

namespace hp::bvh {

struct Bvh8 {
  static constexpr int kWidth = 8;
  /// Child boxes in structure-of-arrays form: box[2a][i] and box[2a + 1][i] are child i's bounds on axis a.
  /// An empty slot has an inverted box (+inf, -inf), which fails every slab test. 224 bytes, padded to 256.
  struct alignas(64) Node {
    float box[6][kWidth];
    /// Interior child: node index. Leaf child: kLeaf | index of its first packet.
    uint32_t child[kWidth];
  };
  /// Four triangles of one leaf in structure-of-arrays form: v[vertex][axis][lane].
  struct alignas(16) Packet {
    float v[3][3][4];
    /// Scene index per lane; kNoTriangle in an unused lane (whose vertices are NaN, never hit). kMore on lane
    /// 0 marks that the leaf continues in the next packet.
    uint32_t scene[4];
  };
  static constexpr uint32_t kLeaf = 0x80000000u;
  static constexpr uint32_t kMore = 0x80000000u;
  static constexpr uint32_t kNoTriangle = 0x7fffffffu;

  std::vector<Node> nodes;  ///< root at 0
  std::vector<Packet> packets;
};

/// The 8-wide form of `bvh`; `tris` must be leaf_order(bvh, ...) of the same build. A binary subtree holding
/// at most four triangles becomes one leaf (one packet).
Bvh8 make_bvh8(const Bvh& bvh, const LeafOrderTriangles& tris);

/// Closest hit, bit for bit the one of intersect_closest on the Bvh it was made from. `stats` (optional)
/// counts wide nodes visited and triangle lanes tested.
Hit intersect_closest(const Bvh8& bvh, const Ray& ray, TraversalStats* stats = nullptr);
/// Some hit in [tmin, tmax], or a miss exactly when intersect_any on the binary tree misses.
Hit intersect_any(const Bvh8& bvh, const Ray& ray, TraversalStats* stats = nullptr);

}  // namespace hp::bvh
