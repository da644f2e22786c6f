// One memory access recorded by an instrumented shader, written once for C++ and GLSL (like
// shared_types.h, whose HP_CHECK_* macros and GLSL/C++ switch this header reuses).
//
// A record is 16 bytes (four uints, std430-compatible, no padding) so that a 128 MiB trace buffer
// holds 8 M accesses and a whole workgroup slice can be streamed back and replayed:
//
//   invocation  global linear invocation index within the dispatch:
//                 workgroup_linear * invocations_per_workgroup + gl_LocalInvocationIndex,
//               workgroup_linear = wg.x + wg.y * count.x + wg.z * count.x * count.y.
//               The replay recovers the workgroup and the lane from it, so no other id is stored.
//               32 bits: 4 G invocations (a 1920x1080 frame is 2 M).
//   seq         the invocation's own access counter (0, 1, 2, ...). Lanes of one wavefront that share
//               a rank issue together in the replay (lockstep); the GPU's atomic counter order is
//               not relied on.
//   info        packed: bits 0..3 size-1 (1..16 bytes: scalar up to vec4/uvec4 loads),
//                       bits 4..5 kind (HP_TRACE_LOAD / STORE / ATOMIC),
//                       bits 6..7 reserved (0),
//                       bits 8..15 buffer id (index into the trace file's buffer table; ~16 are used,
//                                  256 fit),
//                       bits 16..31 reserved (0): readers reject non-zero so future use is safe.
//   offset      byte offset within the buffer: 32 bits covers buffers up to 4 GiB. For images it is
//               the LOGICAL linear offset (y * width + x) * texel_bytes + byte; the trace file's buffer
//               table declares how texels are laid out in memory (linear rows or tiles) and the
//               replay maps the logical offset to an address, so shaders need not know the layout.
//
// Recording: a slice's records go to the `regions` equal regions of `region_capacity` records that follow
// the header (the host has several such buffers, writing some out while the device fills another), each
// region with its own counter on its own 64-byte line. A
// workgroup appends to the region of its block of the dispatch (contiguous blocks of workgroup indices,
// one per region) with atomicAdd on that region's count: lavapipe runs each contiguous block of a dispatch
// on one thread, so with a region per thread no two threads add to the same counter (on one shared
// counter the cache line bounced between the cores on every add). If the returned index is past
// `region_capacity` the record is not written but the count keeps growing, so the host sees the overflow
// and re-runs the slice smaller: a record is never silently dropped.
#ifndef HP_TRACE_RECORD_H
#define HP_TRACE_RECORD_H

#include "shared_types.h"

#define HP_TRACE_LOAD 0u
#define HP_TRACE_STORE 1u
#define HP_TRACE_ATOMIC 2u
#define HP_TRACE_MAX_ACCESS_BYTES 16u
#define HP_TRACE_SIZE_MASK 0xFu
#define HP_TRACE_KIND_SHIFT 4u
#define HP_TRACE_KIND_MASK 3u
#define HP_TRACE_BUFFER_SHIFT 8u
#define HP_TRACE_BUFFER_MASK 0xFFu
#define HP_TRACE_RESERVED_MASK 0xFFFF00C0u
// Packs the info word; size must be 1..16, kind one of HP_TRACE_*, buffer < 256.
#define HP_TRACE_INFO(buffer, kind, size) \
  ((((size) - 1u) & HP_TRACE_SIZE_MASK) | (((kind) & HP_TRACE_KIND_MASK) << HP_TRACE_KIND_SHIFT) | \
   (((buffer) & HP_TRACE_BUFFER_MASK) << HP_TRACE_BUFFER_SHIFT))

#ifdef __cplusplus
namespace hp::gpu {
#endif

struct TraceRecord {
  uint invocation;
  uint seq;
  uint info;
  uint offset;
};
HP_CHECK_SIZE(TraceRecord, 16);
HP_CHECK_LAYOUT(TraceRecord, seq, 4);
HP_CHECK_LAYOUT(TraceRecord, info, 8);
HP_CHECK_LAYOUT(TraceRecord, offset, 12);

#define HP_TRACE_MAX_REGIONS 16u

// One region's record counter, alone on a 64-byte line.
struct TraceRegionCount {
  uint count;  // atomically incremented by every access of the region, even past its capacity
  uint pad[15];
};
HP_CHECK_SIZE(TraceRegionCount, 64);

// Head of the trace storage buffer; the records follow it (std430: a 1152-byte header, then the array;
// region r holds records [r * region_capacity, (r + 1) * region_capacity)).
struct TraceBufferHeader {
  uint regions;          // 1..HP_TRACE_MAX_REGIONS
  uint region_capacity;  // records each region holds
  uint pass_id;
  // Work sharing (a CPU device): where `units` is not 0 the dispatch is one workgroup per region, whose
  // subgroups take the slice's `units` invocations a workgroup's worth at a time from the counter
  // `work.count`, so that a thread held up by the host's writers leaves its share to the others instead of
  // holding up the slice. 0: each workgroup takes its own tile.
  uint units;
  uint reserved[12];
  TraceRegionCount work;  // on a line of its own: the hooks read the line above at every record
  TraceRegionCount region[HP_TRACE_MAX_REGIONS];
};
HP_CHECK_SIZE(TraceBufferHeader, 64 + 64 + 64 * 16);
HP_CHECK_LAYOUT(TraceBufferHeader, work, 64);
HP_CHECK_LAYOUT(TraceBufferHeader, region, 128);

#ifdef __cplusplus
inline constexpr uint trace_size(uint info) { return (info & HP_TRACE_SIZE_MASK) + 1u; }
inline constexpr uint trace_kind(uint info) { return (info >> HP_TRACE_KIND_SHIFT) & HP_TRACE_KIND_MASK; }
inline constexpr uint trace_buffer(uint info) { return (info >> HP_TRACE_BUFFER_SHIFT) & HP_TRACE_BUFFER_MASK; }
static_assert(HP_TRACE_INFO(5u, HP_TRACE_STORE, 16u) == (15u | (1u << 4) | (5u << 8)));
static_assert(trace_size(HP_TRACE_INFO(3u, HP_TRACE_ATOMIC, 4u)) == 4u);
static_assert(trace_kind(HP_TRACE_INFO(3u, HP_TRACE_ATOMIC, 4u)) == HP_TRACE_ATOMIC);
static_assert(trace_buffer(HP_TRACE_INFO(200u, HP_TRACE_LOAD, 1u)) == 200u);
static_assert((HP_TRACE_INFO(255u, 3u, 16u) & HP_TRACE_RESERVED_MASK) == 0u);
}  // namespace hp::gpu
#else
uint hp_trace_size(uint info) { return (info & HP_TRACE_SIZE_MASK) + 1u; }
uint hp_trace_kind(uint info) { return (info >> HP_TRACE_KIND_SHIFT) & HP_TRACE_KIND_MASK; }
uint hp_trace_buffer(uint info) { return (info >> HP_TRACE_BUFFER_SHIFT) & HP_TRACE_BUFFER_MASK; }
#endif

#endif
