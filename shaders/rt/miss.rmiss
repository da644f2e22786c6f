#version 460
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require
// The miss shader of every ray-tracing-pipeline pass.
#include "common/rt_payload.glsl"

layout(location = 0) rayPayloadInEXT HpPayload payload;

void main() { payload.primitive = -1; }
