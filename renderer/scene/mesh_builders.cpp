#include "scene/mesh_builders.hpp"

#include <glm/gtc/constants.hpp>

#include <cmath>
#include <stdexcept>

namespace hp {

Mesh make_quad(const glm::vec3& corner, const glm::vec3& u, const glm::vec3& v) {
  Mesh m;
  const glm::vec3 n = glm::normalize(glm::cross(u, v));
  m.positions = {corner, corner + u, corner + u + v, corner + v};
  m.normals.assign(4, n);
  m.indices = {0, 1, 2, 0, 2, 3};
  return m;
}

Mesh make_box() {
  Mesh m;
  m.name = "box";
  const glm::vec3 axes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int a = 0; a < 3; ++a) {
    for (float sign : {1.0f, -1.0f}) {
      const glm::vec3 n = axes[a] * sign;
      // u x v == n makes the quad counter-clockwise seen from outside.
      const glm::vec3 u = axes[(a + 1) % 3];
      const glm::vec3 v = glm::cross(n, u);
      const glm::vec3 c = 0.5f * n;
      const auto base = static_cast<uint32_t>(m.positions.size());
      for (const glm::vec3& p :
           {c - 0.5f * u - 0.5f * v, c + 0.5f * u - 0.5f * v, c + 0.5f * u + 0.5f * v, c - 0.5f * u + 0.5f * v}) {
        m.positions.push_back(p);
        m.normals.push_back(n);
      }
      for (uint32_t i : {0u, 1u, 2u, 0u, 2u, 3u}) m.indices.push_back(base + i);
    }
  }
  return m;
}

Mesh make_uv_sphere(uint32_t segments, uint32_t rings, float radius) {
  if (segments < 3 || rings < 2) throw std::invalid_argument("make_uv_sphere: needs segments >= 3, rings >= 2");
  Mesh m;
  m.name = "sphere";
  const std::size_t vertex_count = 2 + std::size_t(segments) * (rings - 1);
  m.positions.reserve(vertex_count);
  m.normals.reserve(vertex_count);
  m.indices.reserve(uv_sphere_triangles(segments, rings) * 3);

  // The seam is closed by wrapping the segment index instead of duplicating a column: without texture
  // coordinates there is nothing to split, and shared vertices keep the surface watertight.
  m.positions.push_back({0.0f, radius, 0.0f});
  m.normals.push_back({0.0f, 1.0f, 0.0f});
  std::vector<float> sin_t(segments), cos_t(segments);
  for (uint32_t j = 0; j < segments; ++j) {
    const double theta = 2.0 * glm::pi<double>() * j / segments;
    sin_t[j] = static_cast<float>(std::sin(theta));
    cos_t[j] = static_cast<float>(std::cos(theta));
  }
  for (uint32_t i = 1; i < rings; ++i) {
    const double phi = glm::pi<double>() * i / rings;
    const auto sp = static_cast<float>(std::sin(phi)), cp = static_cast<float>(std::cos(phi));
    for (uint32_t j = 0; j < segments; ++j) {
      const glm::vec3 n(sp * sin_t[j], cp, sp * cos_t[j]);
      m.positions.push_back(radius * n);
      m.normals.push_back(n);
    }
  }
  const auto south = static_cast<uint32_t>(m.positions.size());
  m.positions.push_back({0.0f, -radius, 0.0f});
  m.normals.push_back({0.0f, -1.0f, 0.0f});

  auto at = [segments](uint32_t ring, uint32_t seg) { return 1 + (ring - 1) * segments + seg % segments; };
  for (uint32_t j = 0; j < segments; ++j) m.indices.insert(m.indices.end(), {0u, at(1, j), at(1, j + 1)});
  for (uint32_t i = 1; i + 1 < rings; ++i) {
    for (uint32_t j = 0; j < segments; ++j) {
      const uint32_t a = at(i, j), b = at(i + 1, j), c = at(i + 1, j + 1), d = at(i, j + 1);
      m.indices.insert(m.indices.end(), {a, b, c, a, c, d});
    }
  }
  for (uint32_t j = 0; j < segments; ++j)
    m.indices.insert(m.indices.end(), {at(rings - 1, j), south, at(rings - 1, j + 1)});
  return m;
}

}  // namespace hp
