#version 460
#extension GL_GOOGLE_include_directive : require
// Sizes the consume pass on the GPU from the compacted ray count: no CPU readback, no ray dropped.
#include "common/compaction.glsl"

layout(local_size_x = 1) in;

void main() {
  consume_groups_x = (ray_count + HP_CONSUME_GROUP - 1u) / HP_CONSUME_GROUP;
  consume_groups_y = 1u;
  consume_groups_z = 1u;
}
