// Reflection ray generation and hit shading, shared by the direct reflection pass and the compaction path
// (compact.comp generates the rays, consume.comp traces and shades them), so every path casts the same
// rays and shades them the same way.
#ifndef HP_REFLECTION_COMMON_GLSL
#define HP_REFLECTION_COMMON_GLSL

#include "common/traversal.glsl"
#include "gpu/bindings.h"
#include "common/ray_offset.glsl"
#include "common/sampling.glsl"
#include "common/brdf.glsl"

const float HP_FLT_MAX = 3.402823466e+38;

// The shading data seen as texels (RtScene::geometry_texels), like the positions: normals as R32G32B32A32_UINT,
// material ids and materials.
layout(set = 0, binding = HP_BIND_RT_NORMAL_TEXELS) uniform utextureBuffer normal_texels;
layout(set = 0, binding = HP_BIND_RT_SOUP_NORMAL_TEXELS) uniform utextureBuffer soup_normal_texels;
layout(set = 0, binding = HP_BIND_RT_SLOT_MATERIAL_TEXELS) uniform utextureBuffer slot_material_texels;  // R32_UINT
layout(set = 0, binding = HP_BIND_RT_MATERIAL_TEXELS) uniform utextureBuffer material_texels;

vec3 hit_normal(uint slot, float u, float v) {
  vec3 n0, n1, n2;
  if (HP_GEOMETRY_SOUP != 0u) {
    HP_REC_LOADS(3u, HP_TBUF_SOUP_NORMALS, slot * 36u + uvec4(0u, 12u, 24u, 0u), 12u);
    uint b = slot * 9u;
    if (HP_GEOMETRY_TEXELS != 0u) {
      n0 = uintBitsToFloat(texelFetch(soup_normal_texels, int(slot * 3u)).xyz);
      n1 = uintBitsToFloat(texelFetch(soup_normal_texels, int(slot * 3u + 1u)).xyz);
      n2 = uintBitsToFloat(texelFetch(soup_normal_texels, int(slot * 3u + 2u)).xyz);
    } else {
      n0 = vec3(soup_normals[b + 0u], soup_normals[b + 1u], soup_normals[b + 2u]);
      n1 = vec3(soup_normals[b + 3u], soup_normals[b + 4u], soup_normals[b + 5u]);
      n2 = vec3(soup_normals[b + 6u], soup_normals[b + 7u], soup_normals[b + 8u]);
    }
  } else {
    uvec3 vi = hp_slot_indices(slot);  // as the traversal reads them (a texel where it can)
    uint i0 = vi.x * 3u, i1 = vi.y * 3u, i2 = vi.z * 3u;
    // i0..i2 are already float indices (vertex * 3)
    HP_REC_LOADS(4u, uvec4(HP_TBUF_INDICES, HP_TBUF_NORMALS, HP_TBUF_NORMALS, HP_TBUF_NORMALS),
                 uvec4(slot * 12u, uvec3(i0, i1, i2) * 4u), 12u);
    if (HP_GEOMETRY_TEXELS != 0u) {
      n0 = uintBitsToFloat(texelFetch(normal_texels, int(vi.x)).xyz);
      n1 = uintBitsToFloat(texelFetch(normal_texels, int(vi.y)).xyz);
      n2 = uintBitsToFloat(texelFetch(normal_texels, int(vi.z)).xyz);
    } else {
      n0 = vec3(normals[i0], normals[i0 + 1u], normals[i0 + 2u]);
      n1 = vec3(normals[i1], normals[i1 + 1u], normals[i1 + 2u]);
      n2 = vec3(normals[i2], normals[i2 + 1u], normals[i2 + 2u]);
    }
  }
  vec3 n = (1.0 - u - v) * n0 + u * n1 + v * n2;
  float len2 = dot(n, n);
  return len2 > 0.0 ? n * inversesqrt(len2) : vec3(0.0, 1.0, 0.0);
}


// The reflection ray of grid cell q (its full-resolution pixel at the cell centre); false for a
// background or non-reflective pixel.
bool hp_reflection_ray(ivec2 q, uint cell, out vec3 o, out vec3 d) {
  o = vec3(0.0);
  d = vec3(0.0);
  int s = int(rt.grid.z);
  ivec2 p = min(q * s + s / 2, ivec2(frame.extent.xy) - 1);
  uint pix = uint(p.y) * frame.extent.x + uint(p.x);
  HP_REC_LOADS(2u, uvec4(HP_TBUF_GBUF_DEPTH, HP_TBUF_GBUF_NORMAL, 0u, 0u), uvec4(pix * 4u, pix * 8u, 0u, 0u),
               uvec4(4u, 8u, 0u, 0u));
  float depth = texelFetch(g_depth, p, 0).r;
  vec4 nr = texelFetch(g_normal_roughness, p, 0);
  if (hp_is_background(depth) || !(nr.a < rt.reflection.x)) return false;
  precise vec3 n = normalize(nr.xyz);
  vec3 pos = hp_world_position(p, depth);
  precise vec3 v = normalize(frame.camera_pos.xyz - pos);
  vec2 xi;
  if ((HP_RT_FLAGS & HP_RT_SHARED_JITTER) != 0u) {
    xi = rt.jitter.xy;  // one offset for every thread this frame (the study's scenario 1)
  } else {
    // Per thread: the Halton point of this frame, rotated per pixel (Cranley-Patterson) so that
    // neighbours decorrelate while each pixel keeps a low-discrepancy sequence over frames.
    uint h = hp_hash(cell ^ hp_hash(rt.frame.y));
    vec2 rot = vec2(float(h & 0xFFFFu), float(h >> 16)) / 65536.0;
    xi = fract(vec2(hp_halton2(rt.frame.x + 1u), hp_halton3(rt.frame.x + 1u)) + rot);
  }
  precise vec3 mirror = reflect(-v, n);
  d = mirror;
  if (nr.a > 0.0) {
    precise vec3 hv = hp_sample_ggx(n, nr.a, xi);
    precise vec3 dj = reflect(-v, hv);
    if (dot(dj, n) > 0.0) d = dj;  // a sample below the surface falls back to the mirror direction
  }
  o = (HP_RT_FLAGS & HP_RT_ROBUST_OFFSET) != 0u ? hp_offset_gbuffer(p, depth, pos, n) : hp_offset_bias(pos, n, rt.shadow.x);
  return true;
}

// Traces the reflection ray (o, d) to its closest hit and shades it (material x direct light with an
// optional shadow ray, plus ambient); the sky on a miss. `was_cast` is false when the ray is invalid.
vec3 hp_shade_reflection(vec3 o, vec3 d, inout HpStats st, inout uint shadow_rays, out HpHit h, out bool was_cast) {
  h = hp_no_hit();
  was_cast = false;
  vec3 color = frame.sky_color.rgb;
  HpRay r;
  if (!hp_prepare(o, d, 0.0, HP_FLT_MAX, r)) return color;
  was_cast = true;
  h = hp_trace(r, false, st);
  if (h.slot < 0) return color;
  uint slot = uint(h.slot);
  HP_REC_LOAD(HP_TBUF_SLOT_MATERIAL, slot * 4u, 4u);
  uint mi;
  GpuMaterial m;
  if (HP_GEOMETRY_TEXELS != 0u) {
    mi = texelFetch(slot_material_texels, int(slot)).x;
    m.base_color_metallic = uintBitsToFloat(texelFetch(material_texels, int(mi * 2u)));
    m.roughness = uintBitsToFloat(texelFetch(material_texels, int(mi * 2u + 1u)));
  } else {
    mi = slot_material[slot];
    m = materials[mi];
  }
  HP_REC_LOADS(2u, HP_TBUF_MATERIALS, mi * 32u + uvec4(0u, 16u, 0u, 0u), 16u);
  vec3 hn = hit_normal(slot, h.u, h.v);
  if (dot(hn, d) > 0.0) hn = -hn;
  precise vec3 hp = o + h.t * d;  // the shadow ray's origin: identical in every path (no FMA)
  vec3 l = frame.light_dir.xyz;
  float vis = 1.0;
  if ((HP_RT_FLAGS & HP_RT_REFLECTION_SHADOWS) != 0u && dot(hn, l) > 0.0) {
    vec3 so = (HP_RT_FLAGS & HP_RT_ROBUST_OFFSET) != 0u ? hp_offset_robust(hp, hn) : hp_offset_bias(hp, hn, rt.shadow.x);
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
  return vis * shade_direct(hn, -d, l, m.base_color_metallic.rgb, m.base_color_metallic.a, hit_rough, light) +
         shade_ambient(hn, -d, m.base_color_metallic.rgb, m.base_color_metallic.a, frame.sky_color.rgb);
}

// Adds one reflection ray's work to the counters (HP_RT_COUNTERS).
void hp_count_reflection(bool was_cast, HpStats st, uint shadow_rays) {
  if ((HP_RT_FLAGS & HP_RT_COUNTERS) == 0u) return;
  hp_counter_add(HP_COUNTER_REFL_RAYS, was_cast ? 1u : 0u);
  hp_counter_add(HP_COUNTER_REFL_NODES, st.nodes);
  hp_counter_add(HP_COUNTER_REFL_TRIS, st.tris);
  hp_counter_add(HP_COUNTER_REFL_SHADOW_RAYS, shadow_rays);
}

#endif
