// The 4-wide node layout ("wide4", NodeLayout::wide4): the binary tree collapsed into nodes of up to four
// slots, each wide node holding a cut of a binary node's subtree chosen for the least SAH cost, with the
// slots' boxes quantized to 8 bits (gpu::WideNode in
// core/gpu/shared_types.h says the bytes). The GPU passes read it when a scene asks for it
// (shaders/common/traversal.glsl, hp_trace_wide); the traversal here is its C++ twin, operation for
// operation, so the two agree bit for bit, counters included.
//
// Semantics: those of the binary reference (traverse.hpp) for the answers: closest hit = smallest t, ties
// to the smallest scene index, hence bit for bit the binary tree's hit; any hit = a miss exactly when the
// binary tree misses. The work differs: a visited wide node is one node (its four child boxes are tested
// together, with the closest t so far), a popped leaf is tested without its box again. Children are visited
// in the binary order (stored per ray octant in the node), hit children after the first pushed.
#pragma once

#include "bvh/bvh.hpp"
#include "bvh/traverse.hpp"

#include <cstdint>
#include <span>
#include <vector>

namespace hp::bvh {

struct WideBvh {
  std::vector<gpu::WideNode> nodes;  ///< root at 0; an empty tree is one node with four empty slots
  /// The most stack entries a traversal of this tree can hold: at each wide node on a path it pushes the
  /// node's hit children but one. make_wide refuses a tree over HP_BVH_STACK_SIZE.
  int stack_need = 0;
};

/// The wide form of `bvh`. Throws InputError when a leaf holds more than 15 primitives, a primitive slot
/// needs more than 27 bits, or the stack bound above exceeds HP_BVH_STACK_SIZE (each names the limit).
WideBvh make_wide(const Bvh& bvh);

/// Slot `slot`'s decoded box of wide node `n` (bmin, bmax), as both traversals compute it.
void wide_child_box(const gpu::WideNode& n, int slot, glm::vec3& bmin, glm::vec3& bmax);

Hit intersect_closest(const WideBvh& bvh, const LeafOrderTriangles& tris, const Ray& ray,
                      TraversalStats* stats = nullptr);
Hit intersect_any(const WideBvh& bvh, const LeafOrderTriangles& tris, const Ray& ray, TraversalStats* stats = nullptr);
/// A batch on `threads` workers (0 = all cores), as cast_rays on the binary tree.
std::vector<Hit> cast_rays(const WideBvh& bvh, const LeafOrderTriangles& tris, std::span<const Ray> rays, HitMode mode,
                           int threads = 0, TraversalStats* stats = nullptr);

}  // namespace hp::bvh
