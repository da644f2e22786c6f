// Every struct that both C++ and GLSL read, written once for both languages.
// GLSL: included into shaders (std430 buffers, push constants). C++: included from anywhere in hp::gpu,
// with static_asserts that pin sizes and offsets to the std430 layout the shaders use.
#ifndef HP_SHARED_TYPES_H
#define HP_SHARED_TYPES_H

#ifdef __cplusplus
#include <cstddef>
#include <cstdint>
#include <glm/glm.hpp>
namespace hp::gpu {
using vec2 = glm::vec2;
using vec3 = glm::vec3;
using vec4 = glm::vec4;
using ivec2 = glm::ivec2;
using ivec4 = glm::ivec4;
using uvec2 = glm::uvec2;
using uvec4 = glm::uvec4;
using mat4 = glm::mat4;
using uint = uint32_t;
#define HP_CHECK_LAYOUT(T, field, off) static_assert(offsetof(T, field) == (off), #T "." #field " offset")
#define HP_CHECK_SIZE(T, size) static_assert(sizeof(T) == (size), #T " size")
#else
#define HP_CHECK_LAYOUT(T, field, off)
#define HP_CHECK_SIZE(T, size)
#endif

// ---------------------------------------------------------------------------------------------------------
// BVH node: the study's 32 bytes (float3 min, float3 max, int offset, int primAndAxis), reordered so that
// each float3 shares a 16-byte std430 slot with one int: the node is two vec4-sized loads on a GPU.
//   interior: offset = index of the second child (the first child follows its parent), count = 0;
//   leaf:     offset = first primitive (triangle, or object for the object granularity), count > 0.
// prim_axis packs (count << 2) | split axis; the split axis orders the children front to back.
struct BvhNode {
  vec3 bmin;
  int offset;
  vec3 bmax;
  uint prim_axis;
};
HP_CHECK_SIZE(BvhNode, 32);
HP_CHECK_LAYOUT(BvhNode, offset, 12);
HP_CHECK_LAYOUT(BvhNode, bmax, 16);
HP_CHECK_LAYOUT(BvhNode, prim_axis, 28);

#define HP_BVH_AXIS_BITS 2u
#define HP_BVH_AXIS_MASK 3u
// Fixed traversal stack shared by the C++ reference and every shader; the builder guarantees that no tree
// needs more (its depth is bounded so that stack use <= HP_BVH_STACK_SIZE).
#define HP_BVH_STACK_SIZE 64

// BVH node of the 4-wide layout (node layout "wide4", bvh::NodeLayout): 64 bytes, four 16-byte texels. A wide
// node stands for a binary interior node P and holds up to four slots: a cut of P's subtree (binary nodes
// below P covering each of its leaves once), chosen for the least SAH cost (bvh/wide.cpp), in left-to-right
// order, the empty slots last.
//   w[0].xyz: the quantization origin (P's box min, float bits);
//   w[0].w:   bits 0-23 an 8-bit float exponent per axis (the axis' step is 2^(e - 127)); bits 24-31 zero;
//   w[1] = (lo.x, hi.x, lo.y, hi.y), w[2].xy = (lo.z, hi.z): byte i of each word is slot i's bound in steps,
//             decoded as origin + q * step (one rounding; q * step is exact) and never inside the binary box;
//   w[2].zw:  the visiting order per ray octant (octant = x<0 | y<0 << 1 | z<0 << 2), a byte each: octants 0-3
//             in w[2].z, 4-7 in w[2].w, byte bits 2i..2i+1 = the slot visited i-th. It is the binary
//             traversal's order (at each binary node the second child first where the ray is negative on the
//             node's split axis), the empty slots after the occupied ones;
//   w[3]:     the slots' child words: 0 = empty; interior = wide node index; leaf = HP_WIDE_LEAF |
//             count << HP_WIDE_COUNT_SHIFT | first primitive (count 1..15, as the binary leaf's offset/count).
struct WideNode {
  uvec4 w[4];
};
HP_CHECK_SIZE(WideNode, 64);
#define HP_WIDE_LEAF 0x80000000u
#define HP_WIDE_COUNT_SHIFT 27u
#define HP_WIDE_COUNT_MASK 15u
#define HP_WIDE_FIRST_MASK 0x07FFFFFFu

// ---------------------------------------------------------------------------------------------------------
// Frame-wide constants (uniform buffer, std140-compatible: only vec4/mat4 members).
struct FrameUniforms {
  mat4 view_proj;        // camera-relative: applied to (world - camera_pos) (view.hpp)
  mat4 inv_view_proj;    // camera-relative: gives (world - camera_pos)
  vec4 camera_pos;       // xyz, w unused
  vec4 light_dir;        // xyz toward the light (normalised), w = intensity
  vec4 light_color;      // rgb, a unused
  vec4 sky_color;        // rgb, a unused
  uvec4 extent;          // width, height, frame index, flags (HP_COMPOSITE_*)
  vec4 params;           // x = reversed-Z (1/0), y = near, z = far, w unused
};
HP_CHECK_SIZE(FrameUniforms, 224);
HP_CHECK_LAYOUT(FrameUniforms, inv_view_proj, 64);
HP_CHECK_LAYOUT(FrameUniforms, camera_pos, 128);
HP_CHECK_LAYOUT(FrameUniforms, extent, 192);
// FrameUniforms.extent.w: which ray-traced results the composite reads (Frame::upload_uniforms, composite.comp).
#define HP_COMPOSITE_SHADOWS 1u
#define HP_COMPOSITE_REFLECTIONS 2u

// Per-draw push constants of the G-buffer pass: exactly the 128 bytes every Vulkan device guarantees.
struct GBufferPush {
  mat4 world;
  vec4 normal_row0;  // rows of the inverse-transpose of world's 3x3 in xyz; w = base colour r, g, b
  vec4 normal_row1;
  vec4 normal_row2;
  vec4 material;     // x = metallic, y = roughness, z = material index, w unused
};
HP_CHECK_SIZE(GBufferPush, 128);

// ---------------------------------------------------------------------------------------------------------
// Parameters of the ray-tracing passes (uniform buffer, std140-compatible: only 16-byte members).
struct RayParams {
  uvec4 grid;        // x, y = reflection grid size; z = reflection scale divisor (1, 2, 4); w unused
  vec4 shadow;       // x = normal bias (world units); yzw unused
  vec4 reflection;   // x = roughness threshold (reflective when roughness < x); yzw unused
  uvec4 frame;       // x = sample index (frames since the last reset), y = seed, z = first workgroup row of a
                     // traced slice, w = trace sampling (k | log2(burst) << 20, trace_capture.glsl)
  vec4 jitter;       // xy = this frame's shared offset in [0, 1)^2 (HP_RT_SHARED_JITTER)
  vec4 bounds_min;   // xyz: scene bounds (origin sort keys); w = sort key mode (HP_SORT_*)
  vec4 bounds_max;   // xyz: scene bounds; w = write-back mode (HP_WRITEBACK_*)
};
HP_CHECK_SIZE(RayParams, 112);

// Ray compaction / sorting (the study's section 4.2).
#define HP_SORT_NONE 0
#define HP_SORT_OCTANT 1
#define HP_SORT_DIRECTION 2
#define HP_SORT_ORIGIN 3
#define HP_WRITEBACK_INDEX 0
#define HP_WRITEBACK_REPROJECT 1

// A compacted reflection ray: its origin and grid cell, its direction.
struct CompactRay {
  vec4 origin_cell;  // xyz origin, w = uintBitsToFloat(grid cell)
  vec4 dir;          // xyz direction, w unused
};
HP_CHECK_SIZE(CompactRay, 32);

#define HP_RT_COUNTERS 1u        // shaders add rays, nodes visited and triangles tested to the counter buffer
#define HP_RT_DUMP_RAYS 2u       // shaders write every ray they cast and its result (tests, cross-checks)
#define HP_RT_REFLECTION_SHADOWS 4u  // reflection hits are shaded with a shadow ray
#define HP_RT_ROBUST_OFFSET 8u   // ray origins offset robustly (else by the normal bias, RayParams.shadow.x)
#define HP_RT_SHARED_JITTER 16u  // one reflection jitter offset per frame (else one per thread)

// A ray as the shaders dump it (HP_RT_DUMP_RAYS): the bvh::Ray layout, then the result.
struct RayDump {
  vec4 origin_tmin;
  vec4 dir_tmax;
  ivec4 hit;         // x = scene triangle index or -1 (any-hit: 0/-1 hit flag as prim), y = floatBitsToInt(t), z = cast (1) or not (0)
};
HP_CHECK_SIZE(RayDump, 48);

// The traversal on its own (shaders/trace_rays.comp): a ray in, in the bvh::Ray layout...
struct BatchRay {
  vec4 origin_tmin;
  vec4 dir_tmax;
};
HP_CHECK_SIZE(BatchRay, 32);

// ... and its answer: the bvh::Hit fields (scene triangle index or -1, t, u, v as bits; all 0 on a miss)
// and the ray's work counters (bvh::TraversalStats).
struct BatchResult {
  ivec4 hit;    // x = scene triangle index or -1, y/z/w = floatBitsToInt(t / u / v)
  uvec4 work;   // x = nodes visited, y = triangles tested
};
HP_CHECK_SIZE(BatchResult, 32);

// Counter buffer layout (uint pairs, low word then high word, added with carry).
#define HP_COUNTER_SHADOW_RAYS 0
#define HP_COUNTER_SHADOW_NODES 2
#define HP_COUNTER_SHADOW_TRIS 4
#define HP_COUNTER_REFL_RAYS 6
#define HP_COUNTER_REFL_NODES 8
#define HP_COUNTER_REFL_TRIS 10
#define HP_COUNTER_REFL_SHADOW_RAYS 12
#define HP_COUNTER_REPROJECT_MISPLACED 14  // compaction with write-back by reprojection: rays written elsewhere
#define HP_COUNTER_WORDS 16

// A material as the reflection pass reads it.
struct GpuMaterial {
  vec4 base_color_metallic;  // rgb, a = metallic
  vec4 roughness;            // x = roughness
};
HP_CHECK_SIZE(GpuMaterial, 32);

#ifdef __cplusplus
}  // namespace hp::gpu
#endif
#endif
