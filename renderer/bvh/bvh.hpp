// Building a BVH and flattening it to the 32-byte node that C++ and GLSL share (hp::gpu::BvhNode).
//
// Node layout (core/gpu/shared_types.h): depth-first, root at 0, the first child right after its
// parent; interior: offset = index of the second child, count = 0, axis = split axis; leaf: offset = first
// primitive slot, count > 0. prim_axis = (count << HP_BVH_AXIS_BITS) | axis.
//
// Stack guarantee: a traversal that pushes the far child and descends into the near one holds at most
// `depth` entries, where depth counts the interior nodes above a leaf. The builder bounds that depth by
// BuildOptions::max_depth <= HP_BVH_STACK_SIZE, switching a node from its SAH split to a median split
// whenever the SAH split could no longer be finished within the remaining depth (see build_bvh).
#pragma once

#include "bvh/geometry.hpp"
#include "bvh_options.hpp"
#include "gpu/shared_types.h"

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace hp::bvh {

/// Where one build's wall time went (steady clock, milliseconds). The top of the tree, its two subtrees and
/// the join are those of the binned builder's first fork, which is at the root whenever the root's second child
/// is large enough to fork (8192 primitives) and a second thread is allowed; `forked` is false otherwise (one
/// thread, a small scene, the full-sweep builder), and then only references_ms and tree_ms are set.
struct BuildPhases {
  double references_ms = 0.0;  ///< the primitive references and their bounds (parallel chunks)
  double tree_ms = 0.0;        ///< the tree, from the references to the end
  bool forked = false;
  double top_ms = 0.0;     ///< from the tree's start to its first fork (the root: its split search, partition)
  double first_ms = 0.0;   ///< the fork's first subtree, on the thread that forked (it may fork again inside)
  double second_ms = 0.0;  ///< its second subtree, on a thread of its own
  std::size_t first_primitives = 0, second_primitives = 0;
  double append_ms = 0.0;  ///< after both: the second subtree's nodes appended after the first's
};

/// A flattened BVH. Plain data: upload `nodes` as they are, and primitives in leaf order (leaf_order()).
struct Bvh {
  std::vector<gpu::BvhNode> nodes;  ///< depth-first; empty scene: one node with an empty (inverted) box
  /// Leaf order -> scene index of the primitive (triangle index, or object index for Granularity::object).
  /// Degenerate triangles (is_degenerate) and empty objects are left out, so it can be shorter than the
  /// input.
  std::vector<uint32_t> prim_ids;
  Granularity granularity = Granularity::triangle;
  /// Object granularity: the object ranges given to build_bvh (object i = triangles
  /// [object_first[i], object_first[i+1]) in scene order). Empty for the triangle granularity.
  std::vector<uint32_t> object_first;
  float traversal_cost = 0.5f;  ///< the cost model it was built with, for bvh_stats()
  int max_depth = 0;            ///< interior nodes above the deepest leaf (= worst-case stack use)
  /// Nodes where the SAH split was replaced by a median split to keep the depth within max_depth.
  std::size_t depth_limited_splits = 0;
  BuildPhases phases;  ///< how long the build that made it took, by phase
};

/// Builds a BVH over `triangles` (scene order).
/// Object granularity: `object_first` has one entry per object plus a final one (its first entry 0, its
/// last triangles.size(), non-decreasing); object i holds triangles [object_first[i], object_first[i+1]).
/// Triangle granularity: `object_first` must be empty.
/// Throws hp::InputError for invalid options or object ranges. Never returns a tree deeper than
/// options.max_depth.
Bvh build_bvh(std::span<const Triangle> triangles, const BuildOptions& options,
              std::span<const uint32_t> object_first = {});

/// Shape and quality of a built tree.
struct BvhStats {
  std::size_t nodes = 0;
  std::size_t leaves = 0;
  std::size_t primitives = 0;  ///< primitives referenced by leaves (triangles or objects)
  std::size_t triangles = 0;   ///< triangles a traversal can test (object granularity: all in the objects)
  /// leaf_size_histogram[k] = number of leaves holding k primitives.
  std::vector<std::size_t> leaf_size_histogram;
  int max_depth = 0;
  /// SAH cost relative to the root's area: sum over interior nodes of traversal_cost * A(n) / A(root)
  /// plus sum over leaves of primitives(n) * A(n) / A(root). 0 for an empty tree.
  double sah_cost = 0.0;
  /// The same with a leaf costing the triangles it holds (differs from sah_cost for objects only).
  double sah_cost_triangles = 0.0;
};
BvhStats bvh_stats(const Bvh& bvh);

/// Triangles rearranged into the order the traversal (and the GPU) reads them.
struct LeafOrderTriangles {
  /// Triangle granularity: triangles[k] is primitive slot k. Object granularity: the objects' triangles,
  /// objects in leaf order; degenerate triangles inside objects are collapsed to their first vertex so that
  /// the watertight test rejects them exactly (every edge function is exactly 0).
  std::vector<Triangle> triangles;
  std::vector<uint32_t> scene_index;  ///< per entry of `triangles`: its index in scene order
  /// Object granularity only (else empty): object slot j (leaf order) holds triangles
  /// [object_first[j], object_first[j+1]); a leaf (offset, count) holds
  /// [object_first[offset], object_first[offset + count]).
  std::vector<uint32_t> object_first;
};
/// `triangles` must be the array the tree was built from (scene order).
LeafOrderTriangles leaf_order(const Bvh& bvh, std::span<const Triangle> triangles);

/// Unpacking of prim_axis.
inline uint32_t node_count(const gpu::BvhNode& n) { return n.prim_axis >> HP_BVH_AXIS_BITS; }
inline uint32_t node_axis(const gpu::BvhNode& n) { return n.prim_axis & HP_BVH_AXIS_MASK; }
inline bool node_is_leaf(const gpu::BvhNode& n) { return node_count(n) > 0; }

}  // namespace hp::bvh
