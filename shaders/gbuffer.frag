#version 460
#extension GL_GOOGLE_include_directive : require
#include "gpu/shared_types.h"
#include "gpu/bindings.h"

layout(location = 0) in vec3 v_rel_pos;  // position relative to the camera
layout(location = 1) in vec3 v_normal;

layout(set = 0, binding = HP_BIND_GBUFFER_FRAME) uniform Frame { FrameUniforms frame; };
layout(push_constant) uniform Push { GBufferPush pc; };

layout(location = 0) out vec4 out_normal_roughness;  // world normal facing the camera, roughness
layout(location = 1) out vec4 out_albedo_metal;      // base colour (sRGB target), metalness

void main() {
  // Orient by the geometric normal (from screen-space derivatives), not by the winding: glTF surfaces may
  // be double-sided (foliage cards) and any winding convention then fails for one side.
  vec3 to_camera = -v_rel_pos;
  vec3 ng = cross(dFdx(v_rel_pos), dFdy(v_rel_pos));
  if (dot(ng, to_camera) < 0.0) ng = -ng;
  vec3 n = v_normal;
  float len2 = dot(n, n);
  n = len2 > 1e-20 ? n * inversesqrt(len2) : normalize(ng);
  if (dot(n, ng) < 0.0) n = -n;
  out_normal_roughness = vec4(n, pc.material.y);
  out_albedo_metal = vec4(pc.normal_row0.w, pc.normal_row1.w, pc.normal_row2.w, pc.material.x);
}
