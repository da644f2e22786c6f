#version 460
#extension GL_GOOGLE_include_directive : require
#include "sort/radix_common.glsl"

// Pass 1 of 3: the digit histogram of one block of RADIX_BLOCK elements. The dispatch covers the
// capacity; blocks past the live count leave at once (the whole workgroup, so no barrier is skipped by
// part of it).
layout(local_size_x = RADIX_THREADS) in;

shared uint s_hist[RADIX_DIGITS];

void main() {
  RADIX_TRACE_BEGIN();
  const uint block = RADIX_GROUP;
  const uint n = radix_count();
  if (block >= radix_blocks(n)) return;
  const uint t = gl_LocalInvocationID.x;
  if (t < RADIX_DIGITS) s_hist[t] = 0u;
  memoryBarrierShared();
  barrier();
  // Order does not matter for a count, so read with the thread index fastest (coalesced).
  const uint base = block * RADIX_BLOCK;
  for (uint i = 0u; i < RADIX_ITEMS; ++i) {
    const uint idx = base + i * RADIX_THREADS + t;
    if (idx < n) {
      HP_REC_LOAD(hp_sort_keys_in(), idx * 4u, 4u);
      atomicAdd(s_hist[radix_digit(keys_in[idx])], 1u);
    }
  }
  memoryBarrierShared();
  barrier();
  if (t < RADIX_DIGITS) {
    HP_REC_STORE(HP_TBUF_SORT_HISTOGRAMS, (block * RADIX_DIGITS + t) * 4u, 4u);
    histograms[block * RADIX_DIGITS + t] = s_hist[t];
  }
}
