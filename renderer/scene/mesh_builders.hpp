// Procedural meshes shared by the built-in scenes. Every builder produces counter-clockwise front faces
// seen from the side the normals point to (the glTF convention), and normals of unit length.
#pragma once

#include "scene/scene.hpp"

#include <cstdint>

namespace hp {

/// A parallelogram with corners `corner`, `corner+u`, `corner+u+v`, `corner+v`: 4 vertices, 2 triangles,
/// flat normal normalize(cross(u, v)).
Mesh make_quad(const glm::vec3& corner, const glm::vec3& u, const glm::vec3& v);

/// The cube [-0.5, 0.5]^3 with flat faces: 24 vertices, 12 triangles.
Mesh make_box();

/// A UV sphere of the given radius centred at the origin, one vertex per pole, `segments` around the
/// y axis and `rings` bands from pole to pole: 2 + segments*(rings-1) vertices and
/// 2*segments*(rings-1) triangles. Requires segments >= 3, rings >= 2.
Mesh make_uv_sphere(uint32_t segments, uint32_t rings, float radius);

/// Triangles of make_uv_sphere without building it.
constexpr uint64_t uv_sphere_triangles(uint64_t segments, uint64_t rings) { return 2 * segments * (rings - 1); }

}  // namespace hp
