// The wide4 node layout (bvh/wide.hpp): its quantized boxes hold the binary boxes, its traversal gives the
// binary tree's answers (closest hit bit for bit, any hit or miss exactly) with fewer node visits, and the
// trees it cannot hold are refused with the limit named.
#include "bvh/wide.hpp"
#include "bvh_test_scenes.hpp"
#include "checked_traversal.hpp"
#include "error.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <string>

namespace hp::bvh {
namespace {

using testing::build;
using testing::Built;
using testing::random_rays;
using testing::random_soup;
using testing::terrain;
using testing::uv_sphere;

/// Every interior slot's decoded box must hold every binary box below it, so a binary node referenced by a
/// wide slot is found by walking the binary tree in the same slot order.
void expect_boxes_hold(const Bvh& bvh, const WideBvh& w) {
  std::size_t slots = 0, tight = 0;
  // Walk both trees together: wide node index -> the binary node it stands for.
  std::vector<std::pair<uint32_t, uint32_t>> todo{{0, 0}};
  while (!todo.empty()) {
    const auto [wi, p] = todo.back();
    todo.pop_back();
    const gpu::WideNode& n = w.nodes[wi];
    const gpu::BvhNode& pn = bvh.nodes[p];
    uint32_t bin[4] = {UINT32_MAX, UINT32_MAX, UINT32_MAX, UINT32_MAX};
    if (node_is_leaf(pn)) {
      bin[0] = p;
    } else {
      const uint32_t side[2] = {p + 1, static_cast<uint32_t>(pn.offset)};
      for (int s = 0; s < 2; ++s) {
        if (node_is_leaf(bvh.nodes[side[s]])) {
          bin[2 * s] = side[s];
        } else {
          bin[2 * s] = side[s] + 1;
          bin[2 * s + 1] = static_cast<uint32_t>(bvh.nodes[side[s]].offset);
        }
      }
    }
    for (int k = 0; k < 4; ++k) {
      if (bin[k] == UINT32_MAX) {
        EXPECT_EQ(n.w[3][k], 0u) << "wide node " << wi << " slot " << k << " should be empty";
        continue;
      }
      ++slots;
      const gpu::BvhNode& c = bvh.nodes[bin[k]];
      glm::vec3 lo, hi;
      wide_child_box(n, k, lo, hi);
      for (int a = 0; a < 3; ++a) {
        ASSERT_LE(lo[a], c.bmin[a]) << "wide node " << wi << " slot " << k << " axis " << a;
        ASSERT_GE(hi[a], c.bmax[a]) << "wide node " << wi << " slot " << k << " axis " << a;
      }
      // At most one step of the frame larger on each side (the quantization picks the tightest bounds).
      bool within = true;
      for (int a = 0; a < 3; ++a) {
        const float step = std::bit_cast<float>(((n.w[0].w >> (8 * a)) & 255u) << 23);
        within = within && c.bmin[a] - lo[a] <= step * 1.0001f && hi[a] - c.bmax[a] <= step * 1.0001f;
      }
      tight += within;
      if (node_is_leaf(c)) {
        const uint32_t word = n.w[3][k];
        EXPECT_NE(word & HP_WIDE_LEAF, 0u);
        EXPECT_EQ(word & HP_WIDE_FIRST_MASK, static_cast<uint32_t>(c.offset));
        EXPECT_EQ((word >> HP_WIDE_COUNT_SHIFT) & HP_WIDE_COUNT_MASK, node_count(c));
      } else {
        ASSERT_EQ(n.w[3][k] & HP_WIDE_LEAF, 0u);
        todo.emplace_back(n.w[3][k], bin[k]);
      }
    }
  }
  EXPECT_GT(slots, 0u);
  EXPECT_EQ(tight, slots);
}

TEST(BvhWide, QuantizedBoxesHoldTheBinaryBoxesTightly) {
  const auto sphere = uv_sphere(60, 80, 3.0f, glm::vec3(1e4f, -2.5f, 0.125f)).triangles();
  const auto soup = random_soup(3000, 3);
  const auto land = terrain(40).triangles();
  for (const auto* tris : {&sphere, &soup, &land}) {
    for (const int leaf : {1, 4, 15}) {
      BuildOptions o;
      o.max_leaf_size = leaf;
      const Bvh bvh = build_bvh(*tris, o);
      const WideBvh w = make_wide(bvh);
      expect_boxes_hold(bvh, w);
      EXPECT_GT(w.stack_need, 0);
      EXPECT_LE(w.stack_need, HP_BVH_STACK_SIZE);
      // A wide node stands for an interior binary node whose children are not both leaves, or the root.
      EXPECT_LT(w.nodes.size(), bvh.nodes.size() / 2);
    }
  }
}

TEST(BvhWide, SameAnswersAsTheBinaryTreeWithFewerNodeVisits) {
  const auto tris = random_soup(5000, 11);
  const auto rays = random_rays(5000, 12, 12.0f);
  for (const int leaf : {1, 4, 8}) {
    BuildOptions o;
    o.max_leaf_size = leaf;
    const Built b = build(tris, o);
    ASSERT_TRUE(b.wide4.has_value());
    TraversalStats bin, wide;
    std::size_t hits = 0;
    for (const Ray& r : rays) {
      // testing::closest and ::any compare the wide4 answers with the binary tree's.
      hits += testing::closest(b, r).hit();
      testing::any(b, r);
      intersect_closest(b.bvh, b.lt, r, &bin);
      intersect_closest(*b.wide4, b.lt, r, &wide);
    }
    EXPECT_GT(hits, rays.size() / 10);
    // A wide node replaces a binary node and up to two of its children; the triangles tested differ only
    // by the boxes' quantization and the pruning's timing.
    EXPECT_LT(wide.nodes_visited * 10, bin.nodes_visited * 7) << "leaf " << leaf;
    EXPECT_LT(wide.triangles_tested, bin.triangles_tested * 5 / 4) << "leaf " << leaf;
    // The batch helper gives the single rays' answers and counters.
    TraversalStats batch;
    const auto got = cast_rays(*b.wide4, b.lt, rays, HitMode::closest, 2, &batch);
    for (std::size_t i = 0; i < rays.size(); ++i) {
      ASSERT_TRUE(testing::same_bits(got[i], intersect_closest(*b.wide4, b.lt, rays[i]))) << "ray " << i;
    }
    EXPECT_EQ(batch.nodes_visited, wide.nodes_visited);
    EXPECT_EQ(batch.triangles_tested, wide.triangles_tested);
  }
}

TEST(BvhWide, ObjectLeavesAndTinyTrees) {
  // Object granularity: a leaf's objects are tested triangle by triangle, as in the binary tree.
  const auto tris = random_soup(1200, 5);
  std::vector<uint32_t> objects;
  for (uint32_t i = 0; i <= tris.size(); i += 7) objects.push_back(i);
  if (objects.back() != tris.size()) objects.push_back(static_cast<uint32_t>(tris.size()));
  BuildOptions o;
  o.granularity = Granularity::object;
  const Built b = build(tris, o, objects);
  ASSERT_TRUE(b.wide4.has_value());
  std::size_t hits = 0;
  for (const Ray& r : random_rays(2000, 6, 12.0f)) hits += testing::closest(b, r).hit() + testing::any(b, r).hit();
  EXPECT_GT(hits, 100u);

  // One triangle: the root is a leaf, one slot. No triangle: every ray misses at once.
  const std::vector<Triangle> one{{{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}}};
  const Built single = build(one);
  ASSERT_TRUE(single.wide4.has_value());
  ASSERT_EQ(single.wide4->nodes.size(), 1u);
  Ray r;
  r.origin = glm::vec3(0, 0, -5);
  r.dir = glm::vec3(0, 0, 1);
  EXPECT_TRUE(testing::closest(single, r).hit());
  EXPECT_TRUE(testing::any(single, r).hit());
  const Built none = build(std::vector<Triangle>{});
  ASSERT_TRUE(none.wide4.has_value());
  TraversalStats st;
  EXPECT_FALSE(intersect_closest(*none.wide4, none.lt, r, &st).hit());
  EXPECT_EQ(st.nodes_visited, 1u);
  EXPECT_EQ(st.triangles_tested, 0u);
}

TEST(BvhWide, RefusesLeavesOverFifteenAndTreesDeeperThanTheStack) {
  const auto tris = random_soup(400, 9);
  BuildOptions o;
  o.max_leaf_size = 16;
  o.traversal_cost = 50.0f;  // leaves as large as allowed
  try {
    make_wide(build_bvh(tris, o));
    ADD_FAILURE() << "a leaf of 16 was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("15"), std::string::npos) << e.what();
  }
  o.max_leaf_size = 15;
  EXPECT_NO_THROW(make_wide(build_bvh(tris, o)));

  // A hand-made chain (build_bvh never makes one): each wide node holds the next chain node and two copies
  // of the leaf, so it may push two entries; 70 binary levels need 70 entries.
  const auto chain_bvh = [](int chain) {
    Bvh bvh;
    for (int i = 0; i < chain; ++i) bvh.nodes.push_back(gpu::BvhNode{glm::vec3(-1), chain, glm::vec3(1), 0u});
    bvh.nodes.push_back(gpu::BvhNode{glm::vec3(-1), 0, glm::vec3(1), 1u << HP_BVH_AXIS_BITS});
    bvh.prim_ids = {0};
    return bvh;
  };
  try {
    make_wide(chain_bvh(HP_BVH_STACK_SIZE + 6));
    ADD_FAILURE() << "a tree over the stack was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("HP_BVH_STACK_SIZE"), std::string::npos) << e.what();
  }
  const Bvh fits = chain_bvh(HP_BVH_STACK_SIZE - 4);
  const WideBvh w = make_wide(fits);
  EXPECT_LE(w.stack_need, HP_BVH_STACK_SIZE);
  const std::vector<Triangle> tri{{{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}}};
  Ray r;
  r.origin = glm::vec3(0, 0, -5);
  r.dir = glm::vec3(0, 0, 1);
  EXPECT_TRUE(intersect_closest(w, leaf_order(fits, tri), r).hit());
}

}  // namespace
}  // namespace hp::bvh
