// The traversal against brute force: same closest hit (primitive and t, exactly), same any-hit answer,
// for both granularities and both builders, from the binary and the 8-wide traversal; counters; the batch
// helper.
#include "bvh/traverse.hpp"
#include "bvh_test_scenes.hpp"
#include "checked_traversal.hpp"

#include <gtest/gtest.h>

#include <cstring>

namespace hp::bvh {
namespace {

using testing::build;
using testing::Built;
using testing::random_rays;
using testing::random_soup;
using testing::terrain;
using testing::uv_sphere;

/// Compares every ray against brute force; returns the number of closest hits (so callers can check the
/// test was not vacuous).
std::size_t expect_matches_brute_force(const Built& b, std::span<const Triangle> tris, std::span<const Ray> rays) {
  std::size_t hits = 0, mismatches = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    const Hit want = brute_force_closest(tris, rays[i]);
    const Hit got = testing::closest(b, rays[i]);
    const bool any = testing::any(b, rays[i]).hit();
    if (want.prim != got.prim || (want.hit() && (want.t != got.t || want.u != got.u || want.v != got.v)) ||
        any != want.hit()) {
      if (++mismatches <= 5) {
        ADD_FAILURE() << "ray " << i << ": brute force prim " << want.prim << " t " << want.t << ", bvh prim "
                      << got.prim << " t " << got.t << ", any " << any;
      }
    }
    hits += want.hit();
  }
  EXPECT_EQ(mismatches, 0u);
  return hits;
}

TEST(BvhTraverse, RandomSceneMatchesBruteForce) {
  const auto tris = random_soup(4000, 7);
  const auto rays = random_rays(4000, 8, 12.0f);
  for (const bool sweep : {false, true}) {
    for (const int leaf : {1, 4, 8}) {
      BuildOptions o;
      o.full_sweep = sweep;
      o.max_leaf_size = leaf;
      const std::size_t hits = expect_matches_brute_force(build(tris, o), tris, rays);
      EXPECT_GT(hits, rays.size() / 10);
      EXPECT_LT(hits, rays.size());
    }
  }
}

TEST(BvhTraverse, ShortSegmentsAndTminMatchBruteForce) {
  // tmin/tmax cut the segment through the scene: closest and any-hit must respect both ends.
  const auto tris = random_soup(3000, 21);
  auto rays = random_rays(4000, 22, 12.0f);
  for (std::size_t i = 0; i < rays.size(); ++i) {
    rays[i].tmin = static_cast<float>(i % 7);
    rays[i].tmax = rays[i].tmin + static_cast<float>(i % 5) * 2.0f;
  }
  const std::size_t hits = expect_matches_brute_force(build(tris, BuildOptions{}), tris, rays);
  EXPECT_GT(hits, 100u);
}

TEST(BvhTraverse, ObjectGranularityMatchesBruteForce) {
  // Several meshes as objects, placed so that their boxes overlap heavily.
  std::vector<Triangle> tris;
  std::vector<uint32_t> first{0};
  for (int k = 0; k < 30; ++k) {
    const auto s = uv_sphere(8 + k % 5, 10 + k % 7, 0.5f + 0.1f * (k % 4),
                             glm::vec3((k % 5) * 0.8f, (k / 5) * 0.7f, (k % 3) * 0.9f))
                       .triangles();
    tris.insert(tris.end(), s.begin(), s.end());
    first.push_back(static_cast<uint32_t>(tris.size()));
  }
  std::vector<Ray> rays = random_rays(3000, 31, 4.0f);
  for (const bool sweep : {false, true}) {
    BuildOptions o;
    o.granularity = Granularity::object;
    o.full_sweep = sweep;
    o.max_leaf_size = 2;
    const std::size_t hits = expect_matches_brute_force(build(tris, o, first), tris, rays);
    EXPECT_GT(hits, rays.size() / 10);
  }
}

TEST(BvhTraverse, CountersAndPruning) {
  const auto mesh = terrain(100);
  const auto tris = mesh.triangles();
  const Built b = build(tris, BuildOptions{});
  // A ray straight down onto the terrain visits a handful of nodes and triangles, far fewer than exist.
  Ray down;
  down.origin = glm::vec3(37.3f, 100.0f, 61.7f);
  down.dir = glm::vec3(0, -1, 0);
  TraversalStats s;
  const Hit h = intersect_closest(b.bvh, b.lt, down, &s);
  ASSERT_TRUE(h.hit());
  EXPECT_GT(s.nodes_visited, 0u);
  EXPECT_GT(s.triangles_tested, 0u);
  EXPECT_LT(s.nodes_visited, 200u);
  EXPECT_LT(s.triangles_tested, 100u);
  // A grazing ray along the terrain benefits from t-max pruning: closest hit tests fewer triangles than a
  // traversal that must find every intersection would; any-hit stops at the first.
  Ray graze;
  graze.origin = glm::vec3(-1.0f, 0.0f, 50.0f);
  graze.dir = glm::normalize(glm::vec3(1.0f, 0.001f, 0.0f));
  TraversalStats sc, sa;
  const Hit hc = intersect_closest(b.bvh, b.lt, graze, &sc);
  const Hit ha = intersect_any(b.bvh, b.lt, graze, &sa);
  ASSERT_TRUE(hc.hit());
  ASSERT_TRUE(ha.hit());
  EXPECT_LE(sa.triangles_tested, sc.triangles_tested);
  Ray unbounded = graze;
  TraversalStats sfull;
  // The same ray with tmax at the first hit tests no more than the search did.
  unbounded.tmax = hc.t;
  intersect_closest(b.bvh, b.lt, unbounded, &sfull);
  EXPECT_LE(sfull.nodes_visited, sc.nodes_visited);
  // Brute force tests every triangle, the tree a small fraction on average.
  const auto rays = random_rays(2000, 5, 60.0f);
  TraversalStats total;
  for (auto r : rays) {
    r.origin += glm::vec3(50.0f, 0.0f, 50.0f);
    intersect_closest(b.bvh, b.lt, r, &total);
  }
  EXPECT_LT(total.triangles_tested, rays.size() * tris.size() / 50);
}

TEST(BvhTraverse, CastRaysEqualsSingleRays) {
  const auto tris = random_soup(3000, 41);
  const auto rays = random_rays(10000, 42, 12.0f);
  const Built b = build(tris, BuildOptions{});
  for (const HitMode mode : {HitMode::closest, HitMode::any}) {
    TraversalStats batch_stats, single_stats;
    const std::vector<Hit> hits = cast_rays(b.bvh, b.lt, rays, mode, 2, &batch_stats);
    ASSERT_EQ(hits.size(), rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i) {
      const Hit h = mode == HitMode::closest ? intersect_closest(b.bvh, b.lt, rays[i], &single_stats)
                                             : intersect_any(b.bvh, b.lt, rays[i], &single_stats);
      ASSERT_EQ(std::memcmp(&h, &hits[i], sizeof(Hit)), 0) << "ray " << i;
    }
    EXPECT_EQ(batch_stats.nodes_visited, single_stats.nodes_visited);
    EXPECT_EQ(batch_stats.triangles_tested, single_stats.triangles_tested);
  }
}

TEST(BvhTraverse, BarycentricsReconstructTheHitPoint) {
  const Triangle tri{{0, 0, 0}, {4, 0, 0}, {0, 2, 0}};
  Ray r;
  r.origin = glm::vec3(1.0f, 0.5f, 3.0f);
  r.dir = glm::vec3(0, 0, -1);
  Hit h;
  ASSERT_TRUE(intersect_triangle(r, tri, h));
  EXPECT_FLOAT_EQ(h.t, 3.0f);
  const glm::vec3 p = (1.0f - h.u - h.v) * tri.v0 + h.u * tri.v1 + h.v * tri.v2;
  EXPECT_NEAR(p.x, 1.0f, 1e-6f);
  EXPECT_NEAR(p.y, 0.5f, 1e-6f);
  // Both windings hit (no culling), and the range ends are inclusive.
  const Triangle flipped{tri.v0, tri.v2, tri.v1};
  ASSERT_TRUE(intersect_triangle(r, flipped, h));
  r.tmax = 3.0f;
  EXPECT_TRUE(intersect_triangle(r, tri, h));
  r.tmax = std::nextafter(3.0f, 0.0f);
  EXPECT_FALSE(intersect_triangle(r, tri, h));
  r.tmax = 10.0f;
  r.tmin = std::nextafter(3.0f, 4.0f);
  EXPECT_FALSE(intersect_triangle(r, tri, h));
}

TEST(BvhTraverse, InvalidRaysNeverHit) {
  const auto tris = random_soup(500, 3);
  const Built b = build(tris, BuildOptions{});
  const float nan = std::nanf("");
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<Ray> bad(5);
  bad[0].dir = glm::vec3(0.0f);
  bad[1].dir = glm::vec3(nan, 1, 0);
  bad[2].origin = glm::vec3(inf, 0, 0);
  bad[3].tmin = nan;
  bad[4].dir = glm::vec3(-0.0f, 0.0f, -0.0f);
  for (const Ray& r : bad) {
    EXPECT_FALSE(testing::closest(b, r).hit());
    EXPECT_FALSE(testing::any(b, r).hit());
    EXPECT_FALSE(brute_force_closest(tris, r).hit());
  }
}

}  // namespace
}  // namespace hp::bvh
