#version 460
#extension GL_GOOGLE_include_directive : require
// Consumes the compacted (optionally sorted) reflection rays, one thread per ray: the same traversal and
// shading as the direct pass. The result goes to the ray's grid cell (write-back by index, exact) or to
// the cell its origin reprojects to (the study's write-back), where misplaced writes are counted.
#include "common/reflection_common.glsl"
#include "common/compaction.glsl"
#include "common/dispatch_order.glsl"

// Compiled as a compute shader (BVH traversal, or HP_RAY_QUERY) and as a ray-generation shader
// (HP_RT_PIPELINE, launched indirectly over exactly the appended rays), as shadows.comp is.
#ifndef HP_RT_PIPELINE
layout(local_size_x = 64) in;
#endif

void main() {
#ifdef HP_RT_PIPELINE
  // Blocks of 64 rays in spread order (dispatch_order.glsl), as the compute dispatch takes them.
  uint i = hp_spread_blocks(gl_LaunchIDEXT.x, gl_LaunchSizeEXT.x, 64u);
#else
  // rt.frame.z offsets the workgroups when the traced variant is dispatched in slices (0 otherwise); the
  // workgroups take their rays in spread order (dispatch_order.glsl).
  uint group = rt.frame.z + hp_spread(gl_WorkGroupID.x, gl_NumWorkGroups.x);
  uint i = group * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
#endif
  HP_TRACE_BEGIN(uvec2(group, 0u), 1u, rt.frame.w);
  HP_REC_LOAD(HP_TBUF_RAY_COUNT, 0u, 4u);
  if (i >= ray_count) return;
  HP_REC_LOAD(HP_TBUF_SORT_VALUES, i * 4u, 4u);
  uint r = sort_values[i];
  HP_REC_LOAD(HP_TBUF_COMPACT_RAYS, r * 32u, 16u);
  HP_REC_LOAD(HP_TBUF_COMPACT_RAYS, r * 32u + 16u, 16u);
  CompactRay cr = compact_rays[r];
  vec3 o = cr.origin_cell.xyz;
  vec3 d = cr.dir.xyz;
  uint cell = floatBitsToUint(cr.origin_cell.w);
  HpStats st;
  st.nodes = 0u; st.tris = 0u;
  uint shadow_rays = 0u;
  HpHit h;
  bool was_cast;
  vec3 color = hp_shade_reflection(o, d, st, shadow_rays, h, was_cast);
  uint target = cell;
  if (int(rt.bounds_max.w) == HP_WRITEBACK_REPROJECT) {
    // The study wrote results back by projecting the ray origin to the screen.
    vec4 c = frame.view_proj * vec4(o - frame.camera_pos.xyz, 1.0);  // camera-relative view_proj
    vec2 px = (c.xy / c.w * 0.5 + 0.5) * vec2(frame.extent.xy);
    ivec2 g = clamp(ivec2(floor(px)) / int(rt.grid.z), ivec2(0), ivec2(rt.grid.xy) - 1);
    target = uint(g.y) * rt.grid.x + uint(g.x);
    if (target != cell && (HP_RT_FLAGS & HP_RT_COUNTERS) != 0u) hp_counter_add(HP_COUNTER_REPROJECT_MISPLACED, 1u);
  }
  HP_REC_STORE(HP_TBUF_REFLECTION, target * 16u, 16u);
  imageStore(reflection_image, ivec2(target % rt.grid.x, target / rt.grid.x), vec4(color, 1.0));
  hp_count_reflection(was_cast, st, shadow_rays);
}
