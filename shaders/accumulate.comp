#version 460
#extension GL_GOOGLE_include_directive : require
// Temporal accumulation of the reflection buffer: a running mean over the frames since the last reset
// (the host resets the sample index when the camera or the light changes).
#include "common/rt_bindings.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
  ivec2 q = ivec2(gl_GlobalInvocationID.xy);
  if (q.x >= int(rt.grid.x) || q.y >= int(rt.grid.y)) return;
  vec4 cur = imageLoad(reflection_image, q);
  uint n = rt.frame.x;  // samples already in the mean
  vec4 acc = n == 0u ? cur : imageLoad(reflection_accum, q);
  acc += (cur - acc) / float(n + 1u);
  imageStore(reflection_accum, q, acc);
}
