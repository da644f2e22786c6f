// Structure and quality of built trees: every primitive referenced once, boxes nested, the node layout the
// GPU relies on, the depth bound, SAH cost against the exact full sweep, option validation, determinism.
#include "bvh/bvh.hpp"
#include "bvh_test_scenes.hpp"
#include "error.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <functional>

namespace hp::bvh {
namespace {

using testing::exponential_clusters;
using testing::random_soup;
using testing::terrain;
using testing::uv_sphere;

bool contains(const gpu::BvhNode& outer, const glm::vec3& lo, const glm::vec3& hi) {
  return outer.bmin.x <= lo.x && outer.bmin.y <= lo.y && outer.bmin.z <= lo.z && outer.bmax.x >= hi.x &&
         outer.bmax.y >= hi.y && outer.bmax.z >= hi.z;
}

/// Checks every structural promise of build_bvh; returns the number of primitive references.
void check_structure(const Bvh& bvh, std::span<const Triangle> tris, int max_leaf, int max_depth) {
  ASSERT_FALSE(bvh.nodes.empty());
  std::vector<int> seen(bvh.prim_ids.size(), 0);
  int deepest = 0;
  // (node, depth, end of its subtree in the array: the depth-first layout must nest)
  std::function<uint32_t(uint32_t, int)> walk = [&](uint32_t i, int depth) -> uint32_t {
    EXPECT_LT(i, bvh.nodes.size());
    const gpu::BvhNode& n = bvh.nodes[i];
    if (node_is_leaf(n)) {
      deepest = std::max(deepest, depth);
      const uint32_t first = static_cast<uint32_t>(n.offset), count = node_count(n);
      EXPECT_LE(count, static_cast<uint32_t>(max_leaf));
      EXPECT_LE(first + count, bvh.prim_ids.size());
      for (uint32_t k = first; k < first + count && k < seen.size(); ++k) {
        ++seen[k];
        const uint32_t id = bvh.prim_ids[k];
        if (bvh.granularity == Granularity::triangle) {
          const Triangle& t = tris[id];
          const glm::vec3 lo = glm::min(t.v0, glm::min(t.v1, t.v2)), hi = glm::max(t.v0, glm::max(t.v1, t.v2));
          EXPECT_TRUE(contains(n, lo, hi)) << "leaf box misses triangle " << id;
        } else {
          for (uint32_t t = bvh.object_first[id]; t < bvh.object_first[id + 1]; ++t) {
            if (is_degenerate(tris[t])) continue;
            const Triangle& tr = tris[t];
            EXPECT_TRUE(contains(n, glm::min(tr.v0, glm::min(tr.v1, tr.v2)), glm::max(tr.v0, glm::max(tr.v1, tr.v2))));
          }
        }
      }
      return i + 1;
    }
    EXPECT_LT(node_axis(n), 3u);
    const uint32_t second = static_cast<uint32_t>(n.offset);
    EXPECT_TRUE(contains(n, bvh.nodes[i + 1].bmin, bvh.nodes[i + 1].bmax));
    EXPECT_TRUE(contains(n, bvh.nodes[second].bmin, bvh.nodes[second].bmax));
    const uint32_t end_first = walk(i + 1, depth + 1);
    EXPECT_EQ(end_first, second) << "the second child must follow the first child's subtree";
    return walk(second, depth + 1);
  };
  const uint32_t end = walk(0, 0);
  EXPECT_EQ(end, bvh.nodes.size()) << "unreachable nodes";
  EXPECT_EQ(deepest, bvh.max_depth);
  EXPECT_LE(deepest, max_depth);
  for (std::size_t k = 0; k < seen.size(); ++k) ASSERT_EQ(seen[k], 1) << "slot " << k;
  // prim_ids is a permutation of the valid primitives.
  std::vector<uint32_t> ids = bvh.prim_ids;
  std::sort(ids.begin(), ids.end());
  EXPECT_TRUE(std::adjacent_find(ids.begin(), ids.end()) == ids.end()) << "a primitive appears twice";
}

TEST(BvhBuild, StructureBinnedAndSweepBothGranularities) {
  const auto sphere = uv_sphere(60, 80).triangles();
  for (const bool sweep : {false, true}) {
    for (const int leaf : {1, 4, 7}) {
      BuildOptions o;
      o.full_sweep = sweep;
      o.max_leaf_size = leaf;
      const Bvh bvh = build_bvh(sphere, o);
      check_structure(bvh, sphere, leaf, HP_BVH_STACK_SIZE);
      EXPECT_EQ(bvh.prim_ids.size(), sphere.size());
      const BvhStats s = bvh_stats(bvh);
      EXPECT_EQ(s.nodes, bvh.nodes.size());
      EXPECT_EQ(s.primitives, sphere.size());
      EXPECT_EQ(s.leaves, (s.nodes + 1) / 2);
      EXPECT_EQ(s.max_depth, bvh.max_depth);
      std::size_t hist_leaves = 0, hist_prims = 0;
      for (std::size_t k = 0; k < s.leaf_size_histogram.size(); ++k) {
        hist_leaves += s.leaf_size_histogram[k];
        hist_prims += k * s.leaf_size_histogram[k];
      }
      EXPECT_EQ(hist_leaves, s.leaves);
      EXPECT_EQ(hist_prims, s.primitives);
    }
  }
  // Objects: 40 objects of uneven sizes over the same triangles.
  std::vector<uint32_t> first{0};
  for (uint32_t k = 1; first.back() < sphere.size(); ++k) {
    first.push_back(std::min<uint32_t>(static_cast<uint32_t>(sphere.size()), first.back() + 37 * (k % 9 + 1)));
  }
  for (const bool sweep : {false, true}) {
    BuildOptions o;
    o.granularity = Granularity::object;
    o.full_sweep = sweep;
    const Bvh bvh = build_bvh(sphere, o, first);
    check_structure(bvh, sphere, o.max_leaf_size, HP_BVH_STACK_SIZE);
    EXPECT_EQ(bvh.prim_ids.size(), first.size() - 1);
    const BvhStats s = bvh_stats(bvh);
    EXPECT_EQ(s.triangles, sphere.size());
    EXPECT_GT(s.sah_cost_triangles, s.sah_cost) << "objects hold several triangles each";
    const LeafOrderTriangles lt = leaf_order(bvh, sphere);
    EXPECT_EQ(lt.triangles.size(), sphere.size());
    EXPECT_EQ(lt.object_first.size(), first.size());
    for (std::size_t k = 0; k < lt.triangles.size(); ++k) {
      EXPECT_EQ(std::memcmp(&lt.triangles[k], &sphere[lt.scene_index[k]], sizeof(Triangle)), 0);
    }
  }
}

TEST(BvhBuild, LeafOrderTrianglesMatchPrimIds) {
  const auto tris = random_soup(5000, 11);
  const Bvh bvh = build_bvh(tris, BuildOptions{});
  const LeafOrderTriangles lt = leaf_order(bvh, tris);
  ASSERT_EQ(lt.triangles.size(), tris.size());
  EXPECT_TRUE(lt.object_first.empty());
  for (std::size_t k = 0; k < lt.triangles.size(); ++k) {
    EXPECT_EQ(lt.scene_index[k], bvh.prim_ids[k]);
    EXPECT_EQ(std::memcmp(&lt.triangles[k], &tris[bvh.prim_ids[k]], sizeof(Triangle)), 0);
  }
}

/// The binned build's SAH cost stays within 3% of the exact full sweep (the target).
TEST(BvhBuild, BinnedSahWithinThreePercentOfFullSweep) {
  struct Case {
    const char* name;
    std::vector<Triangle> tris;
  };
  std::vector<Case> cases;
  cases.push_back({"soup", random_soup(30000, 3)});
  cases.push_back({"sphere", uv_sphere(100, 150).triangles()});
  cases.push_back({"terrain", terrain(120).triangles()});
  cases.push_back({"clusters", exponential_clusters(-20, 20, 500, 5)});
  {
    // Several spheres of different sizes: a scene with large empty regions.
    std::vector<Triangle> t;
    for (int k = 0; k < 8; ++k) {
      const auto s = uv_sphere(30, 40, 0.3f + k * 0.4f, glm::vec3(k * 5.0f, (k % 3) * 2.0f, 0)).triangles();
      t.insert(t.end(), s.begin(), s.end());
    }
    cases.push_back({"spheres", std::move(t)});
  }
  for (const auto& c : cases) {
    for (const int buckets : {12, 32}) {
      BuildOptions binned;
      binned.buckets = buckets;
      BuildOptions sweep;
      sweep.full_sweep = true;
      const double cb = bvh_stats(build_bvh(c.tris, binned)).sah_cost;
      const double cs = bvh_stats(build_bvh(c.tris, sweep)).sah_cost;
      EXPECT_GT(cs, 1.0) << c.name;
      EXPECT_LE(cb, 1.03 * cs) << c.name << " buckets " << buckets << ": binned " << cb << " vs sweep " << cs;
    }
  }
}

TEST(BvhBuild, MoreBucketsDoNotMakeItMuchWorse) {
  // A sanity check that the bucket count is used at all: 2 buckets must be clearly worse than 32 on a
  // scene with structure.
  const auto tris = uv_sphere(80, 120).triangles();
  BuildOptions two;
  two.buckets = 2;
  BuildOptions many;
  many.buckets = 32;
  EXPECT_GT(bvh_stats(build_bvh(tris, two)).sah_cost, 1.02 * bvh_stats(build_bvh(tris, many)).sah_cost);
}

TEST(BvhBuild, SameTreeForAnyThreadCount) {
  const auto tris = terrain(200).triangles();  // 80k triangles: large enough to fork
  for (const bool sweep : {false, true}) {
    BuildOptions one;
    one.threads = 1;
    one.full_sweep = sweep;
    BuildOptions four = one;
    four.threads = 4;
    const Bvh a = build_bvh(tris, one), b = build_bvh(tris, four);
    ASSERT_EQ(a.nodes.size(), b.nodes.size());
    EXPECT_EQ(std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(gpu::BvhNode)), 0);
    EXPECT_EQ(a.prim_ids, b.prim_ids);
  }
}

// The phases of a two-thread build are those of its fork at the root: the two subtrees hold the root's two
// children, and the top, the longer subtree and the append fit inside the tree's time. One thread and the full
// sweep never fork, so only the references and the tree are timed.
TEST(BvhBuild, PhasesSayWhereTheWallTimeWent) {
  const auto tris = terrain(200).triangles();  // 80k triangles: the root's children are large enough to fork
  // With three threads the first child forks again at once: the phases stay the root's.
  for (const int threads : {2, 3}) {
    BuildOptions o;
    o.threads = threads;
    const Bvh b = build_bvh(tris, o);
    const BuildPhases& p = b.phases;
    ASSERT_TRUE(p.forked) << threads;
    // The first child's subtree is [1, root.offset) in the depth-first layout.
    std::size_t under_first = 0;
    for (int i = 1; i < b.nodes[0].offset; ++i) {
      if (node_is_leaf(b.nodes[i])) under_first += node_count(b.nodes[i]);
    }
    EXPECT_EQ(p.first_primitives, under_first) << threads;
    EXPECT_EQ(p.first_primitives + p.second_primitives, b.prim_ids.size()) << threads;
    EXPECT_GT(p.references_ms, 0.0) << threads;
    EXPECT_GT(p.top_ms, 0.0) << threads;
    EXPECT_GT(p.first_ms, 0.0) << threads;
    EXPECT_GT(p.second_ms, 0.0) << threads;
    EXPECT_GT(p.append_ms, 0.0) << threads;
    EXPECT_LE(p.top_ms + std::max(p.first_ms, p.second_ms) + p.append_ms, p.tree_ms) << threads;
  }

  for (const bool sweep : {false, true}) {
    BuildOptions o;
    o.threads = sweep ? 2 : 1;
    o.full_sweep = sweep;
    const BuildPhases q = build_bvh(tris, o).phases;
    EXPECT_FALSE(q.forked) << sweep;
    EXPECT_GT(q.references_ms, 0.0) << sweep;
    EXPECT_GT(q.tree_ms, 0.0) << sweep;
    EXPECT_EQ(q.top_ms + q.first_ms + q.second_ms + q.append_ms, 0.0) << sweep;
    EXPECT_EQ(q.first_primitives + q.second_primitives, 0u) << sweep;
  }
}

TEST(BvhBuild, InvalidOptionsAreInputErrors) {
  const auto tris = random_soup(100, 1);
  const auto bad = [&](auto change) {
    BuildOptions o;
    change(o);
    EXPECT_THROW(build_bvh(tris, o), InputError);
  };
  bad([](BuildOptions& o) { o.buckets = 1; });
  bad([](BuildOptions& o) { o.buckets = 5000; });
  bad([](BuildOptions& o) { o.max_leaf_size = 0; });
  bad([](BuildOptions& o) { o.max_depth = HP_BVH_STACK_SIZE + 1; });
  bad([](BuildOptions& o) { o.max_depth = 0; });
  bad([](BuildOptions& o) { o.traversal_cost = -1.0f; });
  bad([](BuildOptions& o) { o.threads = -2; });
  // 100 triangles cannot fit depth 3 with leaves of 4 (needs 5 levels): a clear error, not a deep tree.
  bad([](BuildOptions& o) { o.max_depth = 3; });
  // Object ranges: missing, not ending at the triangle count, decreasing; and given for triangles.
  BuildOptions obj;
  obj.granularity = Granularity::object;
  EXPECT_THROW(build_bvh(tris, obj), InputError);
  const std::vector<uint32_t> short_ranges{0, 50};
  EXPECT_THROW(build_bvh(tris, obj, short_ranges), InputError);
  const std::vector<uint32_t> decreasing{0, 60, 40, 100};
  EXPECT_THROW(build_bvh(tris, obj, decreasing), InputError);
  const std::vector<uint32_t> ok{0, 40, 100};
  EXPECT_NO_THROW(build_bvh(tris, obj, ok));
  EXPECT_THROW(build_bvh(tris, BuildOptions{}, ok), InputError);
}

TEST(BvhBuild, EmptyInputGivesOneEmptyNode) {
  const std::vector<Triangle> none;
  const Bvh bvh = build_bvh(none, BuildOptions{});
  ASSERT_EQ(bvh.nodes.size(), 1u);
  EXPECT_GT(bvh.nodes[0].bmin.x, bvh.nodes[0].bmax.x);
  EXPECT_TRUE(bvh.prim_ids.empty());
  EXPECT_EQ(bvh_stats(bvh).nodes, 0u);
}

TEST(BvhBuild, DegenerateCentroidRangeIsSplitByCount) {
  // 100 identical triangles: no spatial split exists, yet leaves must respect the maximum size.
  std::vector<Triangle> same(100, Triangle{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  for (const bool sweep : {false, true}) {
    BuildOptions o;
    o.full_sweep = sweep;
    const Bvh bvh = build_bvh(same, o);
    check_structure(bvh, same, o.max_leaf_size, HP_BVH_STACK_SIZE);
    EXPECT_EQ(bvh_stats(bvh).primitives, 100u);
    EXPECT_LE(bvh.max_depth, 5);  // a balanced count split: ceil(log2(100 / 4)) = 5
  }
}

}  // namespace
}  // namespace hp::bvh
