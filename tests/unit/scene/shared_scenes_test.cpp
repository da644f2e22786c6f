// Every real scene in ${HP_SHARED_DIR}/scenes loads, with the triangle count its README lists.
#include "scene/load.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

namespace hp {
namespace {

namespace fs = std::filesystem;

struct SharedScene {
  const char* folder;
  const char* file;
  std::size_t triangles;  ///< from ${HP_SHARED_DIR}/scenes/README.md
};

const SharedScene kScenes[] = {
    {"DamagedHelmet", "DamagedHelmet.gltf", 15'452},
    {"WaterBottle", "WaterBottle.gltf", 4'510},
    {"Balloon", "scene.gltf", 35'698},
    {"Pine", "scene.gltf", 1'650},
};

fs::path scenes_dir() { return fs::path(HP_SHARED_DIR) / "scenes"; }

class SharedScenes : public testing::TestWithParam<SharedScene> {};

TEST_P(SharedScenes, LoadsWithTheListedTriangleCount) {
  const SharedScene& p = GetParam();
  if (!fs::is_directory(scenes_dir()))
    GTEST_SKIP() << "shared scenes not found at " << scenes_dir() << " (set -DHP_SHARED_DIR=...)";
  const fs::path file = scenes_dir() / p.folder / p.file;
  ASSERT_TRUE(fs::exists(file)) << file;
  const Scene s = load_scene(file.string());
  EXPECT_EQ(triangle_count(s), p.triangles) << p.folder;
  const Aabb b = world_bounds(s);
  EXPECT_FALSE(b.empty());
  EXPECT_GT(b.area(), 0.0f);
  for (const Mesh& m : s.meshes) {
    ASSERT_EQ(m.normals.size(), m.positions.size()) << m.name;
    for (const glm::vec3& n : m.normals) ASSERT_NEAR(glm::length(n), 1.0f, 1e-3f) << m.name;
    ASSERT_LT(m.material, s.materials.size()) << m.name;
  }
  const WorldGeometry g = world_geometry(s);
  EXPECT_EQ(g.triangle_count(), p.triangles);
}

INSTANTIATE_TEST_SUITE_P(Readme, SharedScenes, testing::ValuesIn(kScenes),
                         [](const testing::TestParamInfo<SharedScene>& info) {
                           return std::string(info.param.folder);
                         });

TEST(SharedScenesFolder, EveryGltfInTheFolderIsListed) {
  if (!fs::is_directory(scenes_dir()))
    GTEST_SKIP() << "shared scenes not found at " << scenes_dir() << " (set -DHP_SHARED_DIR=...)";
  // A scene added to the folder without a count here would go untested.
  for (const auto& entry : fs::recursive_directory_iterator(scenes_dir())) {
    const auto ext = entry.path().extension();
    if (ext != ".gltf" && ext != ".glb") continue;
    bool listed = false;
    for (const SharedScene& s : kScenes) listed |= entry.path() == scenes_dir() / s.folder / s.file;
    EXPECT_TRUE(listed) << entry.path() << " is not in the README table of this test";
  }
}

}  // namespace
}  // namespace hp
