// How a BVH is built: the plain options that scenarios, reports and the builder share (no Vulkan, no scenes).
#pragma once

#include "gpu/shared_types.h"

namespace hp::bvh {

/// What one BVH primitive is.
enum class Granularity {
  triangle,  ///< one primitive per triangle (default)
  object,    ///< one primitive per object (a contiguous triangle range); a leaf's objects are tested
             ///< triangle by triangle, as the study's Unity code did
};

/// How the built tree is laid out for the traversals (bvh/wide.hpp). The builder's tree is the same.
enum class NodeLayout {
  binary32,  ///< the study's 32-byte binary node (gpu::BvhNode): the default, what the study's scenarios use
  wide4,     ///< 64-byte 4-wide nodes with 8-bit quantized child boxes (gpu::WideNode), leaves of <= 15
};

struct BuildOptions {
  /// Number of SAH buckets per binned axis, 2..1024 (a node of n < buckets primitives uses n). Ignored by
  /// the full sweep.
  int buckets = 12;
  /// Bin all three axes and take the cheapest split (default). false: bin only the axis of largest centroid
  /// extent, as the study and pbrt do; measured here that rule lands 4-5% above the full sweep's SAH cost
  /// on spheres and terrains even with 32 buckets, all three axes within 1% (docs/bvh.md).
  bool all_axes = true;
  /// Exact top-down SAH: every split position between primitives sorted by centroid, on all three axes.
  /// Slower (O(N log N) with three presorted lists); the reference the binned build is measured against.
  bool full_sweep = false;
  /// Cost of one traversal step relative to one primitive test (which costs 1). The study used 0.5.
  float traversal_cost = 0.5f;
  /// Largest leaf, in primitives (triangles or objects), 1..(2^30 - 1). A node with more is always split;
  /// one with fewer becomes a leaf when that is cheaper than its best split. The study used 4.
  int max_leaf_size = 4;
  Granularity granularity = Granularity::triangle;
  /// Worker threads; 0 = std::thread::hardware_concurrency().
  int threads = 0;
  /// Largest number of interior nodes above any leaf, 1..HP_BVH_STACK_SIZE (which it defaults to).
  int max_depth = HP_BVH_STACK_SIZE;
  /// Layout the traversals read; not an input of the build itself.
  NodeLayout node_layout = NodeLayout::binary32;
};

}  // namespace hp::bvh
