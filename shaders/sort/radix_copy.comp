#version 460
#extension GL_GOOGLE_include_directive : require
#include "sort/radix_common.glsl"

// After an odd number of passes the sorted pairs sit in the scratch buffers; this copies the live
// elements (and only those: the count comes from the GPU) back into the caller's buffers.
layout(local_size_x = RADIX_THREADS) in;

void main() {
  RADIX_TRACE_BEGIN();
  const uint base = RADIX_GROUP * RADIX_BLOCK;
  const uint n = radix_count();
  for (uint i = 0u; i < RADIX_ITEMS; ++i) {
    const uint idx = base + i * RADIX_THREADS + gl_LocalInvocationID.x;
    if (idx < n) {
      HP_REC_LOAD(hp_sort_keys_in(), idx * 4u, 4u);
      HP_REC_STORE(hp_sort_keys_out(), idx * 4u, 4u);
      keys_out[idx] = keys_in[idx];
      HP_REC_LOAD(hp_sort_values_in(), idx * 4u, 4u);
      HP_REC_STORE(hp_sort_values_out(), idx * 4u, 4u);
      values_out[idx] = values_in[idx];
    }
  }
}
