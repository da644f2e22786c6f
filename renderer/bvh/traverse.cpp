// Compiled with -ffp-contract=off (see CMakeLists.txt): a fused multiply-add in an edge function rounds
// the two products differently, so the two triangles sharing an edge no longer compute exactly opposite
// values for it, and rays through the edge fall through (watertightness is lost).
#include "bvh/traverse.hpp"

#include "bvh/traverse_detail.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace hp::bvh {
namespace {

using detail::prepare;
using detail::PreparedRay;
using detail::slab;
using detail::watertight;

inline const float* node_floats(const gpu::BvhNode& n) { return &n.bmin.x; }

template <bool kAny>
Hit traverse(const Bvh& bvh, const LeafOrderTriangles& lt, const Ray& ray, TraversalStats* stats) {
  Hit best;
  PreparedRay r;
  if (bvh.nodes.empty() || !prepare(ray, r)) return best;
  const gpu::BvhNode* nodes = bvh.nodes.data();

  float best_t = r.tmax;
  uint32_t best_scene = UINT32_MAX;
  uint64_t visited = 0, tested = 0;
  uint32_t stack[HP_BVH_STACK_SIZE];
  int sp = 0;
  uint32_t node = 0;
  for (;;) {
    const gpu::BvhNode& n = nodes[node];
    ++visited;
    float tn, tf;
    if (slab(r, node_floats(n), best_t, tn, tf)) {
      const uint32_t count = n.prim_axis >> HP_BVH_AXIS_BITS;
      if (count == 0) {
        const uint32_t axis = n.prim_axis & HP_BVH_AXIS_MASK;
        uint32_t near_child = node + 1;
        uint32_t far_child = static_cast<uint32_t>(n.offset);
        if (r.near_at[axis] >= 4) std::swap(near_child, far_child);
        if (sp == HP_BVH_STACK_SIZE) {
          // build_bvh bounds the depth; a tree that breaks it was not built by build_bvh.
          throw std::logic_error("bvh traversal: stack overflow (tree deeper than HP_BVH_STACK_SIZE)");
        }
        stack[sp++] = far_child;
        // The far child is usually visited soon after the near subtree; on trees larger than the caches
        // fetching it now measured 10-30% more rays per second (1M-triangle scenes, random rays).
        __builtin_prefetch(&nodes[far_child]);
        node = near_child;
        continue;
      }
      const uint32_t first = static_cast<uint32_t>(n.offset);
      // Any hit: occluded, nothing else matters.
      if (detail::test_leaf<kAny>(r, lt, first, first + count, best, best_t, best_scene, tested)) sp = 0;
    }
    if (sp == 0) break;
    node = stack[--sp];
  }
  if (stats) {
    stats->nodes_visited += visited;
    stats->triangles_tested += tested;
  }
  return best;
}

template <bool kAny>
Hit brute_force(std::span<const Triangle> triangles, const Ray& ray) {
  Hit best;
  PreparedRay r;
  if (!prepare(ray, r)) return best;
  float best_t = r.tmax;
  for (std::size_t k = 0; k < triangles.size(); ++k) {
    if (is_degenerate(triangles[k])) continue;
    float t, u, v;
    if (!watertight(r, triangles[k], t, u, v) || !(t >= r.tmin) || !(t <= best_t)) continue;
    if (kAny) return Hit{static_cast<int32_t>(k), t, u, v};
    // Scene order is increasing k, so "t == best_t" keeps the smaller index already.
    if (t < best_t || best.prim < 0) {
      best_t = t;
      best = Hit{static_cast<int32_t>(k), t, u, v};
    }
  }
  return best;
}

}  // namespace

Hit intersect_closest(const Bvh& bvh, const LeafOrderTriangles& tris, const Ray& ray, TraversalStats* stats) {
  return traverse<false>(bvh, tris, ray, stats);
}

Hit intersect_any(const Bvh& bvh, const LeafOrderTriangles& tris, const Ray& ray, TraversalStats* stats) {
  return traverse<true>(bvh, tris, ray, stats);
}

std::vector<Hit> cast_rays(const Bvh& bvh, const LeafOrderTriangles& tris, std::span<const Ray> rays, HitMode mode,
                           int threads, TraversalStats* stats) {
  return detail::cast_mode(rays, mode, threads, stats, [&](auto any, const Ray& ray, TraversalStats* local) {
    return traverse<decltype(any)::value>(bvh, tris, ray, local);
  });
}

bool intersect_triangle(const Ray& ray, const Triangle& tri, Hit& hit) {
  PreparedRay r;
  if (!prepare(ray, r)) return false;
  float t, u, v;
  if (!watertight(r, tri, t, u, v) || !(t >= r.tmin) || !(t <= r.tmax)) return false;
  hit = Hit{0, t, u, v};
  return true;
}

bool intersect_box(const Ray& ray, const glm::vec3& bmin, const glm::vec3& bmax, float& tnear, float& tfar) {
  PreparedRay r;
  if (!prepare(ray, r)) return false;
  const float box[8] = {bmin.x, bmin.y, bmin.z, 0.0f, bmax.x, bmax.y, bmax.z, 0.0f};
  return slab(r, box, r.tmax, tnear, tfar);
}

Hit brute_force_closest(std::span<const Triangle> triangles, const Ray& ray) {
  return brute_force<false>(triangles, ray);
}

Hit brute_force_any(std::span<const Triangle> triangles, const Ray& ray) { return brute_force<true>(triangles, ray); }

}  // namespace hp::bvh
