#include "rt_geometry.hpp"

#include <chrono>

namespace hp {

RtGeometry build_rt_geometry(const Scene& scene, const bvh::BuildOptions& options) {
  RtGeometry g;
  g.world = world_geometry(scene);
  g.triangles = bvh::make_triangles(g.world.positions, g.world.indices);
  const auto t0 = std::chrono::steady_clock::now();
  if (options.granularity == bvh::Granularity::object) {
    g.bvh = bvh::build_bvh(g.triangles, options, g.world.instance_first_triangle);
  } else {
    g.bvh = bvh::build_bvh(g.triangles, options);
  }
  g.node_layout = options.node_layout;
  if (g.node_layout == bvh::NodeLayout::wide4) g.wide = bvh::make_wide(g.bvh);
  g.build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  g.leaf = bvh::leaf_order(g.bvh, g.triangles);
  return g;
}

bvh::Hit trace_reference(const RtGeometry& g, const bvh::Ray& ray, bvh::HitMode mode, bvh::TraversalStats* stats) {
  const bool any = mode == bvh::HitMode::any;
  if (g.node_layout == bvh::NodeLayout::wide4) {
    return any ? bvh::intersect_any(g.wide, g.leaf, ray, stats) : bvh::intersect_closest(g.wide, g.leaf, ray, stats);
  }
  return any ? bvh::intersect_any(g.bvh, g.leaf, ray, stats) : bvh::intersect_closest(g.bvh, g.leaf, ray, stats);
}

std::vector<bvh::Hit> cast_reference(const RtGeometry& g, std::span<const bvh::Ray> rays, bvh::HitMode mode,
                                     int threads, bvh::TraversalStats* stats) {
  if (g.node_layout == bvh::NodeLayout::wide4) return bvh::cast_rays(g.wide, g.leaf, rays, mode, threads, stats);
  return bvh::cast_rays(g.bvh, g.leaf, rays, mode, threads, stats);
}

}  // namespace hp
