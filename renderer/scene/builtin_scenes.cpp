#include "scene/builtin_scenes.hpp"

#include "scene/mesh_builders.hpp"

#include <glm/gtc/constants.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <array>
#include <cmath>

namespace hp {
namespace {

glm::vec3 v3(const float (&a)[3]) { return {a[0], a[1], a[2]}; }

uint32_t add_material(Scene& s, std::string name, glm::vec3 color, float metallic, float roughness) {
  s.materials.push_back(Material{std::move(name), color, metallic, roughness});
  return static_cast<uint32_t>(s.materials.size() - 1);
}

uint32_t add_mesh(Scene& s, Mesh mesh, std::string name, uint32_t material) {
  mesh.name = std::move(name);
  mesh.material = material;
  s.meshes.push_back(std::move(mesh));
  return static_cast<uint32_t>(s.meshes.size() - 1);
}

void add_instance(Scene& s, uint32_t mesh, const glm::mat4& world) { s.instances.push_back(Instance{mesh, world}); }

/// world = T * Ry * S: the placement every box and sphere in the built-in scenes uses.
glm::mat4 place(const glm::vec3& center, float yaw_deg, const glm::vec3& size) {
  glm::mat4 m = glm::translate(glm::mat4(1.0f), center);
  m = glm::rotate(m, glm::radians(yaw_deg), glm::vec3(0.0f, 1.0f, 0.0f));
  return glm::scale(m, size);
}

/// SplitMix64: a tiny, fully specified generator, so the layout is the same on every platform
/// (std::uniform_real_distribution is not specified bit-exactly).
struct Rng {
  uint64_t state;
  uint64_t next() {
    uint64_t z = (state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  float uniform() { return static_cast<float>(next() >> 40) * (1.0f / 16777216.0f); }  // [0, 1)
  float range(float lo, float hi) { return lo + (hi - lo) * uniform(); }
};

/// Saturated colour from a hue in [0, 1) (HSV with S = 0.75, V = 0.9).
glm::vec3 hue_color(float h) {
  const glm::vec3 k = glm::abs(glm::fract(glm::vec3(h) + glm::vec3(1.0f, 2.0f / 3.0f, 1.0f / 3.0f)) * 6.0f - 3.0f);
  const glm::vec3 rgb = glm::clamp(k - 1.0f, 0.0f, 1.0f);
  return 0.9f * glm::mix(glm::vec3(1.0f), rgb, 0.75f);
}

}  // namespace

std::vector<std::string> builtin_names() { return {"pica", "cornell", "sphere-1m", "terrain-1m"}; }

std::optional<Scene> make_builtin_scene(const std::string& name) {
  if (name == "pica") return make_pica_scene();
  if (name == "cornell") return make_cornell_scene();
  if (name == "sphere-1m") return make_sphere_1m_scene();
  if (name == "terrain-1m") return make_terrain_1m_scene();
  return std::nullopt;
}

// ---------------------------------------------------------------------------------------------------------
// builtin:pica. Layout (floor y = 0, camera looking toward -z):
//   z = -4     a wall of four large blocks, one carrying a small cube
//   z = -1.6   8 metal spheres, roughness 0.02 -> 0.9 from left to right
//   z = -0.3   8 dielectric spheres of different hues, roughness 0.02 -> 0.9
//   x = +-6    two large spheres (a mirror and a rough ceramic) and two stacks of three rotated cubes,
//              plus a third stack at the back left
//   front      an arc of 18 small cubes and spheres with seeded colours, roughness and metalness
// The light comes from the front left and high, so every object throws a shadow back and to the right
// where the raised camera sees it.
Scene make_pica_scene() {
  Scene s;
  s.name = "builtin:pica";
  const Mesh box = make_box();
  const Mesh sphere = make_uv_sphere(pica::kSphereSegments, pica::kSphereRings, 1.0f);
  std::size_t objects = 0;
  auto add_box = [&](const std::string& name, glm::vec3 color, float metallic, float roughness, glm::vec3 center,
                     float yaw, glm::vec3 size) {
    const uint32_t mat = add_material(s, name, color, metallic, roughness);
    add_instance(s, add_mesh(s, box, name, mat), place(center, yaw, size));
    ++objects;
  };
  auto add_sphere = [&](const std::string& name, glm::vec3 color, float metallic, float roughness, glm::vec3 center,
                        float radius) {
    const uint32_t mat = add_material(s, name, color, metallic, roughness);
    add_instance(s, add_mesh(s, sphere, name, mat), place(center, 0.0f, glm::vec3(radius)));
    ++objects;
  };

  // A low-roughness, slightly metallic floor: the surface the reflection pass is about.
  {
    const float h = pica::kFloorHalfSize;
    const uint32_t mat = add_material(s, "floor", glm::vec3(0.62f, 0.62f, 0.66f), 0.2f, 0.08f);
    add_instance(s, add_mesh(s, make_quad({-h, 0.0f, h}, {2 * h, 0.0f, 0.0f}, {0.0f, 0.0f, -2 * h}), "floor", mat),
                 glm::mat4(1.0f));
  }

  // Roughness sweeps: the same sphere at eight roughness values, once metallic, once dielectric.
  const std::array<glm::vec3, 4> metals = {glm::vec3(1.00f, 0.78f, 0.34f), glm::vec3(0.95f, 0.64f, 0.54f),
                                           glm::vec3(0.97f, 0.96f, 0.91f), glm::vec3(0.91f, 0.92f, 0.92f)};
  for (int i = 0; i < 8; ++i) {
    const float rough = 0.02f + (0.9f - 0.02f) * static_cast<float>(i) / 7.0f;
    const float x = -4.2f + 1.2f * static_cast<float>(i);
    add_sphere("metal_sphere_" + std::to_string(i), metals[i % 4], 1.0f, rough, {x, 0.45f, -1.6f}, 0.45f);
    add_sphere("plastic_sphere_" + std::to_string(i), hue_color(static_cast<float>(i) / 8.0f), 0.0f, rough,
               {x, 0.45f, -0.3f}, 0.45f);
  }

  // Back wall of blocks, and one small cube resting on the second block.
  add_box("block_0", {0.85f, 0.30f, 0.25f}, 0.0f, 0.55f, {-5.0f, 0.9f, -4.2f}, 10.0f, glm::vec3(1.8f));
  add_box("block_1", {0.25f, 0.45f, 0.85f}, 0.0f, 0.25f, {-1.9f, 1.0f, -4.4f}, -20.0f, glm::vec3(2.0f));
  add_box("block_2", {0.95f, 0.93f, 0.88f}, 1.0f, 0.15f, {1.5f, 0.8f, -4.1f}, 35.0f, glm::vec3(1.6f));
  add_box("block_3", {0.95f, 0.80f, 0.20f}, 0.0f, 0.7f, {4.6f, 0.95f, -4.3f}, 5.0f, glm::vec3(1.9f));
  add_box("block_1_top", {0.20f, 0.75f, 0.45f}, 0.0f, 0.35f, {-1.9f, 2.3f, -4.4f}, 25.0f, glm::vec3(0.6f));

  // Two large spheres that dominate the sides: a mirror and a rough ceramic.
  add_sphere("mirror_sphere", {0.97f, 0.97f, 0.97f}, 1.0f, 0.02f, {-6.0f, 1.1f, -1.4f}, 1.1f);
  add_sphere("ceramic_sphere", {0.90f, 0.45f, 0.20f}, 0.0f, 0.9f, {6.0f, 1.1f, -1.4f}, 1.1f);

  // Stacks: each cube turned further than the one below, like a staircase of rotations.
  const std::array<glm::vec2, 3> stacks = {glm::vec2(-6.4f, 1.2f), glm::vec2(6.4f, 1.2f), glm::vec2(-7.6f, -4.0f)};
  const std::array<float, 3> sizes = {0.9f, 0.7f, 0.5f};
  for (int k = 0; k < 3; ++k) {
    float y = 0.0f;
    for (int level = 0; level < 3; ++level) {
      const float size = sizes[level];
      const float metallic = (k + level) % 2 == 0 ? 0.0f : 1.0f;
      const float rough = 0.1f + 0.35f * static_cast<float>(level) + 0.05f * static_cast<float>(k);
      add_box("stack_" + std::to_string(k) + "_" + std::to_string(level),
              hue_color(0.13f + 0.29f * static_cast<float>(k * 3 + level)), metallic, rough,
              {stacks[k].x, y + 0.5f * size, stacks[k].y}, 15.0f * static_cast<float>(level) + 10.0f * k,
              glm::vec3(size));
      y += size;
    }
  }

  // The front arc: seeded sizes, colours and materials, alternating cube / sphere.
  Rng rng{0x9151ca9151caull};
  for (int i = 0; i < 18; ++i) {
    const float a = glm::radians(-60.0f + 120.0f * static_cast<float>(i) / 17.0f);
    const glm::vec3 p(5.6f * std::sin(a) + rng.range(-0.08f, 0.08f), 0.0f,
                      -1.0f + 5.6f * std::cos(a) + rng.range(-0.08f, 0.08f));
    const glm::vec3 color = hue_color(rng.uniform());
    const float metallic = rng.uniform() < 0.4f ? 1.0f : 0.0f;
    const float rough = rng.range(0.02f, 0.9f);
    const std::string name = "arc_" + std::to_string(i);
    if (i % 2 == 0) {
      const float size = rng.range(0.35f, 0.55f);
      add_box(name + "_cube", color, metallic, rough, {p.x, 0.5f * size, p.z}, rng.range(0.0f, 90.0f), glm::vec3(size));
    } else {
      const float r = rng.range(0.18f, 0.3f);
      add_sphere(name + "_sphere", color, metallic, rough, {p.x, r, p.z}, r);
    }
  }
  (void)objects;  // == pica::kObjects; the tests check it through the instance list

  s.camera.position = {0.0f, 5.5f, 12.5f};
  s.camera.target = {0.0f, 0.6f, -1.2f};
  s.camera.vfov_deg = 45.0f;
  s.camera.znear = 0.1f;
  s.camera.zfar = 100.0f;
  s.has_camera = true;
  s.light.direction = glm::normalize(glm::vec3(-0.5f, 0.75f, 0.4f));
  return s;
}

// ---------------------------------------------------------------------------------------------------------
// builtin:cornell: see the geometry block in builtin_scenes.hpp; every number here comes from there.
Scene make_cornell_scene() {
  using namespace cornell;
  Scene s;
  s.name = "builtin:cornell";
  const uint32_t white = add_material(s, "white", {0.73f, 0.73f, 0.73f}, 0.0f, 0.9f);
  const uint32_t red = add_material(s, "red", {0.63f, 0.065f, 0.05f}, 0.0f, 0.9f);
  const uint32_t green = add_material(s, "green", {0.14f, 0.45f, 0.091f}, 0.0f, 0.9f);

  const float w = kRightX - kLeftX, h = kCeilingY - kFloorY, d = kOpenZ - kBackZ;
  // make_quad's normal is cross(u, v): each (u, v) pair below is ordered so that it points into the box.
  const glm::mat4 id(1.0f);
  add_instance(s, add_mesh(s, make_quad({kLeftX, kFloorY, kOpenZ}, {w, 0, 0}, {0, 0, -d}), "floor", white), id);
  add_instance(s, add_mesh(s, make_quad({kLeftX, kCeilingY, kBackZ}, {w, 0, 0}, {0, 0, d}), "ceiling", white), id);
  add_instance(s, add_mesh(s, make_quad({kLeftX, kFloorY, kBackZ}, {w, 0, 0}, {0, h, 0}), "back", white), id);
  add_instance(s, add_mesh(s, make_quad({kLeftX, kFloorY, kBackZ}, {0, h, 0}, {0, 0, d}), "left", red), id);
  add_instance(s, add_mesh(s, make_quad({kRightX, kFloorY, kOpenZ}, {0, h, 0}, {0, 0, -d}), "right", green), id);

  // One cube mesh instanced twice: the scene also exercises instancing (a mesh counted once per instance).
  const uint32_t box = add_mesh(s, make_box(), "box", white);
  add_instance(s, box, place(v3(kTallCenter), kTallYawDeg, v3(kTallSize)));
  add_instance(s, box, place(v3(kShortCenter), kShortYawDeg, v3(kShortSize)));

  s.camera.position = v3(kCameraPosition);
  s.camera.target = v3(kCameraTarget);
  s.camera.up = {0.0f, 1.0f, 0.0f};
  s.camera.vfov_deg = kCameraVfovDeg;
  s.camera.znear = kCameraZnear;
  s.camera.zfar = kCameraZfar;
  s.has_camera = true;
  s.light.direction = glm::normalize(v3(kLightDirection));
  return s;
}

// ---------------------------------------------------------------------------------------------------------
Scene make_sphere_1m_scene() {
  using namespace sphere_1m;
  Scene s;
  s.name = "builtin:sphere-1m";
  const uint32_t mat = add_material(s, "sphere", {0.8f, 0.55f, 0.35f}, 0.0f, 0.4f);
  add_instance(s, add_mesh(s, make_uv_sphere(kSegments, kRings, kRadius), "sphere-1m", mat), glm::mat4(1.0f));
  s.camera.position = {0.0f, 1.2f, 3.2f};
  s.camera.target = {0.0f, 0.0f, 0.0f};
  s.camera.vfov_deg = 45.0f;
  s.camera.znear = 0.05f;
  s.camera.zfar = 20.0f;
  s.has_camera = true;
  return s;
}

// ---------------------------------------------------------------------------------------------------------
namespace {

/// Lattice value in [-1, 1] from a hash of (x, z, octave, seed).
float lattice(int64_t x, int64_t z, uint64_t salt) {
  Rng r{static_cast<uint64_t>(x) * 0x8da6b343ull ^ static_cast<uint64_t>(z) * 0xd8163841ull ^ salt};
  return 2.0f * r.uniform() - 1.0f;
}

/// Value noise with smoothstep interpolation; |result| <= 1.
float value_noise(float x, float z, uint64_t salt) {
  const float fx = std::floor(x), fz = std::floor(z);
  const auto ix = static_cast<int64_t>(fx), iz = static_cast<int64_t>(fz);
  float tx = x - fx, tz = z - fz;
  tx = tx * tx * (3.0f - 2.0f * tx);
  tz = tz * tz * (3.0f - 2.0f * tz);
  const float a = lattice(ix, iz, salt), b = lattice(ix + 1, iz, salt);
  const float c = lattice(ix, iz + 1, salt), d = lattice(ix + 1, iz + 1, salt);
  return glm::mix(glm::mix(a, b, tx), glm::mix(c, d, tx), tz);
}

/// fBm amplitudes 6 + 3 + 1.5 + 0.75 + 0.375 = 11.625, ridge 2: |height| <= 13.625 < kMaxAbsHeight.
float terrain_height(float x, float z) {
  float h = 0.0f, amp = 6.0f, freq = 1.0f / 40.0f;
  for (uint64_t octave = 0; octave < 5; ++octave) {
    h += amp * value_noise(x * freq, z * freq, terrain_1m::kSeed + octave * 0x51ed27ull);
    amp *= 0.5f;
    freq *= 2.0f;
  }
  return h + 2.0f * std::sin(0.05f * x + 0.03f * z);
}

}  // namespace

Scene make_terrain_1m_scene() {
  using namespace terrain_1m;
  Scene s;
  s.name = "builtin:terrain-1m";
  const uint32_t mat = add_material(s, "terrain", {0.36f, 0.42f, 0.27f}, 0.0f, 0.85f);

  constexpr uint32_t nx = kQuadsX + 1, nz = kQuadsZ + 1;
  const float x0 = -0.5f * kQuadsX * kCellSize, z0 = -0.5f * kQuadsZ * kCellSize;
  Mesh m;
  m.positions.resize(std::size_t(nx) * nz);
  m.normals.resize(m.positions.size());
  for (uint32_t j = 0; j < nz; ++j) {
    for (uint32_t i = 0; i < nx; ++i) {
      // Edges are computed from the index, not accumulated, so the bounds are exactly +-100 and +-50.
      const float x = i == kQuadsX ? -x0 : x0 + kCellSize * static_cast<float>(i);
      const float z = j == kQuadsZ ? -z0 : z0 + kCellSize * static_cast<float>(j);
      m.positions[std::size_t(j) * nx + i] = {x, terrain_height(x, z), z};
    }
  }
  // Normals from central differences of the grid (one-sided at the border): cheap and matches the mesh.
  auto y = [&](uint32_t i, uint32_t j) { return m.positions[std::size_t(j) * nx + i].y; };
  for (uint32_t j = 0; j < nz; ++j) {
    for (uint32_t i = 0; i < nx; ++i) {
      const uint32_t il = i > 0 ? i - 1 : i, ir = i + 1 < nx ? i + 1 : i;
      const uint32_t jd = j > 0 ? j - 1 : j, ju = j + 1 < nz ? j + 1 : j;
      const float dydx = (y(ir, j) - y(il, j)) / (kCellSize * static_cast<float>(ir - il));
      const float dydz = (y(i, ju) - y(i, jd)) / (kCellSize * static_cast<float>(ju - jd));
      m.normals[std::size_t(j) * nx + i] = glm::normalize(glm::vec3(-dydx, 1.0f, -dydz));
    }
  }
  m.indices.reserve(std::size_t(kTriangles) * 3);
  for (uint32_t j = 0; j < kQuadsZ; ++j) {
    for (uint32_t i = 0; i < kQuadsX; ++i) {
      const uint32_t a = j * nx + i, b = a + 1, c = a + nx, d = c + 1;
      // Counter-clockwise seen from above (+y): a(x,z) -> c(x,z+1) -> b(x+1,z) turns left around +y.
      m.indices.insert(m.indices.end(), {a, c, b, b, c, d});
    }
  }
  add_instance(s, add_mesh(s, std::move(m), "terrain-1m", mat), glm::mat4(1.0f));

  s.camera.position = {-70.0f, 45.0f, 80.0f};
  s.camera.target = {0.0f, 0.0f, 0.0f};
  s.camera.vfov_deg = 45.0f;
  s.camera.znear = 0.5f;
  s.camera.zfar = 500.0f;
  s.has_camera = true;
  s.light.direction = glm::normalize(glm::vec3(0.6f, 0.5f, -0.3f));
  return s;
}

}  // namespace hp
