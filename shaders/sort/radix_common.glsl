// Declarations shared by the radix sort kernels. Every kernel uses the same descriptor set layout so the
// host can build two sets (caller -> scratch and scratch -> caller) and bind either with any pipeline.
#ifndef HP_SORT_RADIX_COMMON_GLSL
#define HP_SORT_RADIX_COMMON_GLSL

#include "gpu/radix_config.h"
#include "gpu/bindings.h"
#include "common/trace_capture.glsl"

layout(push_constant) uniform RadixPush {
  uint shift;        // first key bit of this pass's digit
  uint capacity;     // elements the buffers hold; the live count is clamped to it
  uint key_mask;     // the caller's significant key bits: a last pass that straddles them ignores the rest
  uint first_group;  // the block of this dispatch's first workgroup (a traced slice; 0 otherwise)
  uint sampling;     // the traced variants' workgroup sampling (HP_TRACE_BEGIN)
  uint to_caller;    // the bound set reads the scratch buffers and writes the caller's (trace buffer ids)
} pc;

layout(set = 0, binding = HP_BIND_SORT_KEYS_IN, std430) readonly buffer KeysIn { uint keys_in[]; };
layout(set = 0, binding = HP_BIND_SORT_VALUES_IN, std430) readonly buffer ValuesIn { uint values_in[]; };
layout(set = 0, binding = HP_BIND_SORT_KEYS_OUT, std430) writeonly buffer KeysOut { uint keys_out[]; };
layout(set = 0, binding = HP_BIND_SORT_VALUES_OUT, std430) writeonly buffer ValuesOut { uint values_out[]; };
// Per block, RADIX_DIGITS counters (block-major: [block][digit]); the scan turns them into global
// output offsets in place.
layout(set = 0, binding = HP_BIND_SORT_HISTOGRAMS, std430) buffer Histograms { uint histograms[]; };
// The live element count, written by the GPU (an atomic counter) or the host; read by every kernel so the
// dispatches can be sized for the capacity without a CPU readback.
layout(set = 0, binding = HP_BIND_SORT_COUNT, std430) readonly buffer Count { uint live_count; };

// The workgroup's block in the whole dispatch (a traced slice starts at first_group). RADIX_TRACE_BEGIN
// starts the traced variants' recording; a macro, since it needs gl_WorkGroupSize, which a kernel may use
// only after its local_size declaration.
#define RADIX_GROUP (gl_WorkGroupID.x + pc.first_group)
#define RADIX_TRACE_BEGIN() HP_TRACE_BEGIN(uvec2(RADIX_GROUP, 0u), 1u, pc.sampling)
// Buffer ids for the records: which of the caller's and the scratch buffers the set binds where.
uint hp_sort_keys_in() { return pc.to_caller != 0u ? HP_TBUF_SORT_SCRATCH_KEYS : HP_TBUF_SORT_KEYS; }
uint hp_sort_values_in() { return pc.to_caller != 0u ? HP_TBUF_SORT_SCRATCH_VALUES : HP_TBUF_SORT_VALUES; }
uint hp_sort_keys_out() { return pc.to_caller != 0u ? HP_TBUF_SORT_KEYS : HP_TBUF_SORT_SCRATCH_KEYS; }
uint hp_sort_values_out() { return pc.to_caller != 0u ? HP_TBUF_SORT_VALUES : HP_TBUF_SORT_SCRATCH_VALUES; }

uint radix_count() {
  HP_REC_LOAD(HP_TBUF_RAY_COUNT, 0u, 4u);
  return min(live_count, pc.capacity);
}
uint radix_blocks(uint n) { return (n + RADIX_BLOCK - 1u) / RADIX_BLOCK; }
uint radix_digit(uint key) { return ((key & pc.key_mask) >> pc.shift) & (RADIX_DIGITS - 1u); }

#endif
