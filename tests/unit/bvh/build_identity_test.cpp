// The builders' output is pinned: for fixed inputs and options, the flattened nodes and the primitive order
// hash to values recorded from the reference implementation of the binned SAH builder. The CI gate's
// metrics (BVH shape, cache counts) and the GPU = CPU agreement depend on the exact tree, so a faster
// builder must make exactly the same decisions (bins, splits, ties, partition order) whatever the thread
// count. A failure here means the tree changed: a new tree is a new, non-default option, not a new default.
#include "bvh/build_common.hpp"
#include "bvh/bvh.hpp"
#include "bvh_test_scenes.hpp"

#include <gtest/gtest.h>

#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <vector>

#if HP_BVH_TESTS_HAVE_SCENE
#include "scene/load.hpp"
#include "scene/scene.hpp"

#include <filesystem>
#endif

namespace hp::bvh {
namespace {

using testing::exponential_clusters;
using testing::random_soup;
using testing::terrain;
using testing::uv_sphere;

/// FNV-1a over the flattened nodes and the leaf order.
uint64_t tree_hash(const Bvh& b) {
  uint64_t h = 1469598103934665603ull;
  const auto mix = [&h](const void* p, std::size_t n) {
    const auto* c = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) {
      h ^= c[i];
      h *= 1099511628211ull;
    }
  };
  mix(b.nodes.data(), b.nodes.size() * sizeof(gpu::BvhNode));
  mix(b.prim_ids.data(), b.prim_ids.size() * sizeof(uint32_t));
  return h;
}

struct Pinned {
  std::size_t nodes;
  std::size_t depth_limited;
  uint64_t hash;
};

std::string hex(uint64_t h) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "0x%016" PRIx64, h);
  return buf;
}

void expect_pinned(const char* what, const Bvh& b, const Pinned& want) {
  EXPECT_EQ(b.nodes.size(), want.nodes) << what;
  EXPECT_EQ(b.depth_limited_splits, want.depth_limited) << what;
  EXPECT_EQ(hex(tree_hash(b)), hex(want.hash))
      << what << " (nodes " << b.nodes.size() << ", depth-limited splits " << b.depth_limited_splits << ")";
}

BuildOptions with_threads(int threads) {
  BuildOptions o;
  o.threads = threads;
  return o;
}

TEST(BvhBuildIdentity, ProceduralScenesBuildThePinnedTrees) {
  // 239,200 triangles: large enough that the builder forks and the top levels use the threaded paths.
  const auto sphere = uv_sphere(300, 400).triangles();
  for (const int threads : {1, 2, 3, 8}) {
    const Pinned want{286607, 0, 0x53d1155c800e1dc0ull};
    expect_pinned(("sphere threads " + std::to_string(threads)).c_str(), build_bvh(sphere, with_threads(threads)),
                  want);
  }
  {
    BuildOptions o;
    o.all_axes = false;
    expect_pinned("terrain largest axis", build_bvh(terrain(150).triangles(), o),
                  Pinned{54765, 0, 0x223054e7d2d6a478ull});
  }
  {
    BuildOptions o;
    o.buckets = 32;
    o.max_leaf_size = 1;
    o.threads = 2;
    expect_pinned("soup 32 buckets leaf 1", build_bvh(random_soup(50000, 9), o),
                  Pinned{99999, 0, 0x727535b226de0647ull});
  }
  {
    BuildOptions o;
    o.buckets = 5;
    o.max_leaf_size = 8;
    o.traversal_cost = 1.0f;
    expect_pinned("sphere 5 buckets leaf 8 cost 1", build_bvh(sphere, o), Pinned{243717, 0, 0xee593b7eec0d2051ull});
  }
  {
    // Exponential clusters under a tight depth bound: the median-split fallback and its counter.
    BuildOptions o;
    o.max_depth = 16;
    expect_pinned("clusters depth 16", build_bvh(exponential_clusters(-20, 20, 500, 5), o),
                  Pinned{19709, 1254, 0x135d55557eeebf2cull});
  }
  {
    // Coincident centroids: no axis can be binned, count splits only.
    std::vector<Triangle> same(1000, Triangle{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
    expect_pinned("identical triangles", build_bvh(same, BuildOptions{}), Pinned{511, 0, 0x3ca7ebd97e6110efull});
  }
  {
    std::vector<uint32_t> first{0};
    for (uint32_t k = 1; first.back() < sphere.size(); ++k) {
      first.push_back(std::min<uint32_t>(static_cast<uint32_t>(sphere.size()), first.back() + 7 * (k % 13 + 1)));
    }
    BuildOptions o;
    o.granularity = Granularity::object;
    expect_pinned("sphere objects", build_bvh(sphere, o, first), Pinned{8917, 0, 0x467b907e8e2be532ull});
  }
}

/// A sphere whose coordinates near zero are set to +0 and -0 in turn; `zeroed` counts them.
std::vector<Triangle> signed_zero_sphere(int rings, int segments, std::size_t& zeroed) {
  auto sphere = uv_sphere(rings, segments).triangles();
  for (auto& t : sphere) {
    for (glm::vec3* v : {&t.v0, &t.v1, &t.v2}) {
      for (int a = 0; a < 3; ++a) {
        if (std::abs((*v)[a]) < 0.02f) (*v)[a] = (zeroed++ % 2) ? -0.0f : 0.0f;
      }
    }
  }
  return sphere;
}

TEST(BvhBuildIdentity, SignedZerosBuildThePinnedTree) {
  // min/max keep the later operand on ties, so with +0 and -0 in the input the boxes' zero signs follow the
  // order in which the builder folds primitives and bins: that order is part of the pinned tree too.
  std::size_t k = 0;
  const auto sphere = signed_zero_sphere(300, 400, k);
  ASSERT_EQ(k, 76008u);
  for (const int threads : {1, 2, 3}) {
    expect_pinned(("signed zeros threads " + std::to_string(threads)).c_str(), build_bvh(sphere, with_threads(threads)),
                  Pinned{277967, 0, 0xed00d3cded988acbull});
  }
}

/// The binned builder's input for `tris`: one reference per non-degenerate triangle, in scene order.
std::vector<detail::PrimRef> prim_refs(const std::vector<Triangle>& tris) {
  std::vector<detail::PrimRef> refs;
  for (std::size_t i = 0; i < tris.size(); ++i) {
    const Triangle& t = tris[i];
    if (is_degenerate(t)) continue;
    refs.push_back(
        {glm::min(t.v0, glm::min(t.v1, t.v2)), static_cast<uint32_t>(i), glm::max(t.v0, glm::max(t.v1, t.v2)), 0});
  }
  return refs;
}

TEST(BvhBuildIdentity, TriangleRefsMatchTheScalarDefinition) {
  // build_bvh makes its references with detail::make_triangle_ref; they must be prim_refs' to the bit (the
  // zero signs included), with the same triangles left out. Vertices are drawn from values that stress both:
  // signed zeros (min/max ties), non-finite values in every position, denormals, extremes, and collinear
  // triangles (exactly degenerate in double).
  const float inf = std::numeric_limits<float>::infinity();
  const std::vector<float> values = {0.0f,  -0.0f,  1.0f,    -1.0f,   2.0f,     0.5f, 3.0f, 1e-30f,       -1e-30f,
                                     1e30f, 1e-40f, -1e-40f, 3.4e38f, -3.4e38f, inf,  -inf, std::nanf("")};
  std::mt19937 rng(12345);
  std::uniform_int_distribution<std::size_t> pick(0, values.size() - 1);
  std::uniform_int_distribution<int> small(-3, 3);
  std::vector<Triangle> tris;
  for (int i = 0; i < 200000; ++i) {
    Triangle t;
    for (float* f : {&t.v0.x, &t.v0.y, &t.v0.z, &t.v1.x, &t.v1.y, &t.v1.z, &t.v2.x, &t.v2.y, &t.v2.z})
      *f = values[pick(rng)];
    tris.push_back(t);
    // Collinear: v1 = v0 + d, v2 = v0 + 2d in small integers, with zeros of either sign.
    const glm::vec3 v0(small(rng), small(rng), small(rng)), d(small(rng), small(rng), small(rng));
    Triangle c{v0, v0 + d, v0 + 2.0f * d};
    for (float* f : {&c.v0.x, &c.v1.y, &c.v2.z}) {
      if (*f == 0.0f && (i & 1)) *f = -0.0f;
    }
    tris.push_back(c);
  }
  const auto sphere = uv_sphere(40, 60).triangles();
  tris.insert(tris.end(), sphere.begin(), sphere.end());
  const std::vector<detail::PrimRef> expected = prim_refs(tris);
  std::vector<detail::PrimRef> got;
  std::size_t degenerate = 0;
  detail::RefBounds bounds;
  for (std::size_t i = 0; i < tris.size(); ++i) {
    detail::PrimRef r;
    if (detail::make_triangle_ref(tris[i], static_cast<uint32_t>(i), r, &bounds)) {
      got.push_back(r);
    } else {
      ++degenerate;
    }
  }
  // The bounds folded on the way are the builder's own fold over the references (the same order).
  detail::RefBounds refold;
  for (const detail::PrimRef& r : expected) refold.add(r);
  const auto same = [](const detail::RefBounds& a, const detail::RefBounds& b) {
    const auto eq = [](__m128 x, __m128 y) { return std::memcmp(&x, &y, sizeof(x)) == 0; };
    return eq(a.lo, b.lo) && eq(a.hi, b.hi) && eq(a.clo, b.clo) && eq(a.chi, b.chi);
  };
  EXPECT_TRUE(same(bounds, refold));
  EXPECT_TRUE(bounds.signed_zeros() && refold.signed_zeros());
  // The draws above reach the extremes in every coordinate; a sphere alone has bounds of its own.
  detail::RefBounds sphere_bounds, sphere_refold;
  for (std::size_t i = 0; i < sphere.size(); ++i) {
    detail::PrimRef r;
    ASSERT_TRUE(detail::make_triangle_ref(sphere[i], static_cast<uint32_t>(i), r, &sphere_bounds));
  }
  for (const detail::PrimRef& r : prim_refs(sphere)) sphere_refold.add(r);
  EXPECT_TRUE(same(sphere_bounds, sphere_refold));
  EXPECT_GT(degenerate, 100000u);  // the draws above give both kinds in numbers
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(0, std::memcmp(&got[i], &expected[i], sizeof(detail::PrimRef)))
        << "reference " << i << " (triangle " << expected[i].id << ")";
  }
}

TEST(BvhBuildIdentity, AvxAndBaselineCodeBuildTheSameTree) {
  // The identity tests above run the code this CPU picks; this one runs both on the same input, so that the
  // pinned trees hold for the baseline code on AVX2 hosts too.
  if (!detail::binned_avx2_available()) GTEST_SKIP() << "this CPU has no AVX2: only the baseline code runs here";
  std::size_t zeroed = 0;
  const auto zeros = signed_zero_sphere(120, 160, zeroed);
  ASSERT_GT(zeroed, 0u);
  const std::vector<std::pair<const char*, std::vector<Triangle>>> scenes = {
      {"sphere", uv_sphere(300, 400).triangles()},
      {"terrain", terrain(200).triangles()},
      {"soup", random_soup(50000, 7)},
      {"clusters", exponential_clusters(-6, 6, 3000, 11)},
      {"signed zeros", zeros},
  };
  for (const auto& [name, tris] : scenes) {
    for (const bool all_axes : {true, false}) {
      for (const int threads : {1, 2}) {
        BuildOptions o;
        const detail::BuildParams p{o.buckets,   all_axes, o.traversal_cost, static_cast<uint32_t>(o.max_leaf_size),
                                    o.max_depth, threads};
        auto base_refs = prim_refs(tris), avx_refs = base_refs;
        const detail::PairTree base = detail::build_binned(base_refs, p, detail::BinnedIsa::baseline);
        const detail::PairTree avx = detail::build_binned(avx_refs, p, detail::BinnedIsa::avx2);
        const std::string what =
            std::string(name) + (all_axes ? ", all axes" : ", largest axis") + ", threads " + std::to_string(threads);
        ASSERT_EQ(base.flat.size(), avx.flat.size()) << what;
        EXPECT_EQ(0, std::memcmp(base.flat.data(), avx.flat.data(), base.flat.size() * sizeof(gpu::BvhNode))) << what;
        EXPECT_EQ(base.order, avx.order) << what;
        EXPECT_EQ(base.flat_max_depth, avx.flat_max_depth) << what;
        EXPECT_EQ(base.depth_limited_splits, avx.depth_limited_splits) << what;
      }
    }
  }
}

TEST(BvhBuildIdentity, FullSweepBuildsThePinnedTree) {
  BuildOptions o;
  o.full_sweep = true;
  expect_pinned("terrain full sweep", build_bvh(terrain(100).triangles(), o), Pinned{24037, 0, 0xa4e947c537eb22f7ull});
}

#if HP_BVH_TESTS_HAVE_SCENE
std::vector<Triangle> scene_triangles(const std::string& spec) {
  const Scene scene = load_scene(spec);
  const WorldGeometry world = world_geometry(scene);
  return make_triangles(world.positions, world.indices);
}

TEST(BvhBuildIdentity, BuiltinScenesBuildThePinnedTrees) {
  // The scenes the study and the CI gate use, with the default options.
  const auto sphere = scene_triangles("builtin:sphere-1m");
  expect_pinned("sphere-1m threads 1", build_bvh(sphere, with_threads(1)), Pinned{1155631, 0, 0x97d6d399854a0b9dull});
  expect_pinned("sphere-1m threads 2", build_bvh(sphere, with_threads(2)), Pinned{1155631, 0, 0x97d6d399854a0b9dull});
  expect_pinned("terrain-1m", build_bvh(scene_triangles("builtin:terrain-1m"), with_threads(2)),
                Pinned{1043661, 0, 0x996888922b234ec2ull});
  expect_pinned("pica", build_bvh(scene_triangles("builtin:pica"), BuildOptions{}),
                Pinned{69227, 0, 0x6db8123d3ae98ffdull});
}

TEST(BvhBuildIdentity, SharedScenesBuildThePinnedTrees) {
  const std::filesystem::path root = std::filesystem::path(HP_SHARED_DIR) / "scenes";
  const std::filesystem::path balloon = root / "Balloon" / "scene.gltf",
                              helmet = root / "DamagedHelmet" / "DamagedHelmet.gltf";
  if (!std::filesystem::exists(balloon) || !std::filesystem::exists(helmet))
    GTEST_SKIP() << root << ": scenes not found";
  expect_pinned("Balloon", build_bvh(scene_triangles(balloon.string()), BuildOptions{}),
                Pinned{37999, 0, 0xb2b85552d62c9ff4ull});
  expect_pinned("DamagedHelmet", build_bvh(scene_triangles(helmet.string()), BuildOptions{}),
                Pinned{20459, 0, 0xfa4e737639afdc5dull});
}
#endif

}  // namespace
}  // namespace hp::bvh
