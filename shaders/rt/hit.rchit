#version 460
#extension GL_EXT_ray_tracing : require
#extension GL_GOOGLE_include_directive : require
// The closest-hit shader of every ray-tracing-pipeline pass: hands the committed triangle back to the
// ray-generation shader, which maps and shades it exactly as the compute paths do.
#include "common/rt_payload.glsl"

layout(location = 0) rayPayloadInEXT HpPayload payload;
hitAttributeEXT vec2 barycentrics;

void main() {
  payload.primitive = gl_InstanceCustomIndexEXT + gl_PrimitiveID;  // custom index: 0, or the instance's first triangle
  payload.t = gl_HitTEXT;
  payload.u = barycentrics.x;
  payload.v = barycentrics.y;
}
