// The scene as the renderer and the BVH builder see it: plain data, no Vulkan, no file formats.
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace hp {

/// Axis-aligned box; empty when min > max on any axis.
struct Aabb {
  glm::vec3 min{std::numeric_limits<float>::infinity()};
  glm::vec3 max{-std::numeric_limits<float>::infinity()};

  void grow(const glm::vec3& p) {
    min = glm::min(min, p);
    max = glm::max(max, p);
  }
  void grow(const Aabb& b) {
    min = glm::min(min, b.min);
    max = glm::max(max, b.max);
  }
  bool empty() const { return min.x > max.x || min.y > max.y || min.z > max.z; }
  glm::vec3 extent() const { return empty() ? glm::vec3(0.0f) : max - min; }
  glm::vec3 center() const { return 0.5f * (min + max); }
  /// Surface area; 0 for an empty box.
  float area() const {
    const glm::vec3 e = extent();
    return 2.0f * (e.x * e.y + e.y * e.z + e.z * e.x);
  }
};

/// glTF pbrMetallicRoughness factors (textures are never decoded).
struct Material {
  std::string name;
  glm::vec3 base_color{0.8f};
  float metallic = 0.0f;
  float roughness = 0.5f;
};

/// One triangle mesh in its own object space.
struct Mesh {
  std::string name;
  std::vector<glm::vec3> positions;
  std::vector<glm::vec3> normals;  ///< same length as positions (computed when the file has none)
  std::vector<uint32_t> indices;   ///< 3 per triangle
  uint32_t material = 0;           ///< index into Scene::materials

  std::size_t triangle_count() const { return indices.size() / 3; }
};

/// A mesh placed in the world.
struct Instance {
  uint32_t mesh = 0;
  glm::mat4 world{1.0f};
};

/// Pinhole camera. `vfov_deg` is the vertical field of view.
struct Camera {
  glm::vec3 position{0.0f, 0.0f, 5.0f};
  glm::vec3 target{0.0f};
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float vfov_deg = 45.0f;
  float znear = 0.05f;
  float zfar = 1000.0f;
};

/// Directional light. `direction` points from the scene toward the light (normalised).
struct DirectionalLight {
  glm::vec3 direction = glm::normalize(glm::vec3(0.4f, 1.0f, 0.3f));
  glm::vec3 color{1.0f};
  float intensity = 3.0f;
};

struct Scene {
  std::string name;  ///< the spec it was loaded from ("builtin:pica", a path)
  std::vector<Material> materials;
  std::vector<Mesh> meshes;
  std::vector<Instance> instances;
  Camera camera;
  bool has_camera = false;  ///< false: frame the bounds automatically
  DirectionalLight light;
  glm::vec3 sky_color{0.55f, 0.70f, 0.95f};
};

/// Triangles over all instances (a mesh instanced twice counts twice).
std::size_t triangle_count(const Scene& scene);

/// World-space bounds over all instances.
Aabb world_bounds(const Scene& scene);

/// A camera that looks at the whole scene from a pleasing three-quarter view, for an image of the given
/// aspect ratio (width / height).
Camera auto_frame(const Scene& scene, float aspect);

/// Scales the whole world about the origin by `scale`, then translates it: every instance's transform (in
/// double, rounded to float once), the camera's position, target and clip planes. The image is the same up
/// to floating-point precision, which is what the numerical hard cases probe.
void transform_world(Scene& scene, Camera& camera, double scale, const glm::dvec3& translate);

/// The scene's triangles in world space, in "scene order": instances in order, each instance's triangles in
/// its mesh's index order. This order is the one `hybridprof bvh --export-triangles` writes and the one
/// primitive ids refer to everywhere outside the BVH.
struct WorldGeometry {
  std::vector<glm::vec3> positions;               ///< per vertex, world space
  std::vector<glm::vec3> normals;                 ///< per vertex, world space, normalised
  std::vector<uint32_t> indices;                  ///< 3 per triangle, into positions
  std::vector<uint32_t> material;                 ///< per triangle
  std::vector<uint32_t> instance;                 ///< per triangle: the instance it came from
  std::vector<uint32_t> instance_first_triangle;  ///< per instance: its first triangle (size instances+1)

  std::size_t triangle_count() const { return indices.size() / 3; }
};
WorldGeometry world_geometry(const Scene& scene);

}  // namespace hp
