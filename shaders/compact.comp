#version 460
#extension GL_GOOGLE_include_directive : require
// Ray compaction: one thread per reflection-grid cell appends the cell's reflection ray (the very ray the
// direct pass would trace) and its sort key. No ray is dropped and no count goes back to the CPU: the
// consume pass is sized on the GPU (args.comp, vkCmdDispatchIndirect).
#include "common/reflection_common.glsl"
#include "common/compaction.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// Spreads the low 10 bits of x so that two zero bits separate each (for a 3D Morton code).
uint hp_spread3(uint x) {
  x &= 0x3FFu;
  x = (x | (x << 16)) & 0x030000FFu;
  x = (x | (x << 8)) & 0x0300F00Fu;
  x = (x | (x << 4)) & 0x030C30C3u;
  x = (x | (x << 2)) & 0x09249249u;
  return x;
}
// Spreads the low 16 bits of x with one zero bit between each (2D Morton code).
uint hp_spread2(uint x) {
  x &= 0xFFFFu;
  x = (x | (x << 8)) & 0x00FF00FFu;
  x = (x | (x << 4)) & 0x0F0F0F0Fu;
  x = (x | (x << 2)) & 0x33333333u;
  x = (x | (x << 1)) & 0x55555555u;
  return x;
}

uint sort_key(vec3 o, vec3 d, int mode) {
  if (mode == HP_SORT_OCTANT) {
    return (d.x < 0.0 ? 1u : 0u) | (d.y < 0.0 ? 2u : 0u) | (d.z < 0.0 ? 4u : 0u);
  }
  if (mode == HP_SORT_DIRECTION) {
    // Octahedral map of the direction to [0, 1]^2, 10 bits per axis, Morton order (20 bits).
    vec3 n = d / (abs(d.x) + abs(d.y) + abs(d.z));
    vec2 e = n.z >= 0.0 ? n.xy : (1.0 - abs(n.yx)) * vec2(n.x >= 0.0 ? 1.0 : -1.0, n.y >= 0.0 ? 1.0 : -1.0);
    uvec2 qd = uvec2(clamp(e * 0.5 + 0.5, 0.0, 1.0) * 1023.0);
    return hp_spread2(qd.x) | (hp_spread2(qd.y) << 1);
  }
  if (mode == HP_SORT_ORIGIN) {
    // Origin quantized to 10 bits per axis inside the scene bounds, Morton order (30 bits).
    vec3 ext = max(rt.bounds_max.xyz - rt.bounds_min.xyz, vec3(1e-30));
    uvec3 qo = uvec3(clamp((o - rt.bounds_min.xyz) / ext, 0.0, 1.0) * 1023.0);
    return hp_spread3(qo.x) | (hp_spread3(qo.y) << 1) | (hp_spread3(qo.z) << 2);
  }
  return 0u;
}

void main() {
  // rt.frame.z offsets the workgroup rows when the traced variant is dispatched in slices (0 otherwise).
  uvec2 wg = gl_WorkGroupID.xy + uvec2(0u, rt.frame.z);
  ivec2 q = ivec2(wg * gl_WorkGroupSize.xy + gl_LocalInvocationID.xy);
  if (q.x >= int(rt.grid.x) || q.y >= int(rt.grid.y)) return;
  HP_TRACE_BEGIN(wg, gl_NumWorkGroups.x, rt.frame.w);
  uint cell = uint(q.y) * rt.grid.x + uint(q.x);
  // Cleared here; the consume pass writes the reflective cells.
  HP_REC_STORE(HP_TBUF_REFLECTION, cell * 16u, 16u);
  imageStore(reflection_image, q, vec4(0.0));
  vec3 o, d;
  if (!hp_reflection_ray(q, cell, o, d)) return;
  HP_REC_ATOMIC(HP_TBUF_RAY_COUNT, 0u, 4u);
  uint i = atomicAdd(ray_count, 1u);
  HP_REC_STORE(HP_TBUF_COMPACT_RAYS, i * 32u, 16u);
  HP_REC_STORE(HP_TBUF_COMPACT_RAYS, i * 32u + 16u, 16u);
  compact_rays[i] = CompactRay(vec4(o, uintBitsToFloat(cell)), vec4(d, 0.0));
  HP_REC_STORE(HP_TBUF_SORT_KEYS, i * 4u, 4u);
  sort_keys[i] = sort_key(o, d, int(rt.bounds_min.w));
  HP_REC_STORE(HP_TBUF_SORT_VALUES, i * 4u, 4u);
  sort_values[i] = i;
}
