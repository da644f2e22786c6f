#include "bvh/geometry.hpp"

#include "error.hpp"

#include <cmath>
#include <string>

namespace hp::bvh {

std::vector<Triangle> make_triangles(std::span<const glm::vec3> positions, std::span<const uint32_t> indices) {
  if (indices.size() % 3 != 0) {
    throw InputError("triangle indices: count " + std::to_string(indices.size()) + " is not a multiple of 3");
  }
  std::vector<Triangle> tris(indices.size() / 3);
  for (std::size_t t = 0; t < tris.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = indices[3 * t + k];
      if (i >= positions.size()) {
        throw InputError("triangle indices: index " + std::to_string(i) + " of triangle " + std::to_string(t) +
                         " is out of range (" + std::to_string(positions.size()) + " positions)");
      }
    }
    tris[t] = Triangle{positions[indices[3 * t]], positions[indices[3 * t + 1]], positions[indices[3 * t + 2]]};
  }
  return tris;
}

bool is_degenerate(const Triangle& tri) {
  for (const glm::vec3* v : {&tri.v0, &tri.v1, &tri.v2}) {
    if (!std::isfinite(v->x) || !std::isfinite(v->y) || !std::isfinite(v->z)) return true;
  }
  // Differences of floats and products of those differences are exact (or nearly) in double, so a zero
  // here means the vertices are collinear, not merely close.
  const glm::dvec3 e1 = glm::dvec3(tri.v1) - glm::dvec3(tri.v0);
  const glm::dvec3 e2 = glm::dvec3(tri.v2) - glm::dvec3(tri.v0);
  const glm::dvec3 n = glm::cross(e1, e2);
  return n.x == 0.0 && n.y == 0.0 && n.z == 0.0;
}

std::vector<Ray> pinhole_rays(glm::vec3 eye, glm::vec3 target, glm::vec3 up_hint, float vfov_deg, uint32_t n) {
  const uint32_t side = uint32_t(std::ceil(std::sqrt(double(n))));
  const glm::vec3 fwd = glm::normalize(target - eye);
  const glm::vec3 right = glm::normalize(glm::cross(fwd, up_hint));
  const glm::vec3 up = glm::cross(right, fwd);
  const float h = std::tan(glm::radians(vfov_deg) * 0.5f);
  std::vector<Ray> rays;
  rays.reserve(n);
  for (uint32_t i = 0; i < n; ++i) {
    const float sx = (2.0f * (float(i % side) + 0.5f) / float(side) - 1.0f) * h;
    const float sy = (1.0f - 2.0f * (float(i / side) + 0.5f) / float(side)) * h;
    Ray r;
    r.origin = eye;
    r.dir = glm::normalize(fwd + sx * right + sy * up);
    rays.push_back(r);
  }
  return rays;
}

}  // namespace hp::bvh
