// The reference traversal: what every GPU pass must agree with.
//
// Semantics (the GLSL side follows them exactly):
//  - A hit is accepted for ray.tmin <= t <= ray.tmax. Closest hit: smallest t, ties to the smallest scene
//    index, so the answer does not depend on the tree or the traversal order — except between triangles
//    that overlap in one plane, whose computed t can differ by more than a box's rounding: a box entered
//    just after the closest t so far is pruned though it holds a triangle whose computed t is a little
//    smaller, so which of the two is returned depends on the visiting order (docs/bvh.md). Any hit: the
//    first accepted hit found, which is some hit in range, not necessarily the closest.
//  - Nodes are visited depth-first from a fixed stack of HP_BVH_STACK_SIZE entries; each visited node's box
//    is tested (the root's too, which is how an empty tree ends at once); at an interior node the child on
//    the near side of the split axis (by the sign of the ray direction on that axis) is visited first, the
//    other is pushed. A closest-hit traversal prunes boxes that start beyond the closest hit so far.
//  - Ray/box: slab test after Williams et al. (JGT 2005): reciprocal direction, near/far planes picked by
//    its sign (so -0 and +0 select correctly), and comparisons ordered so that the NaN of 0 * inf (an origin
//    exactly on a slab plane with a zero direction component) is discarded, counting that plane as inside.
//    The far bound is widened by 1 + 2 gamma(3) (Ize, JCGT 2(2) 2013), which makes the test conservative.
//  - Ray/triangle: watertight (Woop, Benthin, Wald, JCGT 2(1) 2013), no back-face culling, edge functions
//    recomputed in double when one is exactly 0. Edges and vertices are inclusive: a ray through a shared
//    edge or vertex of a closed mesh hits at least one of the triangles. Compiled with -ffp-contract=off.
//  - A ray with a zero or non-finite direction, a non-finite origin or a NaN tmin/tmax never hits.
#pragma once

#include "bvh/bvh.hpp"
#include "bvh/geometry.hpp"

#include <cstdint>
#include <span>
#include <vector>

namespace hp::bvh {

/// Per-ray work counters; they add up over a batch.
struct TraversalStats {
  uint64_t nodes_visited = 0;     ///< nodes whose box was tested
  uint64_t triangles_tested = 0;  ///< ray/triangle tests run

  TraversalStats& operator+=(const TraversalStats& o) {
    nodes_visited += o.nodes_visited;
    triangles_tested += o.triangles_tested;
    return *this;
  }
};

/// Closest hit of `ray` in the tree. `tris` must come from leaf_order(bvh, ...) of the same build.
/// `stats` (optional) receives this ray's counters (added to what it holds).
Hit intersect_closest(const Bvh& bvh, const LeafOrderTriangles& tris, const Ray& ray, TraversalStats* stats = nullptr);

/// Some hit in [tmin, tmax] (the first found), or a miss: the occlusion query of shadow rays.
Hit intersect_any(const Bvh& bvh, const LeafOrderTriangles& tris, const Ray& ray, TraversalStats* stats = nullptr);

enum class HitMode { closest, any };

/// Casts a batch on `threads` workers (0 = all cores); result i belongs to rays[i]. `stats` (optional)
/// receives the sum over all rays.
std::vector<Hit> cast_rays(const Bvh& bvh, const LeafOrderTriangles& tris, std::span<const Ray> rays, HitMode mode,
                           int threads = 0, TraversalStats* stats = nullptr);

/// The watertight ray/triangle test alone: true when `ray` hits `tri` with ray.tmin <= t <= ray.tmax.
bool intersect_triangle(const Ray& ray, const Triangle& tri, Hit& hit);

/// The slab test alone: true when the ray's [tmin, tmax] overlaps the box; tnear/tfar are the overlap
/// (tfar widened as in the traversal).
bool intersect_box(const Ray& ray, const glm::vec3& bmin, const glm::vec3& bmax, float& tnear, float& tfar);

/// Reference answers without a tree, over scene-order triangles, skipping degenerate ones (is_degenerate):
/// the same hit semantics as the traversal, for tests and cross-checks.
Hit brute_force_closest(std::span<const Triangle> triangles, const Ray& ray);
Hit brute_force_any(std::span<const Triangle> triangles, const Ray& ray);

}  // namespace hp::bvh
