#version 460
#extension GL_GOOGLE_include_directive : require
// Sizes the consume pass (a dispatch, or a ray-tracing launch) on the GPU from the compacted ray count: no CPU readback, no ray dropped.
#include "common/compaction.glsl"

layout(local_size_x = 1) in;

void main() {
  consume_groups_x = (ray_count + HP_CONSUME_GROUP - 1u) / HP_CONSUME_GROUP;
  consume_groups_y = 1u;
  consume_groups_z = 1u;
  // The ray-tracing pipeline's consume launch (vkCmdTraceRaysIndirectKHR): one invocation per ray.
  consume_launch_w = ray_count;
  consume_launch_h = 1u;
  consume_launch_d = 1u;
}
