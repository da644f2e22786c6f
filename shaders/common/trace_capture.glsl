// Memory-access recording for the instrumented pass variants (compiled from the same sources with
// -DHP_TRACE=1, so the traced code is the code that runs). Without HP_TRACE every hook is empty.
#ifndef HP_TRACE_CAPTURE_GLSL
#define HP_TRACE_CAPTURE_GLSL

#include "gpu/trace_buffers.h"
#include "gpu/bindings.h"
#include "gpu/trace_record.h"

#if defined(HP_TRACE) && defined(HP_RT_PIPELINE)
#error "the instrumented variants are compute shaders (compute or ray-query traversal)"
#endif

#ifdef HP_TRACE
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require

layout(std430, set = 0, binding = HP_BIND_TRACE_RECORDS) coherent buffer TraceBuffer {
  TraceBufferHeader trace_head;
  uvec4 trace_records[];  // TraceRecord's four words, stored as one vector (one lane loop in llvmpipe, not four)
};

uint hp_trace_invocation = 0u;  // global linear invocation index in the full (unsliced) dispatch
uint hp_trace_seq = 0u;         // this invocation's access counter
bool hp_trace_on = false;       // this workgroup is sampled
uint hp_trace_region = 0u;      // the trace buffer region of this workgroup's block of the dispatch

// Call once at the start of main(), with the workgroup's position in the full dispatch. The group size is
// passed in: this file is included before main's local_size layout, where gl_WorkGroupSize is still 1.
// `sampling`: the low 20 bits are k, the bits above log2 of the burst length B: the workgroups of every k-th
// burst of B consecutive workgroups (dispatch order) record (B = 1: every k-th workgroup).
void hp_trace_begin(uvec2 workgroup, uint workgroups_x, uint sampling, uint group_invocations, uint local_index) {
  uint wg_linear = workgroup.y * workgroups_x + workgroup.x;
  hp_trace_invocation = wg_linear * group_invocations + local_index;
  hp_trace_seq = 0u;  // in the work-sharing mode an invocation begins several tiles' invocations in turn
  uint k = sampling & 0xFFFFFu;
  hp_trace_on = k <= 1u || ((wg_linear >> (sampling >> 20)) % k) == 0u;
  // The region: this workgroup's block of the dispatch as run (gl_WorkGroupID, not the tile it works on),
  // blocks of ceil(groups / regions) consecutive indices, as lavapipe splits a dispatch among its threads.
  uint groups = gl_NumWorkGroups.x * gl_NumWorkGroups.y * gl_NumWorkGroups.z;
  uint dispatched = (gl_WorkGroupID.z * gl_NumWorkGroups.y + gl_WorkGroupID.y) * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  uint regions = trace_head.regions;
  hp_trace_region = dispatched / ((groups + regions - 1u) / regions);
}

// Records the invocation's next n accesses (n <= 4, a constant at every call, so the loop unrolls), the k-th
// with info[k] and offset[k]: the accesses one statement makes together (a node's 16-byte loads, a
// triangle's index and vertices) take their slots with one reservation.
void hp_rec_n(uint n, uvec4 info, uvec4 offset) {
  if (!hp_trace_on) return;
  // One atomic per subgroup, not per invocation: the active lanes take consecutive runs of n slots of the
  // workgroup's region after the first one's add (the file's writer puts records into issue order, so the
  // slot order does not matter).
  uvec4 lanes = subgroupBallot(true);
  uint lanes_on = subgroupBallotBitCount(lanes);
  uint base = 0u;
  if (subgroupElect()) base = atomicAdd(trace_head.region[hp_trace_region].count, lanes_on * n);
  uint first = subgroupBroadcastFirst(base);
  uint i = first + subgroupBallotExclusiveBitCount(lanes) * n;
  // Past the region's capacity a record is dropped here but counted, so the host sees the overflow and
  // re-runs the slice smaller: nothing is lost silently. Where the subgroup's whole reservation fits (a
  // subgroup-uniform test), the lanes store without a test of their own: 3-4% less capture time for the
  // shadow pass on lavapipe (docs/memory-traces.md).
  uint capacity = trace_head.region_capacity;
  uint at = hp_trace_region * capacity + i;
  if (first + lanes_on * n <= capacity) {
    for (uint k = 0u; k < n; ++k) trace_records[at + k] = uvec4(hp_trace_invocation, hp_trace_seq + k, info[k], offset[k]);
  } else {
    for (uint k = 0u; k < n; ++k) {
      if (i + k < capacity) {
        trace_records[at + k] = uvec4(hp_trace_invocation, hp_trace_seq + k, info[k], offset[k]);
      }
    }
  }
  hp_trace_seq += n;
}
#define HP_REC_LOAD(buf, off, size) hp_rec_n(1u, uvec4(HP_TRACE_INFO((buf), HP_TRACE_LOAD, (size))), uvec4(off))
#define HP_REC_STORE(buf, off, size) hp_rec_n(1u, uvec4(HP_TRACE_INFO((buf), HP_TRACE_STORE, (size))), uvec4(off))
#define HP_REC_ATOMIC(buf, off, size) hp_rec_n(1u, uvec4(HP_TRACE_INFO((buf), HP_TRACE_ATOMIC, (size))), uvec4(off))
// n loads made together, in this order: buffers, offsets and sizes as uvec4 (the first n components count).
#define HP_REC_LOADS(n, bufs, offs, sizes) \
  hp_rec_n((n), HP_TRACE_INFO(uvec4(bufs), HP_TRACE_LOAD, uvec4(sizes)), uvec4(offs))
#define HP_TRACE_BEGIN(wg, wgx, k) \
  hp_trace_begin((wg), (wgx), (k), gl_WorkGroupSize.x * gl_WorkGroupSize.y, gl_LocalInvocationIndex)
// The same for invocation `local` of tile `wg` taken in the work-sharing mode (TraceBufferHeader::units).
#define HP_TRACE_BEGIN_AT(wg, wgx, k, local) \
  hp_trace_begin((wg), (wgx), (k), gl_WorkGroupSize.x * gl_WorkGroupSize.y, (local))

// The work-sharing mode of a capture slice (TraceBufferHeader::units).
bool hp_trace_sharing() { return trace_head.units != 0u; }
// The next workgroup's worth (`group` invocations) of the slice's invocations, from its first (relative to
// the slice); false when none is left. Subgroup-uniform.
bool hp_trace_take(uint group, out uint first) {
  uint u = 0u;
  if (subgroupElect()) u = atomicAdd(trace_head.work.count, group);
  first = subgroupBroadcastFirst(u);
  return first < trace_head.units;
}
#else
#define HP_REC_LOAD(buf, off, size)
#define HP_REC_STORE(buf, off, size)
#define HP_REC_ATOMIC(buf, off, size)
#define HP_REC_LOADS(n, bufs, offs, sizes)
#define HP_TRACE_BEGIN(wg, wgx, k)
#define HP_TRACE_BEGIN_AT(wg, wgx, k, local)
#endif

#endif
