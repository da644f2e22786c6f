#version 460
#extension GL_GOOGLE_include_directive : require
// Ray-traced reflections: for each reflective pixel of the (possibly reduced) reflection grid, the view
// ray reflected about a GGX-sampled microfacet normal, traced to the closest hit and shaded there.
#include "common/reflection_common.glsl"
#include "common/dispatch_order.glsl"

// Compiled as a compute shader (BVH traversal, or HP_RAY_QUERY) and as a ray-generation shader
// (HP_RT_PIPELINE), as shadows.comp is.
#ifndef HP_RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8) in;
#endif

// Cell q of the reflection grid, invocation `local` of tile wg of a row of wgx tiles.
void hp_reflection_cell(uvec2 wg, uint wgx, ivec2 q, uint local) {
  if (q.x >= int(rt.grid.x) || q.y >= int(rt.grid.y)) return;
  HP_TRACE_BEGIN_AT(wg, wgx, rt.frame.w, local);
  uint cell = uint(q.y) * rt.grid.x + uint(q.x);
  HpStats st;
  st.nodes = 0u; st.tris = 0u;
  uint shadow_rays = 0u;
  RayDump dump;
  dump.origin_tmin = vec4(0.0); dump.dir_tmax = vec4(0.0); dump.hit = ivec4(-1, 0, 0, 0);
  vec4 result = vec4(0.0);  // alpha 0: not a reflective pixel
  vec3 o, d;
  bool was_cast = false;
  if (hp_reflection_ray(q, cell, o, d)) {
    HpHit h;
    vec3 color = hp_shade_reflection(o, d, st, shadow_rays, h, was_cast);
    if (was_cast) dump.hit = ivec4(h.slot, floatBitsToInt(h.t), 1, 0);  // slot: mapped to the scene index below
    dump.origin_tmin = vec4(o, 0.0);
    dump.dir_tmax = vec4(d, HP_FLT_MAX);
    result = vec4(color, 1.0);
  }
  HP_REC_STORE(HP_TBUF_REFLECTION, cell * 16u, 16u);
  imageStore(reflection_image, q, result);
  if ((HP_RT_FLAGS & HP_RT_DUMP_RAYS) != 0u) {
    // Debug output only: the slot -> scene lookup is not part of the pass's real work (nor traced).
    if (dump.hit.x >= 0) dump.hit.x = int(slot_scene[uint(dump.hit.x)]);
    reflection_dump[cell] = dump;
  }
  hp_count_reflection(was_cast, st, shadow_rays);
}

void main() {
#ifdef HP_RT_PIPELINE
  hp_reflection_cell(uvec2(0u), 0u, hp_launch_pixel(), 0u);  // dispatch_order.glsl
#else
#ifdef HP_TRACE
  if (hp_trace_sharing()) {  // the slice's tiles, each taken whole by one subgroup (dispatch_order.glsl)
    uint wgx = (rt.grid.x + 7u) / 8u;
    uvec2 wg;
    while (hp_next_shared_tile(wgx, wg)) {
      for (uint c = 0u; c < 64u; c += gl_SubgroupSize) {
        uint local = c + gl_SubgroupInvocationID;
        hp_reflection_cell(wg, wgx, ivec2(wg * 8u + uvec2(local % 8u, local / 8u)), local);
      }
    }
    return;
  }
#endif
  uvec2 wg = hp_tile_workgroup();  // dispatch_order.glsl
  hp_reflection_cell(wg, gl_NumWorkGroups.x, ivec2(wg * gl_WorkGroupSize.xy + gl_LocalInvocationID.xy),
                     gl_LocalInvocationIndex);
#endif
}
