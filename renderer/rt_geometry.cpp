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
  g.build_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  g.leaf = bvh::leaf_order(g.bvh, g.triangles);
  return g;
}

}  // namespace hp
