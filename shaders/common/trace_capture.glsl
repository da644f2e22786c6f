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
  TraceRecord trace_records[];
};

uint hp_trace_invocation = 0u;  // global linear invocation index in the full (unsliced) dispatch
uint hp_trace_seq = 0u;         // this invocation's access counter
bool hp_trace_on = false;       // this workgroup is sampled
uint hp_trace_region = 0u;      // the trace buffer region of this workgroup's block of the dispatch

// Call once at the start of main(), with the workgroup's position in the full dispatch. The group size is
// passed in: this file is included before main's local_size layout, where gl_WorkGroupSize is still 1.
// `sampling`: the low 20 bits are k, the bits above log2 of the burst length B: the workgroups of every k-th
// burst of B consecutive workgroups (dispatch order) record (B = 1: every k-th workgroup).
void hp_trace_begin(uvec2 workgroup, uint workgroups_x, uint sampling, uint group_invocations) {
  uint wg_linear = workgroup.y * workgroups_x + workgroup.x;
  hp_trace_invocation = wg_linear * group_invocations + gl_LocalInvocationIndex;
  uint k = sampling & 0xFFFFFu;
  hp_trace_on = k <= 1u || ((wg_linear >> (sampling >> 20)) % k) == 0u;
  // The region: this workgroup's block of the dispatch as run (gl_WorkGroupID, not the tile it works on),
  // blocks of ceil(groups / regions) consecutive indices, as lavapipe splits a dispatch among its threads.
  uint groups = gl_NumWorkGroups.x * gl_NumWorkGroups.y * gl_NumWorkGroups.z;
  uint dispatched = (gl_WorkGroupID.z * gl_NumWorkGroups.y + gl_WorkGroupID.y) * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  uint regions = trace_head.regions;
  hp_trace_region = dispatched / ((groups + regions - 1u) / regions);
}

void hp_rec(uint buffer_id, uint kind, uint offset, uint size) {
  if (!hp_trace_on) return;
  // One atomic per subgroup, not per invocation: the active lanes take consecutive slots of the workgroup's
  // region after the first one's add (the file's writer puts records into issue order, so the slot order
  // does not matter).
  uvec4 lanes = subgroupBallot(true);
  uint n = subgroupBallotBitCount(lanes);
  uint base = 0u;
  if (subgroupElect()) base = atomicAdd(trace_head.region[hp_trace_region].count, n);
  uint i = subgroupBroadcastFirst(base) + subgroupBallotExclusiveBitCount(lanes);
  // Past the region's capacity the record is dropped here but counted, so the host sees the overflow and
  // re-runs the slice smaller: nothing is lost silently.
  uint capacity = trace_head.region_capacity;
  if (i < capacity) {
    trace_records[trace_head.record_base + hp_trace_region * capacity + i] =
        TraceRecord(hp_trace_invocation, hp_trace_seq, HP_TRACE_INFO(buffer_id, kind, size), offset);
  }
  hp_trace_seq++;
}
#define HP_REC_LOAD(buf, off, size) hp_rec((buf), HP_TRACE_LOAD, uint(off), uint(size))
#define HP_REC_STORE(buf, off, size) hp_rec((buf), HP_TRACE_STORE, uint(off), uint(size))
#define HP_REC_ATOMIC(buf, off, size) hp_rec((buf), HP_TRACE_ATOMIC, uint(off), uint(size))
#define HP_TRACE_BEGIN(wg, wgx, k) hp_trace_begin((wg), (wgx), (k), gl_WorkGroupSize.x * gl_WorkGroupSize.y)
#else
#define HP_REC_LOAD(buf, off, size)
#define HP_REC_STORE(buf, off, size)
#define HP_REC_ATOMIC(buf, off, size)
#define HP_TRACE_BEGIN(wg, wgx, k)
#endif

#endif
