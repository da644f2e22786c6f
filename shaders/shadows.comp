#version 460
#extension GL_GOOGLE_include_directive : require
// Ray-traced shadows of the directional light: one any-hit ray per G-buffer pixel.
#include "common/traversal.glsl"
#include "common/dispatch_order.glsl"
#include "common/ray_offset.glsl"

// Compiled three ways (shaders/CMakeLists.txt): a compute shader walking the BVH (the default), the same
// with HP_RAY_QUERY (the driver's acceleration structure through a ray query), and as a ray-generation
// shader with HP_RT_PIPELINE (one launch per pixel, traceRayEXT). Only the invocation's pixel differs.
#ifndef HP_RT_PIPELINE
layout(local_size_x = 8, local_size_y = 8) in;
#endif

const float HP_FLT_MAX = 3.402823466e+38;

// Pixel p, invocation `local` of tile wg of a row of wgx tiles.
void hp_shadow_pixel(uvec2 wg, uint wgx, ivec2 p, uint local) {
  // A ragged edge is covered by rounding the dispatch up and skipping here (the study truncated it).
  if (p.x >= int(frame.extent.x) || p.y >= int(frame.extent.y)) return;
  HP_TRACE_BEGIN_AT(wg, wgx, rt.frame.w, local);
  uint pix = uint(p.y) * frame.extent.x + uint(p.x);
  HpStats st;
  st.nodes = 0u; st.tris = 0u;
  float lit = 1.0;
  RayDump dump;
  dump.origin_tmin = vec4(0.0); dump.dir_tmax = vec4(0.0); dump.hit = ivec4(-1, 0, 0, 0);
  float depth = texelFetch(g_depth, p, 0).r;
  // The depth, and the normal where the pixel is not background: one reservation for both.
  if (hp_is_background(depth)) {
    HP_REC_LOAD(HP_TBUF_GBUF_DEPTH, pix * 4u, 4u);
  } else {
    HP_REC_LOADS(2u, uvec4(HP_TBUF_GBUF_DEPTH, HP_TBUF_GBUF_NORMAL, 0u, 0u), uvec4(pix * 4u, pix * 8u, 0u, 0u),
                 uvec4(4u, 8u, 0u, 0u));
    vec3 n = normalize(texelFetch(g_normal_roughness, p, 0).xyz);
    vec3 pos = hp_world_position(p, depth);
    vec3 l = frame.light_dir.xyz;
    if (dot(n, l) <= 0.0) {
      lit = 0.0;  // the surface faces away from the light: in its own shadow, no ray needed
    } else {
      vec3 o = (HP_RT_FLAGS & HP_RT_ROBUST_OFFSET) != 0u ? hp_offset_gbuffer(p, depth, pos, n) : hp_offset_bias(pos, n, rt.shadow.x);
      HpRay r;
      if (hp_prepare(o, l, 0.0, HP_FLT_MAX, r)) {
        HpHit h = hp_trace(r, true, st);
        lit = h.slot < 0 ? 1.0 : 0.0;
        dump.hit = ivec4(h.slot, floatBitsToInt(h.t), 1, 0);  // slot: mapped to the scene index below
      }
      dump.origin_tmin = vec4(o, 0.0);
      dump.dir_tmax = vec4(l, HP_FLT_MAX);
    }
  }
  HP_REC_STORE(HP_TBUF_SHADOW_MASK, pix * 4u, 4u);
  imageStore(shadow_mask, p, vec4(lit));
  if ((HP_RT_FLAGS & HP_RT_DUMP_RAYS) != 0u) {
    // Debug output only: the slot -> scene lookup is not part of the pass's real work (nor traced).
    if (dump.hit.x >= 0) dump.hit.x = int(slot_scene[uint(dump.hit.x)]);
    shadow_dump[pix] = dump;
  }
  if ((HP_RT_FLAGS & HP_RT_COUNTERS) != 0u) {
    hp_counter_add(HP_COUNTER_SHADOW_RAYS, uint(dump.hit.z));
    hp_counter_add(HP_COUNTER_SHADOW_NODES, st.nodes);
    hp_counter_add(HP_COUNTER_SHADOW_TRIS, st.tris);
  }
}

void main() {
#ifdef HP_RT_PIPELINE
  hp_shadow_pixel(uvec2(0u), 0u, hp_launch_pixel(), 0u);  // dispatch_order.glsl
#else
#ifdef HP_TRACE
  if (hp_trace_sharing()) {  // the slice's tiles, each taken whole by one subgroup (dispatch_order.glsl)
    uint wgx = (frame.extent.x + 7u) / 8u;
    uvec2 wg;
    while (hp_next_shared_tile(wgx, wg)) {
      for (uint c = 0u; c < 64u; c += gl_SubgroupSize) {
        uint local = c + gl_SubgroupInvocationID;
        hp_shadow_pixel(wg, wgx, ivec2(wg * 8u + uvec2(local % 8u, local / 8u)), local);
      }
    }
    return;
  }
#endif
  uvec2 wg = hp_tile_workgroup();  // dispatch_order.glsl
  hp_shadow_pixel(wg, gl_NumWorkGroups.x, ivec2(wg * gl_WorkGroupSize.xy + gl_LocalInvocationID.xy),
                  gl_LocalInvocationIndex);
#endif
}
