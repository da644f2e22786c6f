#version 460
#extension GL_GOOGLE_include_directive : require
// The passes' one traversal on its own: one thread per ray of a buffer, closest or any hit, no ray
// generation and no shading. Tests check it against the C++ reference on arbitrary rays (hard cases
// included); the frame benchmark times it on the rays a pass cast.
#include "common/traversal.glsl"
#include "common/dispatch_order.glsl"
#include "gpu/bindings.h"

// Compiled as a compute shader (BVH traversal, or HP_RAY_QUERY) and as a ray-generation shader
// (HP_RT_PIPELINE: launched over groups_x * 64 x groups_y invocations, the compute dispatch's), as
// shadows.comp is.
#ifndef HP_RT_PIPELINE
layout(local_size_x = 64) in;  // HP_TRAVERSAL_MAX_GROUP: the traversal stack's shared columns
#endif

// A BatchRay is two RGBA32UI texels: on lavapipe an image load is one call for the eight lanes, a
// storage-buffer load at a per-invocation address a loop over the lanes (RayBatchTracer).
layout(set = 0, binding = HP_BIND_BATCH_RAYS, rgba32ui) uniform readonly uimageBuffer batch_rays;
layout(std430, set = 0, binding = HP_BIND_BATCH_RESULTS) writeonly buffer BatchResults { BatchResult batch_results[]; };
layout(push_constant) uniform BatchParams {
  uint count;
  uint any_hit;
  uint groups_x;  // the dispatch's width in workgroups (it is 2D past the device's per-axis limit)
} batch;

void main() {
#ifdef HP_RT_PIPELINE
  // The compute dispatch's rays per launch index, groups of 64 in the same spread order.
  uint width = batch.groups_x * 64u;
  uint i = hp_spread_blocks(gl_LaunchIDEXT.y * width + gl_LaunchIDEXT.x, width * gl_LaunchSizeEXT.y, 64u);
#else
  // The groups take their rays in spread order (dispatch_order.glsl).
  uint group = hp_spread(gl_WorkGroupID.y * batch.groups_x + gl_WorkGroupID.x, batch.groups_x * gl_NumWorkGroups.y);
  uint i = group * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
#endif
  if (i >= batch.count) return;
  BatchRay ray;
  ray.origin_tmin = uintBitsToFloat(imageLoad(batch_rays, int(2u * i)));
  ray.dir_tmax = uintBitsToFloat(imageLoad(batch_rays, int(2u * i + 1u)));
  BatchResult res;
  res.hit = ivec4(-1, 0, 0, 0);
  res.work = uvec4(0u);
  HpRay r;
  if (hp_prepare(ray.origin_tmin.xyz, ray.dir_tmax.xyz, ray.origin_tmin.w, ray.dir_tmax.w, r)) {
    HpStats st;
    st.nodes = 0u; st.tris = 0u;
    HpHit h = hp_trace(r, batch.any_hit != 0u, st);
    if (h.slot >= 0) {
      res.hit = ivec4(int(slot_scene[uint(h.slot)]), floatBitsToInt(h.t), floatBitsToInt(h.u), floatBitsToInt(h.v));
    }
    res.work = uvec4(st.nodes, st.tris, 0u, 0u);
  }
  batch_results[i] = res;
}
