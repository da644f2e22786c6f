// The GPU passes' answers against the C++ reference traversal, ray by ray: the shaders dump every ray they
// cast (RayTracingOptions::dump_rays) and each is re-traced on the CPU. Shared by the ray-tracing and the
// hard-case tests.
#pragma once

#include "bvh/traverse.hpp"
#include "frame.hpp"

#include <cstdio>
#include <vector>

namespace hp {

/// A frame with both ray-tracing passes and their ray dumps on (the tests' usual frame).
inline FrameSettings rt_test_settings(uint32_t w, uint32_t h) {
  FrameSettings s;
  s.width = w;
  s.height = h;
  s.rt.shadows = true;
  s.rt.reflections = true;
  s.rt.dump_rays = true;
  return s;
}

struct Agreement {
  size_t rays = 0, equal = 0;
};

// Compares every dumped ray's GPU answer with the reference traversal's; prints the disagreements.
inline Agreement compare(const Frame& frame, const std::vector<gpu::RayDump>& dump, bool any_hit, const char* what) {
  const RtGeometry& g = *frame.rt_geometry();
  Agreement a;
  int printed = 0;
  for (size_t i = 0; i < dump.size(); ++i) {
    if (dump[i].hit.z == 0) continue;  // no ray cast for this pixel
    ++a.rays;
    const bvh::Ray ray = dumped_ray(dump[i]);
    const bvh::Hit ref = any_hit ? bvh::intersect_any(g.bvh, g.leaf, ray) : bvh::intersect_closest(g.bvh, g.leaf, ray);
    const int gpu_prim = dump[i].hit.x;
    const bool same = any_hit ? ((gpu_prim >= 0) == ref.hit()) : (gpu_prim == ref.prim);
    if (same) {
      ++a.equal;
    } else if (printed++ < 10) {
      std::printf("  %s differs at #%zu: o=(%.9g, %.9g, %.9g) d=(%.9g, %.9g, %.9g) gpu prim %d, cpu prim %d (t %.9g)\n",
                  what, i, ray.origin.x, ray.origin.y, ray.origin.z, ray.dir.x, ray.dir.y, ray.dir.z, gpu_prim,
                  ref.prim, ref.t);
    }
  }
  std::printf("%s: %zu rays, %zu equal, %zu differ\n", what, a.rays, a.equal, a.rays - a.equal);
  return a;
}

}  // namespace hp
