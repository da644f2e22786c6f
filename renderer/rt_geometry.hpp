// The CPU side of the ray-traced scene: world geometry, the BVH and its leaf-order triangles. Vulkan-free:
// the GPU scene (rt_scene.hpp) uploads it, the CPU reference renderer (reference/) traverses it.
#pragma once

#include "bvh/bvh.hpp"
#include "bvh/traverse.hpp"
#include "bvh/wide.hpp"
#include "scene/scene.hpp"

namespace hp {

/// The CPU side: world geometry, the tree and the leaf-order triangles the reference traversal uses.
struct RtGeometry {
  WorldGeometry world;
  std::vector<bvh::Triangle> triangles;  ///< scene order
  bvh::Bvh bvh;
  bvh::LeafOrderTriangles leaf;
  /// The layout the GPU traversal reads (BuildOptions::node_layout); `wide` holds the wide4 form of `bvh`
  /// where it is chosen (else it is empty).
  bvh::NodeLayout node_layout = bvh::NodeLayout::binary32;
  bvh::WideBvh wide;
  double build_ms = 0.0;  ///< the build, and the wide form's conversion where chosen
};
/// Throws InputError where the tree does not fit the chosen node layout (bvh::make_wide names the limit).
RtGeometry build_rt_geometry(const Scene& scene, const bvh::BuildOptions& options);

/// The C++ traversal of the layout the GPU reads (the binary reference, or the wide4 twin of the shader):
/// the same answers either way, and the GPU's counters for that layout.
bvh::Hit trace_reference(const RtGeometry& g, const bvh::Ray& ray, bvh::HitMode mode,
                         bvh::TraversalStats* stats = nullptr);
/// A batch of trace_reference on `threads` workers (0 = all cores), as bvh::cast_rays.
std::vector<bvh::Hit> cast_reference(const RtGeometry& g, std::span<const bvh::Ray> rays, bvh::HitMode mode,
                                     int threads = 0, bvh::TraversalStats* stats = nullptr);

}  // namespace hp
