// triangle_count, world_bounds, world_geometry (scene order, transforms) and auto_frame.
#include "scene/load.hpp"
#include "scene/mesh_builders.hpp"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <cmath>

namespace hp {
namespace {

/// Two meshes (a triangle with material 1 and a quad with material 0) and three instances:
/// quad at +x 10, triangle scaled (2, 1, 1), quad again at -x 10.
Scene small_scene() {
  Scene s;
  s.materials = {Material{"a"}, Material{"b"}};
  Mesh tri;
  tri.name = "tri";
  tri.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  // A normal at 45 degrees in the xy plane: the inverse-transpose turns it differently from the positions.
  tri.normals.assign(3, glm::normalize(glm::vec3(1, 1, 0)));
  tri.indices = {0, 1, 2};
  tri.material = 1;
  Mesh quad = make_quad({0, 0, 0}, {1, 0, 0}, {0, 0, -1});
  quad.material = 0;
  s.meshes = {tri, quad};
  s.instances = {Instance{1, glm::translate(glm::mat4(1.0f), glm::vec3(10, 0, 0))},
                 Instance{0, glm::scale(glm::mat4(1.0f), glm::vec3(2, 1, 1))},
                 Instance{1, glm::translate(glm::mat4(1.0f), glm::vec3(-10, 0, 0))}};
  return s;
}

TEST(SceneFunctions, TriangleCountCountsEveryInstance) {
  const Scene s = small_scene();
  EXPECT_EQ(triangle_count(s), 2u + 1u + 2u);
  EXPECT_EQ(triangle_count(Scene{}), 0u);
}

TEST(SceneFunctions, WorldBoundsUseTransformedVertices) {
  const Aabb b = world_bounds(small_scene());
  EXPECT_FLOAT_EQ(b.min.x, -10.0f);
  EXPECT_FLOAT_EQ(b.max.x, 11.0f);
  EXPECT_FLOAT_EQ(b.min.y, 0.0f);
  EXPECT_FLOAT_EQ(b.max.y, 1.0f);
  EXPECT_FLOAT_EQ(b.min.z, -1.0f);
  EXPECT_FLOAT_EQ(b.max.z, 0.0f);
  EXPECT_TRUE(world_bounds(Scene{}).empty());
}

TEST(SceneFunctions, WorldGeometryIsInSceneOrder) {
  const Scene s = small_scene();
  const WorldGeometry g = world_geometry(s);
  ASSERT_EQ(g.triangle_count(), 5u);
  ASSERT_EQ(g.positions.size(), 4u + 3u + 4u);
  ASSERT_EQ(g.normals.size(), g.positions.size());
  EXPECT_EQ(g.instance, (std::vector<uint32_t>{0, 0, 1, 2, 2}));
  EXPECT_EQ(g.material, (std::vector<uint32_t>{0, 0, 1, 0, 0}));
  EXPECT_EQ(g.instance_first_triangle, (std::vector<uint32_t>{0, 2, 3, 5}));
  // Each instance's triangles in its mesh's index order, offset by the vertices before it.
  EXPECT_EQ(g.indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 4, 5, 6, 7, 8, 9, 7, 9, 10}));
  EXPECT_EQ(g.positions[0], glm::vec3(10, 0, 0));
  EXPECT_EQ(g.positions[5], glm::vec3(2, 0, 0));  // the triangle's (1,0,0) scaled by 2 in x
  EXPECT_EQ(g.positions[9], glm::vec3(-9, 0, -1));
  // Quad normals stay +y; the triangle's (1,1,0) under scale (2,1,1) becomes (1/2, 1, 0), normalised.
  const glm::vec3 expected = glm::normalize(glm::vec3(0.5f, 1.0f, 0.0f));
  for (int v = 4; v < 7; ++v) {
    EXPECT_NEAR(g.normals[v].x, expected.x, 1e-6f);
    EXPECT_NEAR(g.normals[v].y, expected.y, 1e-6f);
    EXPECT_NEAR(g.normals[v].z, 0.0f, 1e-6f);
  }
  for (const glm::vec3& n : g.normals) EXPECT_NEAR(glm::length(n), 1.0f, 1e-6f);
  // Still perpendicular to the transformed hypotenuse, from (2,0,0) to (0,1,0).
  EXPECT_NEAR(glm::dot(g.normals[4], glm::vec3(-2, 1, 0)), 0.0f, 1e-6f);
}

TEST(SceneFunctions, WorldGeometryOfEmptyScene) {
  const WorldGeometry g = world_geometry(Scene{});
  EXPECT_EQ(g.triangle_count(), 0u);
  EXPECT_EQ(g.instance_first_triangle, (std::vector<uint32_t>{0}));
}

/// Projects `p` with the camera: NDC x, y in [-1, 1] and view depth in [znear, zfar] means it is visible.
void expect_visible(const Camera& c, float aspect, const glm::vec3& p, const std::string& what) {
  const glm::mat4 view = glm::lookAt(c.position, c.target, c.up);
  const glm::mat4 proj = glm::perspective(glm::radians(c.vfov_deg), aspect, c.znear, c.zfar);
  const glm::vec4 v = view * glm::vec4(p, 1.0f);
  const float depth = -v.z;
  EXPECT_GT(depth, c.znear) << what;
  EXPECT_LT(depth, c.zfar) << what;
  const glm::vec4 clip = proj * v;
  EXPECT_LE(std::abs(clip.x / clip.w), 1.0f) << what << " aspect " << aspect;
  EXPECT_LE(std::abs(clip.y / clip.w), 1.0f) << what << " aspect " << aspect;
}

void expect_frames_all_corners(const Scene& s, const std::string& label) {
  const Aabb b = world_bounds(s);
  for (float aspect : {0.4f, 1.0f, 16.0f / 9.0f, 3.0f}) {
    const Camera c = auto_frame(s, aspect);
    EXPECT_GT(c.znear, 0.0f);
    EXPECT_LT(c.znear, c.zfar);
    for (int k = 0; k < 8; ++k) {
      const glm::vec3 corner((k & 1) ? b.max.x : b.min.x, (k & 2) ? b.max.y : b.min.y, (k & 4) ? b.max.z : b.min.z);
      expect_visible(c, aspect, corner, label + " corner " + std::to_string(k));
    }
    // A three-quarter view: not straight along an axis.
    const glm::vec3 d = glm::normalize(c.target - c.position);
    EXPECT_LT(std::abs(d.x), 0.95f);
    EXPECT_LT(std::abs(d.y), 0.95f);
    EXPECT_LT(std::abs(d.z), 0.95f);
  }
}

TEST(SceneFunctions, AutoFrameSeesTheWholeBounds) {
  expect_frames_all_corners(small_scene(), "small");
  expect_frames_all_corners(load_scene("builtin:cornell"), "cornell");
  expect_frames_all_corners(load_scene("builtin:pica"), "pica");
  // Long and thin, far from the origin.
  Scene thin;
  thin.meshes.push_back(make_box());
  thin.instances.push_back(
      {0, glm::scale(glm::translate(glm::mat4(1.0f), glm::vec3(500, -20, 3)), glm::vec3(100, 0.01f, 0.5f))});
  expect_frames_all_corners(thin, "thin");
}

TEST(SceneFunctions, AutoFrameOfDegenerateScenes) {
  // All vertices in one point: still a finite camera with znear < zfar.
  Scene point;
  Mesh m;
  m.positions.assign(3, glm::vec3(1, 2, 3));
  m.normals.assign(3, glm::vec3(0, 1, 0));
  m.indices = {0, 1, 2};
  point.meshes.push_back(m);
  point.instances.push_back({});
  const Camera c = auto_frame(point, 1.0f);
  EXPECT_TRUE(std::isfinite(c.position.x) && std::isfinite(c.znear) && std::isfinite(c.zfar));
  EXPECT_GT(c.znear, 0.0f);
  EXPECT_LT(c.znear, c.zfar);
  EXPECT_GT(glm::length(c.position - c.target), 0.0f);
  EXPECT_EQ(c.target, glm::vec3(1, 2, 3));
  // Empty scene: the default camera, no NaN.
  const Camera e = auto_frame(Scene{}, 1.0f);
  EXPECT_TRUE(std::isfinite(e.position.x));
}

}  // namespace
}  // namespace hp
