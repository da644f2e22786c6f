// The real glTF scenes (HP_SHARED_DIR/scenes, via hp_scene): SAH within 3% of the full sweep, and the
// traversal equal to brute force, for both granularities; the 8-wide traversal equal to the binary one on
// camera and random rays. Skipped when the folder is absent.
#include "bvh/traverse.hpp"
#include "bvh_test_scenes.hpp"
#include "checked_traversal.hpp"
#include "scene/load.hpp"
#include "scene/scene.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <random>

namespace hp::bvh {
namespace {

std::vector<std::string> shared_scene_files() {
  std::vector<std::string> files;
  const std::filesystem::path root = std::filesystem::path(HP_SHARED_DIR) / "scenes";
  if (!std::filesystem::is_directory(root)) return files;
  for (const auto& dir : std::filesystem::directory_iterator(root)) {
    if (!dir.is_directory()) continue;
    for (const auto& f : std::filesystem::directory_iterator(dir.path())) {
      if (f.path().extension() == ".gltf" || f.path().extension() == ".glb") files.push_back(f.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(BvhSharedScenes, SahWithinThreePercentAndTraversalMatchesBruteForce) {
  const auto files = shared_scene_files();
  if (files.empty()) GTEST_SKIP() << HP_SHARED_DIR << "/scenes not found";
  for (const auto& file : files) {
    const Scene scene = load_scene(file);
    const WorldGeometry world = world_geometry(scene);
    const std::vector<Triangle> tris = make_triangles(world.positions, world.indices);
    ASSERT_FALSE(tris.empty()) << file;
    BuildOptions sweep;
    sweep.full_sweep = true;
    const Bvh binned = build_bvh(tris, BuildOptions{});
    const double cb = bvh_stats(binned).sah_cost, cs = bvh_stats(build_bvh(tris, sweep)).sah_cost;
    EXPECT_LE(cb, 1.03 * cs) << file << ": binned " << cb << " vs sweep " << cs;

    // Rays from around the scene's box toward random points inside it.
    const Aabb box = world_bounds(scene);
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    std::vector<Ray> rays(300);
    for (auto& r : rays) {
      const glm::vec3 target = box.min + glm::vec3(u(rng), u(rng), u(rng)) * box.extent();
      r.origin = box.center() + testing::random_dir(rng) * glm::length(box.extent());
      r.dir = target - r.origin;
    }
    BuildOptions objects;
    objects.granularity = Granularity::object;
    const Bvh by_object = build_bvh(tris, objects, world.instance_first_triangle);
    const LeafOrderTriangles lt = leaf_order(binned, tris), olt = leaf_order(by_object, tris);
    std::size_t mismatches = 0, hits = 0;
    for (const Ray& r : rays) {
      const Hit want = brute_force_closest(tris, r);
      for (const Hit got : {intersect_closest(binned, lt, r), intersect_closest(by_object, olt, r)}) {
        mismatches += got.prim != want.prim || got.t != want.t;
      }
      mismatches += intersect_any(binned, lt, r).hit() != want.hit();
      mismatches += intersect_any(by_object, olt, r).hit() != want.hit();
      hits += want.hit();
    }
    EXPECT_EQ(mismatches, 0u) << file;
    EXPECT_GT(hits, 0u) << file;
  }
}

TEST(BvhSharedScenes, EightWideTraversalEqualsTheBinaryOne) {
  const auto files = shared_scene_files();
  if (files.empty()) GTEST_SKIP() << HP_SHARED_DIR << "/scenes not found";
  for (const auto& file : files) {
    const Scene scene = load_scene(file);
    const WorldGeometry world = world_geometry(scene);
    const std::vector<Triangle> tris = make_triangles(world.positions, world.indices);
    // Coherent camera rays (many grazing the same edges) and incoherent rays from inside the box.
    const Camera cam = scene.has_camera ? scene.camera : auto_frame(scene, 1.0f);
    std::vector<Ray> rays = pinhole_rays(cam.position, cam.target, cam.up, cam.vfov_deg, 160 * 160);
    const Aabb box = world_bounds(scene);
    std::mt19937 rng(6);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int i = 0; i < 20000; ++i) {
      Ray r;
      r.origin = box.min + glm::vec3(u(rng), u(rng), u(rng)) * box.extent();
      r.dir = testing::random_dir(rng);
      rays.push_back(r);
    }
    BuildOptions objects;
    objects.granularity = Granularity::object;
    for (const testing::Built& b :
         {testing::build(tris), testing::build(tris, objects, world.instance_first_triangle)}) {
      std::size_t hits = 0;
      for (const Ray& r : rays) {
        hits += testing::closest(b, r).hit();
        testing::any(b, r);
      }
      EXPECT_GT(hits, rays.size() / 10) << file;
    }
  }
}

}  // namespace
}  // namespace hp::bvh
