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

// ---------------------------------------------------------------------------------------------------------
// Frame-wide constants (uniform buffer, std140-compatible: only vec4/mat4 members).
struct FrameUniforms {
  mat4 view_proj;
  mat4 inv_view_proj;
  vec4 camera_pos;       // xyz, w unused
  vec4 light_dir;        // xyz toward the light (normalised), w = intensity
  vec4 light_color;      // rgb, a unused
  vec4 sky_color;        // rgb, a unused
  uvec4 extent;          // width, height, frame index, flags
  vec4 params;           // x = reversed-Z (1/0), y = near, z = far, w unused
};
HP_CHECK_SIZE(FrameUniforms, 224);
HP_CHECK_LAYOUT(FrameUniforms, inv_view_proj, 64);
HP_CHECK_LAYOUT(FrameUniforms, camera_pos, 128);
HP_CHECK_LAYOUT(FrameUniforms, extent, 192);

// Per-draw push constants of the G-buffer pass: exactly the 128 bytes every Vulkan device guarantees.
struct GBufferPush {
  mat4 world;
  vec4 normal_row0;  // rows of the inverse-transpose of world's 3x3 in xyz; w = base colour r, g, b
  vec4 normal_row1;
  vec4 normal_row2;
  vec4 material;     // x = metallic, y = roughness, z = material index, w unused
};
HP_CHECK_SIZE(GBufferPush, 128);

#ifdef __cplusplus
}  // namespace hp::gpu
#endif
#endif
