#version 460
#extension GL_GOOGLE_include_directive : require
// Ray-traced reflections: for each reflective pixel of the (possibly reduced) reflection grid, the view
// ray reflected about a GGX-sampled microfacet normal, traced to the closest hit and shaded there.
#include "common/traversal.glsl"
#include "common/ray_offset.glsl"
#include "common/sampling.glsl"
#include "common/brdf.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

const float HP_FLT_MAX = 3.402823466e+38;

vec3 hit_normal(uint slot, float u, float v) {
  vec3 n0, n1, n2;
  if (HP_GEOMETRY_SOUP != 0u) {
    HP_REC_LOAD(HP_TBUF_SOUP_NORMALS, slot * 36u, 12u);
    HP_REC_LOAD(HP_TBUF_SOUP_NORMALS, slot * 36u + 12u, 12u);
    HP_REC_LOAD(HP_TBUF_SOUP_NORMALS, slot * 36u + 24u, 12u);
    uint b = slot * 9u;
    n0 = vec3(soup_normals[b + 0u], soup_normals[b + 1u], soup_normals[b + 2u]);
    n1 = vec3(soup_normals[b + 3u], soup_normals[b + 4u], soup_normals[b + 5u]);
    n2 = vec3(soup_normals[b + 6u], soup_normals[b + 7u], soup_normals[b + 8u]);
  } else {
    uint i0 = indices[slot * 3u + 0u] * 3u;
    uint i1 = indices[slot * 3u + 1u] * 3u;
    uint i2 = indices[slot * 3u + 2u] * 3u;
    HP_REC_LOAD(HP_TBUF_INDICES, slot * 12u, 12u);
    HP_REC_LOAD(HP_TBUF_NORMALS, i0 * 4u, 12u);  // i0 is already a float index (vertex * 3)
    HP_REC_LOAD(HP_TBUF_NORMALS, i1 * 4u, 12u);
    HP_REC_LOAD(HP_TBUF_NORMALS, i2 * 4u, 12u);
    n0 = vec3(normals[i0], normals[i0 + 1u], normals[i0 + 2u]);
    n1 = vec3(normals[i1], normals[i1 + 1u], normals[i1 + 2u]);
    n2 = vec3(normals[i2], normals[i2 + 1u], normals[i2 + 2u]);
  }
  vec3 n = (1.0 - u - v) * n0 + u * n1 + v * n2;
  float len2 = dot(n, n);
  return len2 > 0.0 ? n * inversesqrt(len2) : vec3(0.0, 1.0, 0.0);
}

void main() {
  // rt.frame.z offsets the workgroup rows when a traced pass is dispatched in slices (0 otherwise).
  uvec2 wg = gl_WorkGroupID.xy + uvec2(0u, rt.frame.z);
  ivec2 q = ivec2(wg * gl_WorkGroupSize.xy + gl_LocalInvocationID.xy);
  if (q.x >= int(rt.grid.x) || q.y >= int(rt.grid.y)) return;
  HP_TRACE_BEGIN(wg, gl_NumWorkGroups.x, rt.frame.w);
  uint cell = uint(q.y) * rt.grid.x + uint(q.x);
  int s = int(rt.grid.z);
  // The full-resolution pixel at the centre of this grid cell (clamped on a ragged edge).
  ivec2 p = min(q * s + s / 2, ivec2(frame.extent.xy) - 1);
  HpStats st;
  st.nodes = 0u; st.tris = 0u;
  uint shadow_rays = 0u;
  RayDump dump;
  dump.origin_tmin = vec4(0.0); dump.dir_tmax = vec4(0.0); dump.hit = ivec4(-1, 0, 0, 0);
  vec4 result = vec4(0.0);  // alpha 0: not a reflective pixel
  uint pix = uint(p.y) * frame.extent.x + uint(p.x);
  HP_REC_LOAD(HP_TBUF_GBUF_DEPTH, pix * 4u, 4u);
  HP_REC_LOAD(HP_TBUF_GBUF_NORMAL, pix * 8u, 8u);
  float depth = texelFetch(g_depth, p, 0).r;
  vec4 nr = texelFetch(g_normal_roughness, p, 0);
  if (!hp_is_background(depth) && nr.a < rt.reflection.x) {
    vec3 n = normalize(nr.xyz);
    vec3 pos = hp_world_position(p, depth);
    vec3 v = normalize(frame.camera_pos.xyz - pos);
    vec2 xi;
    if (int(rt.reflection.y) == HP_JITTER_SHARED) {
      xi = rt.jitter.xy;  // one offset for every thread this frame (the study's scenario 1)
    } else {
      // Per thread: the Halton point of this frame, rotated per pixel (Cranley-Patterson) so that
      // neighbours decorrelate while each pixel keeps a low-discrepancy sequence over frames.
      uint h = hp_hash(cell ^ hp_hash(rt.frame.y));
      vec2 rot = vec2(float(h & 0xFFFFu), float(h >> 16)) / 65536.0;
      xi = fract(vec2(hp_halton2(rt.frame.x + 1u), hp_halton3(rt.frame.x + 1u)) + rot);
    }
    vec3 d = reflect(-v, n);
    if (nr.a > 0.0) {
      vec3 hv = hp_sample_ggx(n, nr.a, xi);
      vec3 dj = reflect(-v, hv);
      if (dot(dj, n) > 0.0) d = dj;  // a sample below the surface falls back to the mirror direction
    }
    vec3 o = int(rt.shadow.y) == HP_OFFSET_ROBUST ? hp_offset_robust(pos, n) : hp_offset_bias(pos, n, rt.shadow.x);
    HpRay r;
    vec3 color = frame.sky_color.rgb;
    if (hp_prepare(o, d, 0.0, HP_FLT_MAX, r)) {
      HpHit h = hp_trace(r, false, st);
      dump.hit = ivec4(h.slot, floatBitsToInt(h.t), 1, 0);  // slot: mapped to the scene index below
      if (h.slot >= 0) {
        uint slot = uint(h.slot);
        HP_REC_LOAD(HP_TBUF_SLOT_MATERIAL, slot * 4u, 4u);
        uint mi = slot_material[slot];
        HP_REC_LOAD(HP_TBUF_MATERIALS, mi * 32u, 16u);
        HP_REC_LOAD(HP_TBUF_MATERIALS, mi * 32u + 16u, 16u);
        GpuMaterial m = materials[mi];
        vec3 hn = hit_normal(slot, h.u, h.v);
        if (dot(hn, d) > 0.0) hn = -hn;
        vec3 hp = o + h.t * d;
        vec3 l = frame.light_dir.xyz;
        float vis = 1.0;
        if ((rt.grid.w & HP_RT_REFLECTION_SHADOWS) != 0u && dot(hn, l) > 0.0) {
          vec3 so = int(rt.shadow.y) == HP_OFFSET_ROBUST ? hp_offset_robust(hp, hn) : hp_offset_bias(hp, hn, rt.shadow.x);
          HpRay sr;
          if (hp_prepare(so, l, 0.0, HP_FLT_MAX, sr)) {
            HpHit sh = hp_trace(sr, true, st);
            vis = sh.slot < 0 ? 1.0 : 0.0;
            shadow_rays++;
          }
        }
        vec3 light = frame.light_color.rgb * frame.light_dir.w;
        // The hit's specular lobe is widened to roughness >= 0.25: a one-sample reflection ray that lands on a
        // near-mirror's highlight would otherwise return radiance ~1e6 (GGX D peaks at 1 / (pi a^2)), and
        // such fireflies need thousands of frames to average out.
        float hit_rough = max(m.roughness.x, 0.25);
        color = vis * shade_direct(hn, -d, l, m.base_color_metallic.rgb, m.base_color_metallic.a, hit_rough, light) +
                shade_ambient(hn, -d, m.base_color_metallic.rgb, m.base_color_metallic.a, frame.sky_color.rgb);
      }
    }
    dump.origin_tmin = vec4(o, 0.0);
    dump.dir_tmax = vec4(d, HP_FLT_MAX);
    result = vec4(color, 1.0);
  }
  HP_REC_STORE(HP_TBUF_REFLECTION, cell * 16u, 16u);
  imageStore(reflection_image, q, result);
  if ((rt.grid.w & HP_RT_DUMP_RAYS) != 0u) {
    // Debug output only: the slot -> scene lookup is not part of the pass's real work (nor traced).
    if (dump.hit.x >= 0) dump.hit.x = int(slot_scene[uint(dump.hit.x)]);
    reflection_dump[cell] = dump;
  }
  if ((rt.grid.w & HP_RT_COUNTERS) != 0u) {
    hp_counter_add(HP_COUNTER_REFL_RAYS, uint(dump.hit.z));
    hp_counter_add(HP_COUNTER_REFL_NODES, st.nodes);
    hp_counter_add(HP_COUNTER_REFL_TRIS, st.tris);
    hp_counter_add(HP_COUNTER_REFL_SHADOW_RAYS, shadow_rays);
  }
}
