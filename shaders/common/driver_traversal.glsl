// hp_trace through the driver's acceleration structure (renderer/accel_structure.hpp), for the same passes
// as the compute traversal: with HP_RAY_QUERY a ray query in the compute shader (VK_KHR_ray_query), with
// HP_RT_PIPELINE a traceRayEXT from a ray-generation shader into shaders/rt/hit.rchit and miss.rmiss
// (VK_KHR_ray_tracing_pipeline). Included by traversal.glsl, which declares HpRay, HpHit and HpStats.
//
// The hit is the driver's committed triangle: its primitive index mapped to the leaf-order slot (the
// identity in leaf order, else as_slot[]), t and the barycentrics (u, v) of vertices 1 and 2, the convention
// the compute traversal uses. The driver's traversal is opaque: HpStats stays 0 (no node or triangle
// counts), and the instrumented variants record only the shader's own accesses. The API promises neither
// watertightness nor a tie-break: a closest hit at exactly the same t as another may name either triangle.
#ifndef HP_DRIVER_TRAVERSAL_GLSL
#define HP_DRIVER_TRAVERSAL_GLSL

#if defined(HP_RAY_QUERY)
#extension GL_EXT_ray_query : require
#elif defined(HP_RT_PIPELINE)
#extension GL_EXT_ray_tracing : require
#endif
#include "gpu/bindings.h"

// 1 where the acceleration structure's triangles are not in leaf order (AsOrder scene or morton, or the
// instances layout): the slot is as_slot[instance custom index + primitive index] (the custom index is 0 in
// the flat layout, an instance's first scene triangle in the instances layout; 0xFFFFFFFF: no slot).
layout(constant_id = 4) const uint HP_AS_REMAP = 0;
layout(set = 0, binding = HP_BIND_RT_TLAS) uniform accelerationStructureEXT hp_tlas;
layout(std430, set = 0, binding = HP_BIND_RT_AS_SLOT) readonly buffer AsSlotBuffer { uint as_slot[]; };

int hp_as_slot(uint primitive) {
  if (HP_AS_REMAP == 0u) return int(primitive);
  uint s = as_slot[primitive];
  return s == 0xFFFFFFFFu ? -1 : int(s);
}

// The API takes 0 <= tmin <= tmax: a segment wholly behind the origin or empty misses; one starting behind
// the origin starts at it (where the compute traversal would also accept hits at negative t).
bool hp_driver_segment(HpRay r, out float tmin) {
  tmin = max(r.tmin, 0.0);
  return r.tmax >= tmin;
}

// What both driver traversals start with: a miss, the segment the API takes, and the ray flags (opaque;
// any hit: stop at the first hit found). False when the segment is empty (the ray misses untraced).
bool hp_driver_begin(HpRay r, bool any_hit, out HpHit best, out float tmin, out uint flags) {
  best = hp_no_hit();
  flags = gl_RayFlagsOpaqueEXT | (any_hit ? gl_RayFlagsTerminateOnFirstHitEXT : 0u);
  return hp_driver_segment(r, tmin);
}

#if defined(HP_RAY_QUERY)
HpHit hp_trace(HpRay r, bool any_hit, inout HpStats stats) {
  HpHit best;
  float tmin;
  uint flags;
  if (!hp_driver_begin(r, any_hit, best, tmin, flags)) return best;
  rayQueryEXT q;
  rayQueryInitializeEXT(q, hp_tlas, flags, 0xFFu, r.org, tmin, r.dir, r.tmax);
  while (rayQueryProceedEXT(q)) {
    // Opaque geometry only: the driver commits every candidate itself, nothing to confirm here.
  }
  if (rayQueryGetIntersectionTypeEXT(q, true) == gl_RayQueryCommittedIntersectionTriangleEXT) {
    best.slot = hp_as_slot(uint(rayQueryGetIntersectionInstanceCustomIndexEXT(q, true)) +
                           uint(rayQueryGetIntersectionPrimitiveIndexEXT(q, true)));
    best.t = rayQueryGetIntersectionTEXT(q, true);
    vec2 b = rayQueryGetIntersectionBarycentricsEXT(q, true);
    best.u = b.x; best.v = b.y;
  }
  return best;
}

#elif defined(HP_RT_PIPELINE)
#include "common/rt_payload.glsl"

layout(location = 0) rayPayloadEXT HpPayload hp_payload;

HpHit hp_trace(HpRay r, bool any_hit, inout HpStats stats) {
  HpHit best;
  float tmin;
  uint flags;
  if (!hp_driver_begin(r, any_hit, best, tmin, flags)) return best;
  hp_payload.primitive = -1;
  // SBT: hit group 0 (closest hit), miss shader 0; no recursion (the payload comes back to this shader).
  traceRayEXT(hp_tlas, flags, 0xFFu, 0u, 1u, 0u, r.org, tmin, r.dir, r.tmax, 0);
  if (hp_payload.primitive >= 0) {
    best.slot = hp_as_slot(uint(hp_payload.primitive));
    best.t = hp_payload.t;
    best.u = hp_payload.u; best.v = hp_payload.v;
  }
  return best;
}
#endif

#endif
