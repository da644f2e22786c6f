#version 460
#extension GL_GOOGLE_include_directive : require
#include "gpu/shared_types.h"
#include "gpu/bindings.h"
#include "common/brdf.glsl"

// One thread per pixel, 8x8 tiles; a ragged right/bottom edge is covered by the dispatch and skipped here.
layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = HP_BIND_COMPOSITE_FRAME) uniform Frame { FrameUniforms frame; };
layout(set = 0, binding = HP_BIND_COMPOSITE_GBUF_DEPTH) uniform sampler2D g_depth;
layout(set = 0, binding = HP_BIND_COMPOSITE_GBUF_NORMAL) uniform sampler2D g_normal_roughness;
layout(set = 0, binding = HP_BIND_COMPOSITE_GBUF_ALBEDO) uniform sampler2D g_albedo_metal;
layout(set = 0, binding = HP_BIND_COMPOSITE_OUTPUT, rgba32f) uniform writeonly image2D out_color;
layout(set = 0, binding = HP_BIND_COMPOSITE_SHADOW_MASK, r32f) uniform readonly image2D shadow_mask;
layout(set = 0, binding = HP_BIND_COMPOSITE_REFLECTION, rgba32f) uniform readonly image2D reflection_accum;

// Relative to the camera (inv_view_proj is camera-relative, view.hpp).
vec3 relative_position(ivec2 p, float depth) {
  vec2 ndc = (vec2(p) + 0.5) / vec2(frame.extent.xy) * 2.0 - 1.0;
  vec4 h = frame.inv_view_proj * vec4(ndc, depth, 1.0);
  return h.xyz / h.w;
}

// The lit colour of a surface pixel.
vec3 shade(ivec2 p, float depth) {
  vec4 nr = texelFetch(g_normal_roughness, p, 0);
  vec4 am = texelFetch(g_albedo_metal, p, 0);
  vec3 n = normalize(nr.xyz);
  vec3 v = normalize(-relative_position(p, depth));
  vec3 l = frame.light_dir.xyz;
  vec3 light = frame.light_color.rgb * frame.light_dir.w;
  uint flags = frame.extent.w;
  float lit = (flags & HP_COMPOSITE_SHADOWS) != 0u ? imageLoad(shadow_mask, p).r : 1.0;
  vec3 c = lit * shade_direct(n, v, l, am.rgb, am.a, nr.a, light);
  vec4 refl = vec4(0.0);
  if ((flags & HP_COMPOSITE_REFLECTIONS) != 0u) {
    // Nearest cell of the (possibly reduced) reflection grid.
    refl = imageLoad(reflection_accum, p / int(frame.params.w));
  }
  if (refl.a > 0.5) {
    // A traced reflection replaces the constant-sky specular term, weighted by Fresnel.
    vec3 f0 = mix(vec3(0.04), am.rgb, am.a);
    vec3 F = fresnel_schlick(f0, max(dot(n, v), 0.0));
    c += shade_ambient_diffuse(n, v, am.rgb, am.a, frame.sky_color.rgb) + F * refl.rgb;
  } else {
    c += shade_ambient(n, v, am.rgb, am.a, frame.sky_color.rgb);
  }
  return c;
}

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (p.x >= int(frame.extent.x) || p.y >= int(frame.extent.y)) return;
  float depth = texelFetch(g_depth, p, 0).r;
  float background = frame.params.x > 0.5 ? 0.0 : 1.0;
  // One store for sky and surface alike: on lavapipe every imageStore in the code is a loop over the lanes
  // that runs for every 8 pixels, needed or not.
  vec3 c = frame.sky_color.rgb;
  if (depth != background) c = shade(p, depth);
  imageStore(out_color, p, vec4(c, 1.0));
}
