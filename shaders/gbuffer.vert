#version 460
#extension GL_GOOGLE_include_directive : require
#include "gpu/shared_types.h"
#include "gpu/bindings.h"

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;

layout(set = 0, binding = HP_BIND_GBUFFER_FRAME) uniform Frame { FrameUniforms frame; };
layout(push_constant) uniform Push { GBufferPush pc; };

layout(location = 0) out vec3 v_rel_pos;  // position relative to the camera
layout(location = 1) out vec3 v_normal;

void main() {
  // Camera-relative: pc.world has the eye subtracted and view_proj has no translation (view.hpp).
  vec4 wp = pc.world * vec4(in_position, 1.0);
  v_rel_pos = wp.xyz;
  v_normal = vec3(dot(pc.normal_row0.xyz, in_normal), dot(pc.normal_row1.xyz, in_normal),
                  dot(pc.normal_row2.xyz, in_normal));
  gl_Position = frame.view_proj * wp;
}
