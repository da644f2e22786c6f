// Built-in scenes: exact counts and bounds, mesh sanity, pica's variety, and cornell's documented geometry
// checked by casting rays against the world-space triangles.
#include "error.hpp"
#include "scene/builtin_scenes.hpp"
#include "scene/load.hpp"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <set>

namespace hp {
namespace {

void expect_near(const glm::vec3& a, const glm::vec3& b, float tol, const std::string& what = "") {
  EXPECT_NEAR(a.x, b.x, tol) << what;
  EXPECT_NEAR(a.y, b.y, tol) << what;
  EXPECT_NEAR(a.z, b.z, tol) << what;
}

/// Every mesh is well formed: matching lengths, indices in range, unit normals, nothing NaN, valid material.
void expect_well_formed(const Scene& s) {
  ASSERT_FALSE(s.instances.empty()) << s.name;
  for (const Instance& inst : s.instances) ASSERT_LT(inst.mesh, s.meshes.size()) << s.name;
  for (const Mesh& m : s.meshes) {
    ASSERT_EQ(m.normals.size(), m.positions.size()) << s.name << " " << m.name;
    ASSERT_EQ(m.indices.size() % 3, 0u) << m.name;
    ASSERT_LT(m.material, s.materials.size()) << m.name;
    bool finite = true, unit = true, in_range = true;
    for (const glm::vec3& p : m.positions) finite &= std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
    for (const glm::vec3& n : m.normals) unit &= std::abs(glm::length(n) - 1.0f) < 1e-4f;  // NaN fails too
    for (uint32_t i : m.indices) in_range &= i < m.positions.size();
    EXPECT_TRUE(finite) << s.name << " " << m.name;
    EXPECT_TRUE(unit) << s.name << " " << m.name;
    EXPECT_TRUE(in_range) << s.name << " " << m.name;
  }
  for (const Material& mat : s.materials) {
    EXPECT_GE(mat.roughness, 0.0f);
    EXPECT_LE(mat.roughness, 1.0f);
    EXPECT_GE(mat.metallic, 0.0f);
    EXPECT_LE(mat.metallic, 1.0f);
  }
  EXPECT_NEAR(glm::length(s.light.direction), 1.0f, 1e-5f) << s.name;
}

TEST(BuiltinScenes, NamesAndLoading) {
  EXPECT_EQ(builtin_scene_names(), (std::vector<std::string>{"pica", "cornell", "sphere-1m", "terrain-1m"}));
  for (const std::string& name : builtin_scene_names()) {
    const Scene s = load_scene("builtin:" + name);
    EXPECT_EQ(s.name, "builtin:" + name);
    EXPECT_TRUE(s.has_camera) << name;
  }
  EXPECT_THROW(load_scene("builtin:nope"), InputError);
  EXPECT_THROW(load_scene(""), InputError);
}

TEST(BuiltinScenes, ExactTriangleCounts) {
  // pica: 27 spheres of 48 x 24 (2,208 triangles each), 23 cubes (12 each), the floor (2).
  EXPECT_EQ(triangle_count(load_scene("builtin:pica")), 27u * 2208u + 23u * 12u + 2u);
  EXPECT_EQ(triangle_count(load_scene("builtin:pica")), 59'894u);
  EXPECT_EQ(triangle_count(load_scene("builtin:cornell")), cornell::kTriangles);
  EXPECT_EQ(cornell::kTriangles, 34u);
  const Scene sphere = load_scene("builtin:sphere-1m");
  EXPECT_EQ(triangle_count(sphere), 1'000'000u);
  EXPECT_EQ(sphere.meshes.at(0).positions.size(), 500'002u);
  const Scene terrain = load_scene("builtin:terrain-1m");
  EXPECT_EQ(triangle_count(terrain), 1'000'000u);
  EXPECT_EQ(terrain.meshes.at(0).positions.size(), 501'501u);
}

TEST(BuiltinScenes, Bounds) {
  const Aabb pica = world_bounds(load_scene("builtin:pica"));
  expect_near(pica.min, {-pica::kFloorHalfSize, 0.0f, -pica::kFloorHalfSize}, 1e-5f, "pica min");
  expect_near(pica.max, {pica::kFloorHalfSize, 2.6f, pica::kFloorHalfSize}, 1e-5f, "pica max");  // cube on block_1

  const Aabb cb = world_bounds(load_scene("builtin:cornell"));
  expect_near(cb.min, {-1, 0, -1}, 0.0f, "cornell min");
  expect_near(cb.max, {1, 2, 1}, 0.0f, "cornell max");

  const Aabb sb = world_bounds(load_scene("builtin:sphere-1m"));
  expect_near(sb.min, glm::vec3(-1.0f), 1e-5f, "sphere min");
  expect_near(sb.max, glm::vec3(1.0f), 1e-5f, "sphere max");

  const Aabb tb = world_bounds(load_scene("builtin:terrain-1m"));
  EXPECT_EQ(tb.min.x, -100.0f);
  EXPECT_EQ(tb.max.x, 100.0f);
  EXPECT_EQ(tb.min.z, -50.0f);
  EXPECT_EQ(tb.max.z, 50.0f);
  EXPECT_GE(tb.min.y, -terrain_1m::kMaxAbsHeight);
  EXPECT_LE(tb.max.y, terrain_1m::kMaxAbsHeight);
  EXPECT_GT(tb.max.y - tb.min.y, 5.0f) << "the terrain should not be flat";
}

TEST(BuiltinScenes, MeshesAreWellFormed) {
  for (const std::string& name : builtin_scene_names()) expect_well_formed(load_scene("builtin:" + name));
}

TEST(BuiltinScenes, GeneratedDeterministically) {
  for (const char* name : {"pica", "terrain-1m"}) {
    const WorldGeometry a = world_geometry(load_scene(std::string("builtin:") + name));
    const WorldGeometry b = world_geometry(load_scene(std::string("builtin:") + name));
    EXPECT_TRUE(a.positions == b.positions) << name;
    EXPECT_TRUE(a.indices == b.indices) << name;
  }
}

TEST(BuiltinScenes, TrianglesFaceOutward) {
  // Sphere: every face normal points away from the centre; terrain: every face points up.
  const WorldGeometry s = world_geometry(load_scene("builtin:sphere-1m"));
  std::size_t inward = 0;
  for (std::size_t t = 0; t < s.triangle_count(); ++t) {
    const glm::vec3 a = s.positions[s.indices[3 * t]], b = s.positions[s.indices[3 * t + 1]],
                    c = s.positions[s.indices[3 * t + 2]];
    if (glm::dot(glm::cross(b - a, c - a), a + b + c) <= 0.0f) ++inward;
  }
  EXPECT_EQ(inward, 0u);
  const WorldGeometry t = world_geometry(load_scene("builtin:terrain-1m"));
  std::size_t down = 0;
  for (std::size_t k = 0; k < t.triangle_count(); ++k) {
    const glm::vec3 a = t.positions[t.indices[3 * k]], b = t.positions[t.indices[3 * k + 1]],
                    c = t.positions[t.indices[3 * k + 2]];
    if (glm::cross(b - a, c - a).y <= 0.0f) ++down;
  }
  EXPECT_EQ(down, 0u);
}

TEST(BuiltinScenes, PicaHasAboutFiftyVariedObjects) {
  const Scene s = load_scene("builtin:pica");
  ASSERT_EQ(s.instances.size(), pica::kObjects + 1) << "fifty objects and the floor";
  std::size_t cubes = 0, spheres = 0, metals = 0, dielectrics = 0;
  float rmin = 1.0f, rmax = 0.0f;
  std::set<std::tuple<int, int, int>> colours;
  for (std::size_t i = 1; i < s.instances.size(); ++i) {
    const Mesh& m = s.meshes[s.instances[i].mesh];
    const Material& mat = s.materials[m.material];
    (m.triangle_count() == 12 ? cubes : spheres) += 1;
    (mat.metallic > 0.5f ? metals : dielectrics) += 1;
    rmin = std::min(rmin, mat.roughness);
    rmax = std::max(rmax, mat.roughness);
    colours.insert({int(mat.base_color.r * 20), int(mat.base_color.g * 20), int(mat.base_color.b * 20)});
    // Everything stands on (or above) the floor and inside it.
    const Aabb b = [&] {
      Aabb box;
      for (const glm::vec3& p : m.positions) box.grow(glm::vec3(s.instances[i].world * glm::vec4(p, 1.0f)));
      return box;
    }();
    EXPECT_GE(b.min.y, -1e-4f) << m.name;
    EXPECT_LT(std::max(std::abs(b.min.x), std::abs(b.max.x)), pica::kFloorHalfSize) << m.name;
  }
  EXPECT_GE(cubes, 15u);
  EXPECT_GE(spheres, 15u);
  EXPECT_GE(metals, 10u);
  EXPECT_GE(dielectrics, 10u);
  EXPECT_LE(rmin, 0.05f);
  EXPECT_GE(rmax, 0.85f);
  EXPECT_GE(colours.size(), 20u);
  // The floor: large, low roughness, slightly metallic.
  const Material& floor = s.materials[s.meshes[s.instances[0].mesh].material];
  EXPECT_LT(floor.roughness, 0.2f);
  EXPECT_GT(floor.metallic, 0.0f);
  EXPECT_LT(floor.metallic, 0.5f);
  // The light is above the horizon, so shadows fall on the floor.
  EXPECT_GT(s.light.direction.y, 0.3f);
}

// ---- Cornell box --------------------------------------------------------------------------------------------

struct Hit {
  float t;
  std::size_t triangle;
};

/// Closest hit over every triangle (Moller-Trumbore): brute force is fine for 34 triangles and keeps the
/// test independent of the BVH.
std::optional<Hit> closest_hit(const WorldGeometry& g, const glm::vec3& o, const glm::vec3& d) {
  std::optional<Hit> best;
  for (std::size_t t = 0; t < g.triangle_count(); ++t) {
    const glm::vec3 a = g.positions[g.indices[3 * t]], b = g.positions[g.indices[3 * t + 1]],
                    c = g.positions[g.indices[3 * t + 2]];
    const glm::vec3 e1 = b - a, e2 = c - a, p = glm::cross(d, e2);
    const float det = glm::dot(e1, p);
    if (std::abs(det) < 1e-12f) continue;
    const glm::vec3 s = o - a;
    const float u = glm::dot(s, p) / det;
    if (u < 0.0f || u > 1.0f) continue;
    const glm::vec3 q = glm::cross(s, e1);
    const float v = glm::dot(d, q) / det;
    if (v < 0.0f || u + v > 1.0f) continue;
    const float dist = glm::dot(e2, q) / det;
    if (dist > 1e-4f && (!best || dist < best->t)) best = Hit{dist, t};
  }
  return best;
}

std::string mesh_of_triangle(const Scene& s, const WorldGeometry& g, std::size_t t) {
  return s.meshes[s.instances[g.instance[t]].mesh].name;
}

TEST(Cornell, WallsLieOnTheDocumentedPlanesFacingInward) {
  const Scene s = load_scene("builtin:cornell");
  struct Wall {
    const char* name;
    int axis;
    float value;
    glm::vec3 normal;
    const char* material;
  };
  const Wall walls[] = {{"floor", 1, cornell::kFloorY, {0, 1, 0}, "white"},
                        {"ceiling", 1, cornell::kCeilingY, {0, -1, 0}, "white"},
                        {"back", 2, cornell::kBackZ, {0, 0, 1}, "white"},
                        {"left", 0, cornell::kLeftX, {1, 0, 0}, "red"},
                        {"right", 0, cornell::kRightX, {-1, 0, 0}, "green"}};
  for (const Wall& w : walls) {
    const auto it = std::find_if(s.meshes.begin(), s.meshes.end(), [&](const Mesh& m) { return m.name == w.name; });
    ASSERT_NE(it, s.meshes.end()) << w.name;
    EXPECT_EQ(it->triangle_count(), 2u) << w.name;
    EXPECT_EQ(s.materials[it->material].name, w.material);
    Aabb box;
    for (const glm::vec3& p : it->positions) {
      EXPECT_EQ(p[w.axis], w.value) << w.name;
      box.grow(p);
    }
    // Each wall spans the full box on its other two axes.
    for (int a = 0; a < 3; ++a) {
      if (a == w.axis) continue;
      EXPECT_EQ(box.min[a], a == 1 ? 0.0f : -1.0f) << w.name;
      EXPECT_EQ(box.max[a], a == 1 ? 2.0f : 1.0f) << w.name;
    }
    for (const glm::vec3& n : it->normals) EXPECT_EQ(n, w.normal) << w.name;
    // The winding agrees with the normal (counter-clockwise seen from inside).
    for (std::size_t t = 0; t < it->indices.size(); t += 3) {
      const glm::vec3 a = it->positions[it->indices[t]], b = it->positions[it->indices[t + 1]],
                      c = it->positions[it->indices[t + 2]];
      EXPECT_GT(glm::dot(glm::cross(b - a, c - a), w.normal), 0.0f) << w.name;
    }
  }
  // Nothing closes the front.
  for (const glm::vec3& p : world_geometry(s).positions) EXPECT_LE(p.z, cornell::kOpenZ);
}

TEST(Cornell, BoxesStandOnTheFloorInsideTheWalls) {
  const Scene s = load_scene("builtin:cornell");
  const WorldGeometry g = world_geometry(s);
  // Instances 5 and 6 are the tall and the short box.
  const float heights[2] = {cornell::kTallSize[1], cornell::kShortSize[1]};
  for (int k = 0; k < 2; ++k) {
    Aabb b;
    const uint32_t inst = 5 + k;
    for (uint32_t t = g.instance_first_triangle[inst]; t < g.instance_first_triangle[inst + 1]; ++t)
      for (int v = 0; v < 3; ++v) b.grow(g.positions[g.indices[3 * t + v]]);
    EXPECT_NEAR(b.min.y, 0.0f, 1e-6f);
    EXPECT_NEAR(b.max.y, heights[k], 1e-6f);
    EXPECT_GT(b.min.x, -1.0f);
    EXPECT_LT(b.max.x, 1.0f);
    EXPECT_GT(b.min.z, -1.0f);
    EXPECT_LT(b.max.z, 1.0f);
    // Out of the documented clear slab |x| <= 0.1.
    EXPECT_TRUE(b.max.x < -cornell::kClearSlabHalfWidth || b.min.x > cornell::kClearSlabHalfWidth) << k;
  }
}

TEST(Cornell, CameraAndLightAreAsDocumented) {
  const Scene s = load_scene("builtin:cornell");
  EXPECT_TRUE(s.has_camera);
  EXPECT_EQ(s.camera.position, glm::vec3(0, 1, 3.5f));
  EXPECT_EQ(s.camera.target, glm::vec3(0, 1, 0));
  EXPECT_EQ(s.camera.up, glm::vec3(0, 1, 0));
  EXPECT_EQ(s.camera.vfov_deg, 40.0f);
  EXPECT_EQ(s.camera.znear, 0.1f);
  EXPECT_EQ(s.camera.zfar, 20.0f);
  expect_near(s.light.direction, glm::normalize(glm::vec3(0.3f, 0.2f, 1.0f)), 1e-6f);
}

TEST(Cornell, CentreRayHitsTheBackWallUnobstructed) {
  const Scene s = load_scene("builtin:cornell");
  const WorldGeometry g = world_geometry(s);
  const auto hit = closest_hit(g, s.camera.position, glm::normalize(s.camera.target - s.camera.position));
  ASSERT_TRUE(hit);
  EXPECT_EQ(mesh_of_triangle(s, g, hit->triangle), "back");
  EXPECT_NEAR(hit->t, 4.5f, 1e-5f);
}

TEST(Cornell, DocumentedClearRegionsAreSeenDirectly) {
  const Scene s = load_scene("builtin:cornell");
  const WorldGeometry g = world_geometry(s);
  struct Probe {
    glm::vec3 point;
    const char* wall;
  };
  std::vector<Probe> probes;
  // The slab |x| <= 0.1 on the back wall, floor and ceiling.
  for (float x : {-0.1f, 0.0f, 0.1f}) {
    for (float y : {0.05f, 0.5f, 1.0f, 1.8f, 1.95f}) probes.push_back({{x, y, -1.0f}, "back"});
    for (float z : {-0.95f, -0.5f, 0.0f, 0.6f}) {
      probes.push_back({{x, 0.0f, z}, "floor"});
      probes.push_back({{x, 2.0f, z}, "ceiling"});
    }
  }
  // The right wall above the short box, the left wall in front of the tall box.
  for (float z : {-0.95f, 0.0f, 0.9f})
    for (float y : {0.6f, 1.0f, 1.9f}) probes.push_back({{1.0f, y, z}, "right"});
  for (float z : {0.1f, 0.5f, 0.9f})
    for (float y : {0.05f, 1.0f, 1.9f}) probes.push_back({{-1.0f, y, z}, "left"});

  for (const Probe& p : probes) {
    const glm::vec3 d = p.point - s.camera.position;
    const auto hit = closest_hit(g, s.camera.position, glm::normalize(d));
    ASSERT_TRUE(hit) << p.wall;
    EXPECT_EQ(mesh_of_triangle(s, g, hit->triangle), p.wall)
        << "(" << p.point.x << ", " << p.point.y << ", " << p.point.z << ")";
    EXPECT_NEAR(hit->t, glm::length(d), 1e-4f) << p.wall;
  }
  // Sanity check that the probes can fail: a point behind the tall box is occluded by it.
  const glm::vec3 hidden(-0.45f, 0.3f, -1.0f);
  const auto hit = closest_hit(g, s.camera.position, glm::normalize(hidden - s.camera.position));
  ASSERT_TRUE(hit);
  EXPECT_EQ(mesh_of_triangle(s, g, hit->triangle), "box");
}

TEST(Cornell, BackWallCentreIsLit) {
  const Scene s = load_scene("builtin:cornell");
  const WorldGeometry g = world_geometry(s);
  EXPECT_FALSE(closest_hit(g, glm::vec3(0, 1, -1), s.light.direction)) << "the shadow ray must leave the box";
  // Documented: the back wall is lit below y = 1.6; above, the ceiling is in the way.
  EXPECT_FALSE(closest_hit(g, glm::vec3(0, 1.55f, -1), s.light.direction));
  EXPECT_TRUE(closest_hit(g, glm::vec3(0, 1.65f, -1), s.light.direction));
  // And the tall box does cast a shadow: a floor point just behind it (away from the light) is shadowed.
  EXPECT_TRUE(closest_hit(g, glm::vec3(-0.6f, 0.0f, -0.9f), s.light.direction));
}

}  // namespace
}  // namespace hp
