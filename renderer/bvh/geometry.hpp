// The plain values the BVH works on: triangles, rays and hits. No scenes, no Vulkan.
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace hp::bvh {

/// One triangle by value: 9 floats, the same layout as one record of the triangle export file.
struct Triangle {
  glm::vec3 v0, v1, v2;
};
static_assert(sizeof(Triangle) == 36, "Triangle must be 9 packed floats");

/// A ray segment: hits are accepted for tmin <= t <= tmax (both ends included). Same field order as one
/// record of the ray file. The direction need not be normalised; t is measured in units of `dir`.
struct Ray {
  glm::vec3 origin{0.0f};
  float tmin = 0.0f;
  glm::vec3 dir{0.0f, 0.0f, 1.0f};
  float tmax = 3.402823466e+38f;
};
static_assert(sizeof(Ray) == 32, "Ray must be 8 packed floats");

/// A hit. `prim` is the triangle's index in scene order (the order given to the builder), -1 for a miss.
/// Barycentrics: point = (1 - u - v) * v0 + u * v1 + v * v2.
struct Hit {
  int32_t prim = -1;
  float t = 0.0f;
  float u = 0.0f;
  float v = 0.0f;

  bool hit() const { return prim >= 0; }
};
static_assert(sizeof(Hit) == 16, "Hit must be 4 packed 32-bit fields");

/// Triangles from an indexed mesh, in index order. Throws hp::InputError when the index count is not a
/// multiple of 3 or an index is out of range.
std::vector<Triangle> make_triangles(std::span<const glm::vec3> positions, std::span<const uint32_t> indices);

/// True for a triangle that can never be hit: a non-finite vertex, or zero area. Zero area is decided by
/// the cross product of two edges evaluated in double, which is exact for collinear float vertices of
/// similar magnitude, so "degenerate" means exactly collinear, not "thin". The builder leaves such
/// triangles out of the tree; the object granularity keeps them inside their objects, collapsed to a point
/// (see LeafOrderTriangles), where the watertight test rejects them exactly.
bool is_degenerate(const Triangle& tri);

/// `n` coherent primary rays of a pinhole camera at `eye` looking at `target` (vertical field of view
/// `vfov_deg`) over a square image of ceil(sqrt(n)) x ceil(sqrt(n)) pixels: one ray through each pixel
/// centre, row-major from the top left, cut at n. Used by `bvh --make-rays` and the BVH benchmark.
std::vector<Ray> pinhole_rays(glm::vec3 eye, glm::vec3 target, glm::vec3 up, float vfov_deg, uint32_t n);

}  // namespace hp::bvh
