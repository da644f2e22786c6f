// The descriptor set every ray-tracing pass uses (one layout, bound once per frame). Buffers a pass does
// not need in a configuration are bound to a small dummy and never read: the specialization constants
// below remove the code that would read them.
#ifndef HP_RT_BINDINGS_GLSL
#define HP_RT_BINDINGS_GLSL

#include "gpu/shared_types.h"
#include "gpu/bindings.h"
#include "common/ray_offset.glsl"

// Geometry layout: 0 = "indexed" (EBO: vertex positions + an index buffer in leaf order),
// 1 = "soup" (de-indexed: three vertices per triangle in leaf order).
layout(constant_id = 0) const uint HP_GEOMETRY_SOUP = 0;
// BVH granularity: 0 = triangle leaves, 1 = object leaves (a leaf's objects are tested triangle by triangle).
layout(constant_id = 1) const uint HP_OBJECT_LEAVES = 0;
// Geometry fetches: 1 = through the texel views below (RtScene::geometry_texels), 0 = storage loads.
layout(constant_id = 2) const uint HP_GEOMETRY_TEXELS = 0;
// What the frame records and how it makes its rays (HP_RT_*: counters, dumps, the reflection hits' shadow
// rays, the offset and jitter modes): a constant, so that a configuration runs none of the code it does not
// ask for. On lavapipe a test of a uniform would still run it, masked, for every 8
// invocations: the dump stores and counter atomics are loops over the lanes, the reflection hits' shadow ray
// a second traversal, and both offset (or jitter) modes would be computed.
layout(constant_id = 3) const uint HP_RT_FLAGS = 0;
// Node layout of the compute traversal (bvh::NodeLayout): 0 = the study's 32-byte binary nodes (gpu::BvhNode),
// 1 = wide4 (gpu::WideNode: 4-wide, quantized child boxes; renderer/bvh/wide.hpp).
layout(constant_id = 5) const uint HP_WIDE_NODES = 0;
// Levels of the order in which workgroups take their tiles or rays (common/dispatch_order.glsl): 0 on a GPU
// (the image order), ceil(log2(threads)) on a CPU driver that gives each thread one block of workgroups.
layout(constant_id = 6) const uint HP_SPREAD_LEVELS = 0;
// How the traversal divides (hp_div, common/traversal.glsl): 0 = the device's 32-bit division, 1 = the quotient
// taken in double precision and rounded once to float (exact_traversal_division in renderer/rt_scene.hpp).
layout(constant_id = 7) const uint HP_EXACT_DIVISION = 0;
// How the traversal reads the node and geometry texels: 0 = texelFetch from the uniform texel buffers (bindings
// 26, 29-31), 1 = imageLoad from the same views as storage texel buffers (bindings 39-42; RtScene::storage_texels:
// faster on lavapipe, common/traversal.glsl).
layout(constant_id = 8) const uint HP_STORAGE_TEXELS = 0;

layout(set = 0, binding = HP_BIND_RT_FRAME) uniform FrameBlock { FrameUniforms frame; };
layout(set = 0, binding = HP_BIND_RT_PARAMS) uniform RayBlock { RayParams rt; };
layout(std430, set = 0, binding = HP_BIND_RT_NODES) readonly buffer NodeBuffer { BvhNode nodes[]; };
layout(std430, set = 0, binding = HP_BIND_RT_POSITIONS) readonly buffer PositionBuffer { float positions[]; };
layout(std430, set = 0, binding = HP_BIND_RT_INDICES) readonly buffer IndexBuffer { uint indices[]; };
layout(std430, set = 0, binding = HP_BIND_RT_SOUP) readonly buffer SoupBuffer { float soup[]; };
layout(std430, set = 0, binding = HP_BIND_RT_OBJECT_FIRST) readonly buffer ObjectBuffer { uint object_first[]; };
layout(std430, set = 0, binding = HP_BIND_RT_SLOT_SCENE) readonly buffer SlotSceneBuffer { uint slot_scene[]; };
layout(std430, set = 0, binding = HP_BIND_RT_NORMALS) readonly buffer NormalBuffer { float normals[]; };
layout(std430, set = 0, binding = HP_BIND_RT_SOUP_NORMALS) readonly buffer SoupNormalBuffer { float soup_normals[]; };
layout(std430, set = 0, binding = HP_BIND_RT_SLOT_MATERIAL) readonly buffer SlotMaterialBuffer
    { uint slot_material[]; };
layout(std430, set = 0, binding = HP_BIND_RT_MATERIALS) readonly buffer MaterialBuffer { GpuMaterial materials[]; };
layout(std430, set = 0, binding = HP_BIND_RT_COUNTERS) coherent buffer CounterBuffer { uint counters[]; };
layout(std430, set = 0, binding = HP_BIND_RT_SHADOW_DUMP) writeonly buffer ShadowDumpBuffer { RayDump shadow_dump[]; };
layout(std430, set = 0, binding = HP_BIND_RT_REFLECTION_DUMP) writeonly buffer ReflectionDumpBuffer
    { RayDump reflection_dump[]; };
layout(set = 0, binding = HP_BIND_RT_GBUF_DEPTH) uniform sampler2D g_depth;
layout(set = 0, binding = HP_BIND_RT_GBUF_NORMAL) uniform sampler2D g_normal_roughness;
layout(set = 0, binding = HP_BIND_RT_GBUF_ALBEDO) uniform sampler2D g_albedo_metal;
layout(set = 0, binding = HP_BIND_RT_SHADOW_MASK, r32f) uniform image2D shadow_mask;
layout(set = 0, binding = HP_BIND_RT_REFLECTION, rgba32f) uniform image2D reflection_image;
layout(set = 0, binding = HP_BIND_RT_REFLECTION_ACCUM, rgba32f) uniform image2D reflection_accum;

// Adds `v` to the 64-bit counter at word `at` (low word, high word); the carry is exact under concurrency:
// the one add that wraps the low word is the one that sees old + v overflow.
void hp_counter_add(uint at, uint v) {
  if (v == 0u) return;
  uint old = atomicAdd(counters[at], v);
  if (old > 0xFFFFFFFFu - v) atomicAdd(counters[at + 1u], 1u);
}

// `precise` here and in the ray set-up: the same ray must come out bit for bit in every shader that builds
// it (direct reflections, compaction, traced variants), whatever the compiler would fuse into FMAs.
// Camera-relative (view.hpp): inv_view_proj has no translation, so a world far from the origin keeps the
// precision of its positions near the camera; the eye is added last.
vec3 hp_world_position(ivec2 p, float depth) {
  precise vec2 ndc = (vec2(p) + 0.5) / vec2(frame.extent.xy) * 2.0 - 1.0;
  precise vec4 h = frame.inv_view_proj * vec4(ndc, depth, 1.0);
  precise vec3 w = h.xyz / h.w + frame.camera_pos.xyz;
  return w;
}

// How far a position reconstructed from the depth buffer can be from the surface: the world distance
// between the reconstructions at `depth` and 8 depth-buffer ULPs nearer the near plane's value (measured:
// about 1e-5 of the distance with a 32-bit standard-Z buffer).
float hp_depth_uncertainty(ivec2 p, float depth, vec3 pos) {
  uint bits = floatBitsToUint(depth);
  precise float d2 = uintBitsToFloat(bits > 8u ? bits - 8u : bits + 8u);
  return distance(hp_world_position(p, d2), pos);
}

// The robust origin of a ray leaving the G-buffer surface at pixel p, moved along the normal only, by what
// the point's error can be: the depth uncertainty, plus 2^-23 (1 to 2 ULPs) of the largest world coordinate
// (the BVH holds world-space floats rounded to that grid, half an ULP per vertex coordinate; the
// camera-relative G-buffer surface is not rounded) and of the distance to the camera (rounding in the
// reconstruction). Measured at 1e5 from the origin (hard_cases.json, 26,217 pixels): no grid term, 1,360
// acne pixels; 2^-23, 15; 2^-22, 25; 2^-20, 85 (a larger offset pushes origins into touching objects). Wächter & Binder's offset (ray_offset.glsl)
// is meant for hit points computed by a ray cast; applied here it was measured to fail both ways: its
// 256-ULP steps per axis are 2 world units at 1e5 from the origin and move the point sideways (3,480 acne
// pixels of 163,708), and its absolute 2^-16 near the origin is 1.5% of a world scaled by 1e-3 (docs/speed-vs-error.md,
// "Shadows").
vec3 hp_offset_gbuffer(ivec2 p, float depth, vec3 pos, vec3 n) {
  vec3 a = abs(pos);
  precise float grid = (max(a.x, max(a.y, a.z)) + distance(pos, frame.camera_pos.xyz)) * (1.0 / 8388608.0);
  precise vec3 o = pos + n * (hp_depth_uncertainty(p, depth, pos) + grid);
  return o;
}

bool hp_is_background(float depth) { return depth == (frame.params.x > 0.5 ? 0.0 : 1.0); }

#endif
