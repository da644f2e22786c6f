// Which tiles or rays a workgroup takes. lavapipe splits a dispatch of N workgroups into one contiguous
// block of about N/T workgroup indices per thread (T threads; llvmpipe's lp_cs_tpool), so with workgroups
// in image order one thread traces the top of the image and the other the bottom, and the dispatch lasts as
// long as the costlier block. hp_spread deals every such block out over the whole image instead. A GPU,
// which hands out workgroups as its cores free up, keeps the image order (HP_SPREAD_LEVELS = 0, the
// identity). Only which workgroup takes which tile changes: the tiles, their rays and the results do not.
#ifndef HP_DISPATCH_ORDER_GLSL
#define HP_DISPATCH_ORDER_GLSL

#include "common/rt_bindings.glsl"
#include "common/trace_capture.glsl"

// A bijection of [0, n), the bit-reversal permutation's first HP_SPREAD_LEVELS (= L) steps generalised to
// any n: the first ceil(n/2) indices take the even positions and the others the odd ones, each half ordered
// the same way for L - 1 more levels, then in order. A block of n/2^L consecutive indices thus lands on
// every 2^L-th position, and 2^L >= T blocks each get their share of every part of the range. No division;
// L is a specialization constant, so the loop unrolls.
uint hp_spread(uint i, uint n) {
  uint pos = 0u;
  uint shift = 0u;
  for (uint level = 0u; level < HP_SPREAD_LEVELS && n > 1u; ++level) {
    uint evens = (n + 1u) >> 1u;
    if (i < evens) {
      n = evens;
    } else {
      i -= evens;
      n -= evens;
      pos |= 1u << shift;
    }
    shift++;
  }
  return pos | (i << shift);
}

// Index i of [0, n) with whole blocks of `block` consecutive indices in spread order and the last, partial
// block in place: the ray-tracing pipelines' launches, which lavapipe splits among its threads the same way,
// take blocks of 8 pixel rows (or of 64 rays, a compute workgroup's) the way the compute passes take theirs.
uint hp_spread_blocks(uint i, uint n, uint block) {
  uint full = n / block;
  if (i >= full * block) return i;
  return hp_spread(i / block, full) * block + i % block;
}

// The two image passes (shadows, reflections) take their rows this way.
#ifdef HP_RT_PIPELINE
// A launch over exactly the image (or the reflection grid): the pixel, rows in spread order 8 at a time.
ivec2 hp_launch_pixel() {
  return ivec2(gl_LaunchIDEXT.x, hp_spread_blocks(gl_LaunchIDEXT.y, gl_LaunchSizeEXT.y, 8u));
}
#else
// The 8x8 tile (workgroup column, row) this workgroup works on: rows in spread order, offset by rt.frame.z
// when a traced pass is dispatched in slices (0 otherwise).
uvec2 hp_tile_workgroup() {
  return uvec2(gl_WorkGroupID.x, rt.frame.z + hp_spread(gl_WorkGroupID.y, gl_NumWorkGroups.y));
}
#ifdef HP_TRACE
// A traced slice in the work-sharing mode (hp_trace_sharing, trace_capture.glsl): the next 8x8 tile of the
// slice, which the calling subgroup takes whole, in rows of `tiles_x` tiles from row rt.frame.z; false when
// none is left. A tile's records then come from one device thread, in its region, in tile order.
bool hp_next_shared_tile(uint tiles_x, out uvec2 wg) {
  uint first;
  wg = uvec2(0u);
  if (!hp_trace_take(64u, first)) return false;
  uint tile = first / 64u;
  wg = uvec2(tile % tiles_x, rt.frame.z + tile / tiles_x);
  return true;
}
#endif
#endif

#endif
