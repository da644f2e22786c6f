#include "scene/scene.hpp"

#include <glm/gtc/matrix_inverse.hpp>

#include <algorithm>
#include <cmath>

namespace hp {

std::size_t triangle_count(const Scene& scene) {
  std::size_t n = 0;
  for (const Instance& inst : scene.instances) n += scene.meshes.at(inst.mesh).triangle_count();
  return n;
}

Aabb world_bounds(const Scene& scene) {
  Aabb box;
  for (const Instance& inst : scene.instances) {
    const Mesh& mesh = scene.meshes.at(inst.mesh);
    // Transforming the mesh's object-space box would over-estimate under rotation; the vertices are exact.
    for (const glm::vec3& p : mesh.positions) box.grow(glm::vec3(inst.world * glm::vec4(p, 1.0f)));
  }
  return box;
}

Camera auto_frame(const Scene& scene, float aspect) {
  Camera cam;  // keeps the default vfov
  const Aabb box = world_bounds(scene);
  if (box.empty()) return cam;
  if (!(aspect > 0.0f) || !std::isfinite(aspect)) aspect = 1.0f;

  const glm::vec3 center = box.center();
  // The bounding sphere holds all 8 corners; fitting the sphere into the narrower of the two view cones
  // therefore fits the box for any view direction.
  float radius = 0.5f * glm::length(box.extent());
  // A single point (or a degenerate flat line) still needs a finite, positive distance.
  radius = std::max(radius, 1e-4f * (1.0f + glm::length(center)));

  const float half_v = glm::radians(cam.vfov_deg) * 0.5f;
  const float half_h = std::atan(std::tan(half_v) * aspect);
  const float half = std::min(half_v, half_h);
  // 5% margin so that the outermost geometry does not touch the image border.
  const float distance = 1.05f * radius / std::sin(half);

  // Three-quarter view: from the front right, above, like a product shot.
  const glm::vec3 dir = glm::normalize(glm::vec3(0.6f, 0.45f, 1.0f));
  cam.target = center;
  cam.position = center + dir * distance;
  cam.up = glm::vec3(0.0f, 1.0f, 0.0f);
  // Everything lies within [distance - radius, distance + radius] of the eye; leave slack on both sides so
  // depth precision is spent on the scene and nothing is clipped.
  cam.znear = std::max(0.5f * (distance - radius), 1e-4f * distance);
  cam.zfar = 1.5f * (distance + radius);
  return cam;
}

WorldGeometry world_geometry(const Scene& scene) {
  WorldGeometry g;
  std::size_t vertices = 0, triangles = 0;
  for (const Instance& inst : scene.instances) {
    vertices += scene.meshes.at(inst.mesh).positions.size();
    triangles += scene.meshes.at(inst.mesh).triangle_count();
  }
  g.positions.reserve(vertices);
  g.normals.reserve(vertices);
  g.indices.reserve(triangles * 3);
  g.material.reserve(triangles);
  g.instance.reserve(triangles);
  g.instance_first_triangle.reserve(scene.instances.size() + 1);

  for (std::size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    const Mesh& mesh = scene.meshes[inst.mesh];
    const auto base = static_cast<uint32_t>(g.positions.size());
    // Normals are covectors: the inverse-transpose keeps them perpendicular under non-uniform scale.
    const glm::mat3 normal_matrix = glm::inverseTranspose(glm::mat3(inst.world));
    for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
      g.positions.push_back(glm::vec3(inst.world * glm::vec4(mesh.positions[v], 1.0f)));
      const glm::vec3 n = normal_matrix * mesh.normals[v];
      const float len = glm::length(n);
      // A zero normal (degenerate input) must not become NaN downstream; +y is as good as any.
      g.normals.push_back(len > 0.0f && std::isfinite(len) ? n / len : glm::vec3(0.0f, 1.0f, 0.0f));
    }
    g.instance_first_triangle.push_back(static_cast<uint32_t>(g.indices.size() / 3));
    for (uint32_t idx : mesh.indices) g.indices.push_back(base + idx);
    g.material.insert(g.material.end(), mesh.triangle_count(), mesh.material);
    g.instance.insert(g.instance.end(), mesh.triangle_count(), static_cast<uint32_t>(i));
  }
  g.instance_first_triangle.push_back(static_cast<uint32_t>(g.indices.size() / 3));
  return g;
}

void transform_world(Scene& scene, Camera& camera, double scale, const glm::dvec3& translate) {
  glm::dmat4 m(scale);
  m[3] = glm::dvec4(translate, 1.0);
  for (Instance& inst : scene.instances) inst.world = glm::mat4(m * glm::dmat4(inst.world));
  const auto move = [&](const glm::vec3& p) { return glm::vec3(glm::dvec3(p) * scale + translate); };
  camera.position = move(camera.position);
  camera.target = move(camera.target);
  camera.znear = float(camera.znear * scale);
  camera.zfar = float(camera.zfar * scale);
  if (scene.has_camera) {
    scene.camera.position = move(scene.camera.position);
    scene.camera.target = move(scene.camera.target);
    scene.camera.znear = float(scene.camera.znear * scale);
    scene.camera.zfar = float(scene.camera.zfar * scale);
  }
}

}  // namespace hp
