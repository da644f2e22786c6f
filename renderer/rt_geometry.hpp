// The CPU side of the ray-traced scene: world geometry, the BVH and its leaf-order triangles. Vulkan-free:
// the GPU scene (rt_scene.hpp) uploads it, the CPU reference renderer (reference/) traverses it.
#pragma once

#include "bvh/bvh.hpp"
#include "bvh/traverse.hpp"
#include "scene/scene.hpp"

namespace hp {

/// The CPU side: world geometry, the tree and the leaf-order triangles the reference traversal uses.
struct RtGeometry {
  WorldGeometry world;
  std::vector<bvh::Triangle> triangles;  ///< scene order
  bvh::Bvh bvh;
  bvh::LeafOrderTriangles leaf;
  double build_ms = 0.0;
};
RtGeometry build_rt_geometry(const Scene& scene, const bvh::BuildOptions& options);

}  // namespace hp
