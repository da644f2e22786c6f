#version 460
#extension GL_GOOGLE_include_directive : require
#include "sort/radix_common.glsl"

// After an odd number of passes the sorted pairs sit in the scratch buffers; this copies the live
// elements (and only those: the count comes from the GPU) back into the caller's buffers.
layout(local_size_x = RADIX_THREADS) in;

void main() {
  const uint n = radix_count();
  const uint base = gl_WorkGroupID.x * RADIX_BLOCK;
  for (uint i = 0u; i < RADIX_ITEMS; ++i) {
    const uint idx = base + i * RADIX_THREADS + gl_LocalInvocationID.x;
    if (idx < n) {
      keys_out[idx] = keys_in[idx];
      values_out[idx] = values_in[idx];
    }
  }
}
