// Buffers of the compaction path (bindings 22..25 of the ray-tracing set).
#ifndef HP_COMPACTION_GLSL
#define HP_COMPACTION_GLSL

#include "gpu/shared_types.h"
#include "gpu/bindings.h"

layout(std430, set = 0, binding = HP_BIND_RT_COMPACT_RAYS) buffer CompactRayBuffer { CompactRay compact_rays[]; };
layout(std430, set = 0, binding = HP_BIND_RT_SORT_KEYS) buffer SortKeyBuffer { uint sort_keys[]; };
layout(std430, set = 0, binding = HP_BIND_RT_SORT_VALUES) buffer SortValueBuffer { uint sort_values[]; };
// The live ray count (appended atomically), the indirect dispatch of the consume pass, and its indirect
// ray-tracing launch (VkTraceRaysIndirectCommandKHR, at byte 16: HP_RAY_COUNT_LAUNCH_OFFSET).
layout(std430, set = 0, binding = HP_BIND_RT_RAY_COUNT) buffer RayCountBuffer {
  uint ray_count;
  uint consume_groups_x, consume_groups_y, consume_groups_z;
  uint consume_launch_w, consume_launch_h, consume_launch_d;
};

#define HP_CONSUME_GROUP 64u

#endif
