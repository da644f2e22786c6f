// The wide4 node layout (bvh/wide.hpp): its quantized boxes hold the binary boxes, its traversal gives the
// binary tree's answers (closest hit bit for bit, any hit or miss exactly) with fewer node visits, and the
// trees it cannot hold are refused with the limit named.
#include "bvh/wide.hpp"
#include "bvh_test_scenes.hpp"
#include "checked_traversal.hpp"
#include "error.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace hp::bvh {
namespace {

using testing::build;
using testing::Built;
using testing::random_rays;
using testing::random_soup;
using testing::terrain;
using testing::uv_sphere;

/// Half a box's area, the SAH's measure.
double half_area(const gpu::BvhNode& c) {
  const glm::dvec3 e = glm::dvec3(c.bmax) - glm::dvec3(c.bmin);
  return e.x * e.y + e.y * e.z + e.z * e.x;
}

/// The wide tree checked against the binary one without knowing how make_wide chose its slots. Each binary
/// node covers a range of leaf slots [lo, hi) (the depth-first layout makes it contiguous, and distinct per
/// node), so a wide slot is named by the range it covers: a leaf word by its own, an interior slot by its
/// wide node's. Checked: each wide node's slots form a cut of its binary node's subtree (strict descendants,
/// left to right, covering the range), every slot's decoded box holds its binary node's box within one
/// quantization step, leaf words say the binary leaf, and each octant's visiting order is the binary
/// traversal's (at the slots' lowest common ancestor, the second child first where the ray is negative on its
/// axis), empty slots last. Returns the sum of the wide nodes' binary box areas (the wide tree's SAH cost).
double expect_wide_matches(const Bvh& bvh, const WideBvh& w) {
  const std::size_t nb = bvh.nodes.size();
  std::vector<uint32_t> lo(nb), hi(nb), parent(nb, UINT32_MAX), depth(nb, 0);
  for (std::size_t i = 0; i < nb; ++i) {
    const gpu::BvhNode& n = bvh.nodes[i];
    if (node_is_leaf(n)) continue;
    parent[i + 1] = parent[n.offset] = static_cast<uint32_t>(i);
    depth[i + 1] = depth[n.offset] = depth[i] + 1;
  }
  for (std::size_t i = nb; i-- > 0;) {
    const gpu::BvhNode& n = bvh.nodes[i];
    if (node_is_leaf(n)) {
      lo[i] = static_cast<uint32_t>(n.offset), hi[i] = lo[i] + node_count(n);
    } else {
      EXPECT_EQ(hi[i + 1], lo[n.offset]) << "binary node " << i << ": its children's leaf ranges are not adjacent";
      lo[i] = lo[i + 1], hi[i] = hi[n.offset];
    }
  }
  std::map<std::pair<uint32_t, uint32_t>, uint32_t> by_range;
  for (std::size_t i = 0; i < nb; ++i) by_range.emplace(std::pair{lo[i], hi[i]}, static_cast<uint32_t>(i));
  // The range each wide node covers, children first (they come after their parent).
  std::vector<std::pair<uint32_t, uint32_t>> wide_range(w.nodes.size(), {UINT32_MAX, 0});
  const auto slot_range = [&](const gpu::WideNode& n, int k) {
    const uint32_t word = n.w[3][k];
    if ((word & HP_WIDE_LEAF) == 0) return wide_range[word];
    const uint32_t first = word & HP_WIDE_FIRST_MASK;
    return std::pair{first, first + ((word >> HP_WIDE_COUNT_SHIFT) & HP_WIDE_COUNT_MASK)};
  };
  for (std::size_t i = w.nodes.size(); i-- > 0;) {
    for (int k = 0; k < 4; ++k) {
      if (w.nodes[i].w[3][k] == 0) continue;
      const auto r = slot_range(w.nodes[i], k);
      wide_range[i].first = std::min(wide_range[i].first, r.first);
      wide_range[i].second = std::max(wide_range[i].second, r.second);
    }
  }
  const auto binary_of = [&](std::pair<uint32_t, uint32_t> r) {
    const auto it = by_range.find(r);
    return it == by_range.end() ? UINT32_MAX : it->second;
  };
  double cost = 0;
  std::size_t slots = 0, tight = 0;
  for (std::size_t wi = 0; wi < w.nodes.size(); ++wi) {
    const gpu::WideNode& n = w.nodes[wi];
    const uint32_t p = binary_of(wide_range[wi]);
    if (wi == 0 && nb == 1) {  // the root leaf alone: one slot, the node stands for it
      EXPECT_EQ(p, 0u);
    } else {
      EXPECT_NE(p, UINT32_MAX) << "wide node " << wi << " covers no binary node's range";
      if (p == UINT32_MAX) continue;
      cost += half_area(bvh.nodes[p]);
    }
    uint32_t bin[4] = {UINT32_MAX, UINT32_MAX, UINT32_MAX, UINT32_MAX};
    uint32_t next = lo[p];
    bool empty_seen = false;
    for (int k = 0; k < 4; ++k) {
      if (n.w[3][k] == 0) {
        empty_seen = true;
        continue;
      }
      EXPECT_FALSE(empty_seen) << "wide node " << wi << ": an occupied slot after an empty one";
      const auto r = slot_range(n, k);
      bin[k] = binary_of(r);
      EXPECT_NE(bin[k], UINT32_MAX) << "wide node " << wi << " slot " << k << " is no binary node";
      if (bin[k] == UINT32_MAX) continue;
      EXPECT_EQ(r.first, next) << "wide node " << wi << " slot " << k << ": not the next part of the cut";
      next = r.second;
      EXPECT_TRUE(bin[k] != p || nb == 1) << "wide node " << wi << " slot " << k << " is its own node";
      ++slots;
      const gpu::BvhNode& c = bvh.nodes[bin[k]];
      glm::vec3 blo, bhi;
      wide_child_box(n, k, blo, bhi);
      bool holds = true;
      for (int a = 0; a < 3; ++a) holds = holds && blo[a] <= c.bmin[a] && bhi[a] >= c.bmax[a];
      EXPECT_TRUE(holds) << "wide node " << wi << " slot " << k << ": the box does not hold binary node " << bin[k];
      // At most one step of the frame larger on each side (the quantization picks the tightest bounds).
      bool within = true;
      for (int a = 0; a < 3; ++a) {
        const float step = std::bit_cast<float>(((n.w[0].w >> (8 * a)) & 255u) << 23);
        within = within && c.bmin[a] - blo[a] <= step * 1.0001f && bhi[a] - c.bmax[a] <= step * 1.0001f;
      }
      tight += within;
      const uint32_t word = n.w[3][k];
      EXPECT_EQ((word & HP_WIDE_LEAF) != 0, node_is_leaf(c)) << "wide node " << wi << " slot " << k;
    }
    EXPECT_EQ(next, hi[p]) << "wide node " << wi << ": the slots do not cover its binary node";
    // The visiting order per octant.
    for (uint32_t octant = 0; octant < 8; ++octant) {
      int want[4] = {0, 1, 2, 3};
      const auto before = [&](int a, int b) {
        if (bin[a] == UINT32_MAX || bin[b] == UINT32_MAX) return bin[a] != UINT32_MAX && bin[b] == UINT32_MAX;
        uint32_t x = bin[a], y = bin[b];
        while (depth[x] > depth[y]) x = parent[x];
        while (depth[y] > depth[x]) y = parent[y];
        uint32_t xc = x;  // a's side: the child of the common ancestor above a
        while (x != y) xc = x, x = parent[x], y = parent[y];
        const bool a_first_child = xc == x + 1;
        const bool second_first = ((octant >> node_axis(bvh.nodes[x])) & 1u) != 0;
        return a_first_child != second_first;
      };
      std::stable_sort(want, want + 4, before);
      const uint32_t got = (n.w[2][2 + octant / 4] >> (8 * (octant % 4))) & 255u;
      for (int pos = 0; pos < 4; ++pos) {
        EXPECT_EQ((got >> (2 * pos)) & 3u, static_cast<uint32_t>(want[pos]))
            << "wide node " << wi << " octant " << octant << " position " << pos;
      }
    }
  }
  EXPECT_GT(slots, 0u);
  EXPECT_EQ(tight, slots);
  return cost;
}

/// The SAH cost (sum of wide-node box areas) of the fixed collapse: each wide node holds its binary node's
/// grandchildren (a leaf child stands for itself).
double grandchild_collapse_cost(const Bvh& bvh, uint32_t p) {
  const gpu::BvhNode& n = bvh.nodes[p];
  double cost = half_area(n);
  for (const uint32_t side : {p + 1, static_cast<uint32_t>(n.offset)}) {
    const gpu::BvhNode& c = bvh.nodes[side];
    if (node_is_leaf(c)) continue;
    for (const uint32_t g : {side + 1, static_cast<uint32_t>(c.offset)}) {
      if (!node_is_leaf(bvh.nodes[g])) cost += grandchild_collapse_cost(bvh, g);
    }
  }
  return cost;
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
      const double cost = expect_wide_matches(bvh, w);
      // The collapse is chosen for the least SAH cost, so it is never worse than the fixed one, and on these
      // trees better (1-4 %: the fixed one leaves a slot empty where a child is a leaf).
      const double fixed = grandchild_collapse_cost(bvh, 0);
      EXPECT_LT(cost, fixed * 0.995) << "leaf " << leaf;
      EXPECT_GT(w.stack_need, 0);
      EXPECT_LE(w.stack_need, HP_BVH_STACK_SIZE);
      // Four slots where the tree allows: a wide node stands for more than two binary interior nodes on
      // average (about three on these trees).
      EXPECT_LT(w.nodes.size(), bvh.nodes.size() / 4);
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
