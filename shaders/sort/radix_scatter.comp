#version 460
#extension GL_GOOGLE_include_directive : require
#include "sort/radix_common.glsl"

// Pass 3 of 3: stable scatter of one block. Thread t owns the RADIX_ITEMS consecutive elements
// [t * RADIX_ITEMS, (t + 1) * RADIX_ITEMS) of its block, so "earlier in the input" is "lower thread, or
// same thread and earlier in its loop". Each thread counts its digits into its own column of s_cnt
// ([digit][thread]); an exclusive scan of s_cnt in digit-major order then gives every (digit, thread)
// the block-local sorted position of its first element with that digit; the thread walks its elements
// again in order and bumps its own counters. No subgroup operation is used, so the ranking does not
// depend on the subgroup size (8 on lavapipe, 32 on NVIDIA).
layout(local_size_x = RADIX_THREADS) in;

#define CELLS (RADIX_DIGITS * RADIX_THREADS)
#define CELLS_PER_THREAD (CELLS / RADIX_THREADS)

#define GROUP_SIZE 16u
#define GROUPS (RADIX_THREADS / GROUP_SIZE)

shared uint s_cnt[CELLS];          // [digit][thread], 16 KiB
shared uint s_sum[RADIX_THREADS];  // per-thread partial sums for the block-wide scan
shared uint s_group[GROUPS];       // their sums per group of GROUP_SIZE threads
shared uint s_base[RADIX_DIGITS];  // global offset of the digit minus its block-local start

void main() {
  RADIX_TRACE_BEGIN();
  const uint block = RADIX_GROUP;
  const uint n = radix_count();
  if (block >= radix_blocks(n)) return;
  const uint t = gl_LocalInvocationID.x;
  const uint first = block * RADIX_BLOCK + t * RADIX_ITEMS;
  const uint last = min(first + RADIX_ITEMS, n);  // first may be past n: an empty range

  for (uint d = 0u; d < RADIX_DIGITS; ++d) s_cnt[d * RADIX_THREADS + t] = 0u;
  // Only thread t touches column t here, so plain increments suffice.
  for (uint i = first; i < last; ++i) {
    HP_REC_LOAD(hp_sort_keys_in(), i * 4u, 4u);
    s_cnt[radix_digit(keys_in[i]) * RADIX_THREADS + t] += 1u;
  }
  memoryBarrierShared();
  barrier();

  // Block-wide exclusive scan of the CELLS counters in digit-major order: each thread scans
  // CELLS_PER_THREAD consecutive cells; the 256 per-thread totals are scanned in two levels (16 threads
  // each scan 16 totals, then one thread scans the 16 group sums), three barriers instead of the 16 of a
  // Hillis-Steele scan: barriers are what a CPU implementation (lavapipe) pays for most.
  const uint c0 = t * CELLS_PER_THREAD;
  uint total = 0u;
  for (uint k = 0u; k < CELLS_PER_THREAD; ++k) total += s_cnt[c0 + k];
  s_sum[t] = total;
  memoryBarrierShared();
  barrier();
  if (t < GROUPS) {
    uint acc = 0u;
    for (uint k = 0u; k < GROUP_SIZE; ++k) {
      acc += s_sum[t * GROUP_SIZE + k];
      s_sum[t * GROUP_SIZE + k] = acc;  // inclusive within the group
    }
    s_group[t] = acc;
  }
  memoryBarrierShared();
  barrier();
  if (t == 0u) {
    uint acc = 0u;
    for (uint g = 0u; g < GROUPS; ++g) {
      const uint c = s_group[g];
      s_group[g] = acc;  // exclusive over groups
      acc += c;
    }
  }
  memoryBarrierShared();
  barrier();
  uint run = s_group[t / GROUP_SIZE] + s_sum[t] - total;  // exclusive
  for (uint k = 0u; k < CELLS_PER_THREAD; ++k) {
    const uint c = s_cnt[c0 + k];
    s_cnt[c0 + k] = run;
    run += c;
  }
  memoryBarrierShared();
  barrier();
  // s_cnt[d][0] is where digit d starts inside the block; the output index of an element is
  // global_offset[block][d] + (its block-local position - that start). Read before thread 0 bumps it.
  if (t < RADIX_DIGITS) {
    HP_REC_LOAD(HP_TBUF_SORT_HISTOGRAMS, (block * RADIX_DIGITS + t) * 4u, 4u);
    s_base[t] = histograms[block * RADIX_DIGITS + t] - s_cnt[t * RADIX_THREADS];
  }
  memoryBarrierShared();
  barrier();

  for (uint i = first; i < last; ++i) {
    HP_REC_LOAD(hp_sort_keys_in(), i * 4u, 4u);
    const uint key = keys_in[i];
    const uint cell = radix_digit(key) * RADIX_THREADS + t;
    const uint pos = s_cnt[cell];
    s_cnt[cell] = pos + 1u;
    const uint dst = s_base[radix_digit(key)] + pos;  // unsigned wrap-around cancels exactly
    HP_REC_STORE(hp_sort_keys_out(), dst * 4u, 4u);
    keys_out[dst] = key;
    HP_REC_LOAD(hp_sort_values_in(), i * 4u, 4u);
    HP_REC_STORE(hp_sort_values_out(), dst * 4u, 4u);
    values_out[dst] = values_in[i];
  }
}
