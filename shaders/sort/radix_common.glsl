// Declarations shared by the radix sort kernels. Every kernel uses the same descriptor set layout so the
// host can build two sets (caller -> scratch and scratch -> caller) and bind either with any pipeline.
#ifndef HP_SORT_RADIX_COMMON_GLSL
#define HP_SORT_RADIX_COMMON_GLSL

#include "sort/radix_config.h"

layout(push_constant) uniform RadixPush {
  uint shift;     // first key bit of this pass's digit
  uint capacity;  // elements the buffers hold; the live count is clamped to it
  uint key_mask;  // the caller's significant key bits: a last pass that straddles them ignores the rest
} pc;

layout(set = 0, binding = 0, std430) readonly buffer KeysIn { uint keys_in[]; };
layout(set = 0, binding = 1, std430) readonly buffer ValuesIn { uint values_in[]; };
layout(set = 0, binding = 2, std430) writeonly buffer KeysOut { uint keys_out[]; };
layout(set = 0, binding = 3, std430) writeonly buffer ValuesOut { uint values_out[]; };
// Per block, RADIX_DIGITS counters (block-major: [block][digit]); the scan turns them into global
// output offsets in place.
layout(set = 0, binding = 4, std430) buffer Histograms { uint histograms[]; };
// The live element count, written by the GPU (an atomic counter) or the host; read by every kernel so the
// dispatches can be sized for the capacity without a CPU readback.
layout(set = 0, binding = 5, std430) readonly buffer Count { uint live_count; };

uint radix_count() { return min(live_count, pc.capacity); }
uint radix_blocks(uint n) { return (n + RADIX_BLOCK - 1u) / RADIX_BLOCK; }
uint radix_digit(uint key) { return ((key & pc.key_mask) >> pc.shift) & (RADIX_DIGITS - 1u); }

#endif
