#version 460
#extension GL_GOOGLE_include_directive : require
#include "sort/radix_common.glsl"

// Pass 2 of 3: one workgroup turns the per-block histograms into each block's first output index for
// each digit: offset[b][d] = sum over d' < d of total(d') + sum over b' < b of hist[b'][d].
// 256 threads = 16 digits x 16 lanes; lane j of digit d owns a contiguous range of blocks, so block
// order (which is what keeps the sort stable across blocks) is preserved.
layout(local_size_x = RADIX_THREADS) in;

#define LANES (RADIX_THREADS / RADIX_DIGITS)

shared uint s_part[RADIX_THREADS];

void main() {
  RADIX_TRACE_BEGIN();
  const uint nb = radix_blocks(radix_count());
  const uint t = gl_LocalInvocationID.x;
  const uint d = t / LANES;
  const uint j = t % LANES;
  const uint per = (nb + LANES - 1u) / LANES;
  const uint b0 = min(j * per, nb);
  const uint b1 = min(b0 + per, nb);

  uint sum = 0u;
  for (uint b = b0; b < b1; ++b) {
    HP_REC_LOAD(HP_TBUF_SORT_HISTOGRAMS, (b * RADIX_DIGITS + d) * 4u, 4u);
    sum += histograms[b * RADIX_DIGITS + d];
  }
  s_part[t] = sum;  // t == d * LANES + j: digit-major, lanes in block order
  memoryBarrierShared();
  barrier();
  // 256 partial sums: one thread scans them (cheap next to the per-block work, and obviously ordered).
  if (t == 0u) {
    uint run = 0u;
    for (uint i = 0u; i < RADIX_THREADS; ++i) {
      const uint c = s_part[i];
      s_part[i] = run;
      run += c;
    }
  }
  memoryBarrierShared();
  barrier();
  uint run = s_part[t];
  for (uint b = b0; b < b1; ++b) {
    HP_REC_LOAD(HP_TBUF_SORT_HISTOGRAMS, (b * RADIX_DIGITS + d) * 4u, 4u);
    const uint c = histograms[b * RADIX_DIGITS + d];
    HP_REC_STORE(HP_TBUF_SORT_HISTOGRAMS, (b * RADIX_DIGITS + d) * 4u, 4u);
    histograms[b * RADIX_DIGITS + d] = run;
    run += c;
  }
}
