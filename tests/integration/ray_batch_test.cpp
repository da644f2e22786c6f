// The passes' one traversal on rays chosen by the test (shaders/trace_rays.comp through RayBatchTracer)
// against the C++ reference, bit for bit: the hit (scene triangle, t, u, v) and the work (nodes visited,
// triangles tested) of every ray, random ones and hard ones (through vertices and edges, along the axes with
// signed zeros, on slab planes, degenerate and non-finite inputs), for both geometry layouts, both BVH
// granularities and both node layouts (the wide4 traversal against its C++ twin, and its closest hits against
// the binary reference's).
#include "vulkan_env.hpp"

#include "common/scoped_env.hpp"

#include "bvh/traverse.hpp"
#include "error.hpp"
#include "frame.hpp"
#include "passes/ray_batch.hpp"
#include "rt_geometry.hpp"
#include "rt_scene.hpp"
#include "scene/load.hpp"

#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <random>
#include <string>

namespace hp {
namespace {

using test::ScopedEnv;

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// Random rays through the scene's box, then rays aimed at the corners and edge midpoints of its first
// triangles (from outside the box and from a vertex of the triangle itself), rays along the axes (both
// signed zeros in the other components) from points on the BVH's slab planes, and rays with degenerate or
// non-finite parts, which must miss without visiting anything.
std::vector<bvh::Ray> test_rays(const RtGeometry& g, size_t random_count) {
  std::vector<bvh::Ray> rays;
  const gpu::BvhNode& root = g.bvh.nodes.front();
  const glm::vec3 lo(root.bmin), hi(root.bmax);
  const glm::vec3 centre = 0.5f * (lo + hi);
  const float radius = glm::length(hi - lo);
  std::mt19937 rng(12345);
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  std::normal_distribution<float> gauss(0.0f, 1.0f);
  for (size_t i = 0; i < random_count; ++i) {
    const glm::vec3 o = lo + (hi - lo) * glm::vec3(u01(rng), u01(rng), u01(rng)) * 1.2f - 0.1f * (hi - lo);
    glm::vec3 d(gauss(rng), gauss(rng), gauss(rng));
    rays.push_back({o, 0.0f, d, 3.402823466e+38f});
  }
  const std::vector<bvh::Triangle>& all = g.leaf.triangles;
  const size_t tris = std::min<size_t>(all.size(), 300);
  for (size_t k = 0; k < tris; ++k) {
    const bvh::Triangle& t = all[k * (all.size() / tris)];
    const glm::vec3 targets[6] = {t.v0, t.v1, t.v2, 0.5f * (t.v0 + t.v1), 0.5f * (t.v1 + t.v2), 0.5f * (t.v2 + t.v0)};
    const glm::vec3 from = centre + radius * glm::normalize(glm::vec3(0.3f, 0.8f, 0.5f) + 0.1f * float(k % 7));
    for (const glm::vec3& p : targets) {
      rays.push_back({from, 0.0f, p - from, 3.402823466e+38f});
      rays.push_back({t.v0, 0.0f, p - t.v0 + glm::vec3(0.0f, 1e-3f, 0.0f), 3.402823466e+38f});  // leaving a vertex
      rays.push_back({from, 0.0f, p - from, 0.999f});  // ends just short of the target
    }
  }
  // Along the axes from the slab planes of the first nodes' boxes: a zero direction component makes the
  // reciprocal infinite and (plane - origin) zero, the 0 * inf NaN the slab test must discard.
  for (size_t n = 0; n < std::min<size_t>(g.bvh.nodes.size(), 64); ++n) {
    const gpu::BvhNode& node = g.bvh.nodes[n];
    const glm::vec3 corner_lo(node.bmin), corner_hi(node.bmax);
    for (int axis = 0; axis < 3; ++axis) {
      for (float sign : {1.0f, -1.0f}) {
        for (float z : {0.0f, -0.0f}) {
          glm::vec3 d(z);
          d[axis] = sign;
          glm::vec3 o = 0.5f * (corner_lo + corner_hi);
          o[(axis + 1) % 3] = corner_lo[(axis + 1) % 3];  // exactly on a slab plane of another axis
          o[axis] = sign > 0 ? lo[axis] - 1.0f : hi[axis] + 1.0f;
          rays.push_back({o, 0.0f, d, 3.402823466e+38f});
          o[(axis + 2) % 3] = corner_hi[(axis + 2) % 3];
          rays.push_back({o, 0.0f, d, 3.402823466e+38f});
        }
      }
    }
  }
  const glm::vec3 o = centre + glm::vec3(0.0f, 0.0f, radius);
  const glm::vec3 d = glm::vec3(0.01f, -0.02f, -1.0f);
  rays.push_back({o, 0.0f, glm::vec3(0.0f), 3.402823466e+38f});    // zero direction
  rays.push_back({o, 0.0f, glm::vec3(-0.0f), 3.402823466e+38f});   // negative zeros
  rays.push_back({o, 0.0f, glm::vec3(kNaN, 0.0f, -1.0f), 1e30f});  // NaN direction
  rays.push_back({o, 0.0f, glm::vec3(0.0f, kInf, -1.0f), 1e30f});  // infinite direction
  rays.push_back({glm::vec3(kNaN), 0.0f, d, 1e30f});               // NaN origin
  rays.push_back({glm::vec3(kInf, 0.0f, 0.0f), 0.0f, d, 1e30f});   // infinite origin
  rays.push_back({o, kNaN, d, 1e30f});                             // NaN tmin
  rays.push_back({o, 0.0f, d, kNaN});                              // NaN tmax
  rays.push_back({o, 5.0f, d, 1.0f});                              // tmin > tmax
  rays.push_back({o, 0.0f, d, 0.0f});                              // empty segment at the origin
  rays.push_back({o, 0.0f, d, kInf});                              // infinite tmax
  rays.push_back({o, -kInf, d, kInf});                             // the whole line
  rays.push_back({o, 0.0f, d * 1e-30f, 3.402823466e+38f});         // tiny direction
  rays.push_back({o, 0.0f, d * 1e30f, 3.402823466e+38f});          // huge direction
  rays.push_back({o * 1e6f, 0.0f, -o, 3.402823466e+38f});          // far away, aimed back at the scene
  return rays;
}

// `gpu` (optional) receives the device's answers.
BatchCheck compare_batch(vk::Context& ctx, const RtGeometry& g, const RtScene& rts, const std::vector<bvh::Ray>& rays,
                         bvh::HitMode mode, const std::string& what,
                         std::vector<RayBatchTracer::Result>* gpu = nullptr) {
  RayBatchTracer tracer(ctx, rts, rays);
  EXPECT_EQ(tracer.size(), rays.size());
  tracer.trace(ctx, mode);
  const std::vector<RayBatchTracer::Result> results = tracer.results(ctx);
  const BatchCheck c = check_against_reference(g, rays, mode, results);
  if (gpu) *gpu = results;
  for (const std::string& d : c.first_differences) std::printf("  %s: %s\n", what.c_str(), d.c_str());
  std::printf("%s: %zu rays (%zu hit), %zu differ\n", what.c_str(), c.rays, c.hits, c.differ);
  return c;
}

// The wide traversal's answers on the device against the binary tree's: its closest hits are the binary
// tree's, bit for bit, but for the documented tie rule
// (docs/bvh.md): where two coplanar triangles overlap, their computed t can differ by more than a box's
// rounding, so which one survives pruning depends on the visiting order; the two answers are then both
// real hits within 1e-4 of each other in t (relative to max(1, t)). Any hit: hit or miss agree.
void expect_binary_hits(const RtGeometry& g, const std::vector<bvh::Ray>& rays, bvh::HitMode mode,
                        const std::vector<RayBatchTracer::Result>& gpu, const std::string& what) {
  size_t differ = 0, ties = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const bvh::Hit want = mode == bvh::HitMode::closest ? bvh::intersect_closest(g.bvh, g.leaf, rays[i])
                                                        : bvh::intersect_any(g.bvh, g.leaf, rays[i]);
    const bvh::Hit& got = gpu[i].hit;
    const auto bits = [](float f) { return std::bit_cast<uint32_t>(f); };
    if (mode == bvh::HitMode::any ? want.hit() == got.hit()
                                  : want.prim == got.prim && bits(want.t) == bits(got.t) &&
                                        bits(want.u) == bits(got.u) && bits(want.v) == bits(got.v)) {
      continue;
    }
    if (mode == bvh::HitMode::closest && want.hit() && got.hit() &&
        std::abs(double(got.t) - double(want.t)) <= 1e-4 * std::max(1.0, std::abs(double(want.t)))) {
      ++ties;
      continue;
    }
    ++differ;
    if (differ <= 3) {
      std::printf("  ray %zu: binary prim %d t %.9g, wide4 prim %d t %.9g\n", i, want.prim, want.t, got.prim, got.t);
    }
  }
  std::printf("%s: wide4 on the device against the binary reference: %zu differ, %zu coplanar ties\n", what.c_str(),
              differ, ties);
  EXPECT_EQ(differ, 0u) << what;
  EXPECT_LE(ties * 1000, rays.size()) << what << ": ties beyond 0.1% of the rays";
}

// `texels`: let the scene fetch its geometry as texels where the device can (the default), or force the
// storage loads.
void check_scene(const std::string& spec, GeometryLayout layout, bvh::Granularity granularity, size_t random_rays,
                 bool texels = true, bvh::NodeLayout nodes = bvh::NodeLayout::binary32) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene(spec);
  bvh::BuildOptions opts;
  opts.granularity = granularity;
  opts.node_layout = nodes;
  const RtGeometry g = build_rt_geometry(scene, opts);
  const RtScene rts(*ctx, scene, g, layout, false, texels);
  EXPECT_EQ(rts.wide_nodes(), nodes == bvh::NodeLayout::wide4);
  EXPECT_EQ(rts.exact_division(), exact_traversal_division(*ctx));
  EXPECT_EQ(rts.storage_texels(), storage_texel_reads(*ctx));
  if (!texels) {
    EXPECT_FALSE(rts.geometry_texels());
  }
  const auto rays = test_rays(g, random_rays);
  const std::string name = spec + " " + to_string(layout) +
                           (granularity == bvh::Granularity::object ? " object BVH" : " triangle BVH") + ", " +
                           to_string(nodes) + " nodes" +
                           (rts.geometry_texels() ? ", geometry as texels" : ", geometry by storage loads");
  for (bvh::HitMode mode : {bvh::HitMode::closest, bvh::HitMode::any}) {
    const std::string what = name + (mode == bvh::HitMode::any ? ", any hit" : ", closest hit");
    std::vector<RayBatchTracer::Result> gpu;
    const BatchCheck t = compare_batch(*ctx, g, rts, rays, mode, what, &gpu);
    EXPECT_EQ(t.differ, 0u) << what;
    EXPECT_GT(t.hits, rays.size() / 10) << what << ": too few hits to prove anything";
    if (nodes == bvh::NodeLayout::wide4) expect_binary_hits(g, rays, mode, gpu, what);
  }
}

TEST(RayBatch, PicaIndexedEqualsTheReferenceBitForBit) {
  check_scene("builtin:pica", GeometryLayout::indexed, bvh::Granularity::triangle, 20000);
}

TEST(RayBatch, PicaSoupEqualsTheReferenceBitForBit) {
  check_scene("builtin:pica", GeometryLayout::soup, bvh::Granularity::triangle, 20000);
}

TEST(RayBatch, TheStorageLoadPathEqualsTheReferenceToo) {
  check_scene("builtin:pica", GeometryLayout::indexed, bvh::Granularity::triangle, 5000, false);
  check_scene("builtin:pica", GeometryLayout::soup, bvh::Granularity::triangle, 5000, false);
}

TEST(RayBatch, Wide4NodesEqualTheirReferenceAndTheBinaryHits) {
  check_scene("builtin:pica", GeometryLayout::indexed, bvh::Granularity::triangle, 20000, true, bvh::NodeLayout::wide4);
  check_scene("builtin:pica", GeometryLayout::soup, bvh::Granularity::triangle, 5000, false, bvh::NodeLayout::wide4);
  check_scene("builtin:cornell", GeometryLayout::indexed, bvh::Granularity::object, 10000, true,
              bvh::NodeLayout::wide4);
  const std::string path = std::string(HP_SHARED_DIR) + "/scenes/DamagedHelmet/DamagedHelmet.gltf";
  if (std::filesystem::exists(path)) {
    check_scene(path, GeometryLayout::indexed, bvh::Granularity::triangle, 10000, true, bvh::NodeLayout::wide4);
  }
}

// The quotients taken in double precision and rounded once (HP_EXACT_DIVISION, on for every device but
// lavapipe) are the correctly rounded ones, so they give the reference's hits bit for bit here too.
TEST(RayBatch, TheDoublePrecisionQuotientsEqualTheReferenceToo) {
  HP_REQUIRE_VULKAN(ctx);
  const ScopedEnv env("HP_EXACT_DIVISION");
  env.set("0");
  EXPECT_FALSE(exact_traversal_division(*ctx));
  env.set("1");
  EXPECT_TRUE(exact_traversal_division(*ctx));
  check_scene("builtin:pica", GeometryLayout::indexed, bvh::Granularity::triangle, 20000);
  check_scene("builtin:pica", GeometryLayout::indexed, bvh::Granularity::triangle, 5000, true, bvh::NodeLayout::wide4);
  check_scene("builtin:cornell", GeometryLayout::soup, bvh::Granularity::object, 5000);
}

// The node and geometry texels read both ways, through storage texel buffers (imageLoad: lavapipe's default)
// and uniform ones (texelFetch: every other device's), whichever this device does not use by default included.
TEST(RayBatch, BothTexelReadsEqualTheReference) {
  HP_REQUIRE_VULKAN(ctx);
  const ScopedEnv env("HP_STORAGE_TEXELS");
  for (const char* value : {"0", "1"}) {
    env.set(value);
    EXPECT_EQ(storage_texel_reads(*ctx), *value == '1');
    check_scene("builtin:pica", GeometryLayout::indexed, bvh::Granularity::triangle, 5000);
    check_scene("builtin:pica", GeometryLayout::soup, bvh::Granularity::triangle, 5000, true, bvh::NodeLayout::wide4);
    check_scene("builtin:cornell", GeometryLayout::indexed, bvh::Granularity::object, 5000, true,
                bvh::NodeLayout::wide4);
  }
}

TEST(RayBatch, CornellObjectBvhEqualsTheReferenceBitForBit) {
  check_scene("builtin:cornell", GeometryLayout::indexed, bvh::Granularity::object, 20000);
}

TEST(RayBatch, DamagedHelmetEqualsTheReferenceBitForBit) {
  const std::string path = std::string(HP_SHARED_DIR) + "/scenes/DamagedHelmet/DamagedHelmet.gltf";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << "scene absent: " << path;
  check_scene(path, GeometryLayout::indexed, bvh::Granularity::triangle, 20000);
}

// The timestamps must bracket the dispatch: on lavapipe a timestamp is resolved at the next flush, and
// without a barrier between the first timestamp and the dispatch both were taken after it (0.1 ms for a
// 75 ms dispatch). On a CPU device the dispatch is nearly all of trace()'s wall time.
TEST(RayBatch, TheTimestampsBracketTheDispatch) {
  HP_REQUIRE_VULKAN(ctx);
  // After a frame, as in the frame benchmark: the deferred timestamp showed there, not on a fresh context.
  const Scene scene = load_scene("builtin:pica");
  FrameSettings fs;
  fs.width = 64;
  fs.height = 36;
  fs.rt.shadows = true;
  Frame frame(*ctx, scene, auto_frame(scene, float(fs.width) / float(fs.height)), fs);
  frame.render();
  ASSERT_NE(frame.rt_geometry(), nullptr);
  const RtGeometry& g = *frame.rt_geometry();
  const auto rays = test_rays(g, 200000);
  RayBatchTracer tracer(*ctx, *frame.rt_scene(), rays);
  tracer.trace(*ctx, bvh::HitMode::closest);  // warm-up
  const auto t0 = std::chrono::steady_clock::now();
  const uint64_t gpu_ns = tracer.trace(*ctx, bvh::HitMode::closest);
  const double host_ns =
      double(std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - t0).count());
  if (!ctx->info().timestamp_valid_bits) GTEST_SKIP() << "no timestamps on this queue";
  std::printf("trace of %zu rays: %.3f ms by timestamps, %.3f ms on the host\n", rays.size(), gpu_ns * 1e-6,
              host_ns * 1e-6);
  EXPECT_GT(gpu_ns, 0u);
  EXPECT_LE(double(gpu_ns), host_ns);
  if (ctx->info().type == "cpu") {
    EXPECT_GE(double(gpu_ns), 0.5 * host_ns);
  }
}

TEST(RayBatch, AnEmptyBatchTracesNothing) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:cornell");
  const RtGeometry g = build_rt_geometry(scene, {});
  const RtScene rts(*ctx, scene, g, GeometryLayout::indexed, false);
  RayBatchTracer tracer(*ctx, rts, {});
  tracer.trace(*ctx, bvh::HitMode::closest);
  EXPECT_TRUE(tracer.results(*ctx).empty());
}

// The dispatch order (shaders/common/dispatch_order.glsl) only changes which workgroup takes which rays:
// with any number of levels, each ray of a batch that is no multiple of the workgroup gets the reference's
// answer (a ray left out or traced twice would leave some result unwritten).
TEST(RayBatch, EveryDispatchOrderTracesEachRayOnce) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  const RtGeometry g = build_rt_geometry(scene, {});
  std::vector<bvh::Ray> rays = test_rays(g, 3000);
  if (rays.size() % 64 == 0) rays.pop_back();
  for (uint32_t levels : {0u, 1u, 3u, 7u}) {
    const RtScene rts(*ctx, scene, g, GeometryLayout::indexed, false, true, true, true, levels);
    EXPECT_EQ(rts.spread_levels(), levels);
    for (bvh::HitMode mode : {bvh::HitMode::closest, bvh::HitMode::any}) {
      const std::string what = "pica, " + std::to_string(levels) + " spread levels" +
                               (mode == bvh::HitMode::any ? ", any hit" : ", closest hit");
      const BatchCheck c = compare_batch(*ctx, g, rts, rays, mode, what);
      EXPECT_EQ(c.differ, 0u) << what;
      EXPECT_GT(c.hits, rays.size() / 10) << what;
    }
  }
}

// A CPU device gets ceil(log2(threads)) levels, lavapipe's LP_NUM_THREADS where set; a GPU none.
TEST(RayBatch, TheDispatchOrderFollowsTheDevicesThreads) {
  HP_REQUIRE_VULKAN(ctx);
  const bool cpu = ctx->properties().deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
  const ScopedEnv env("LP_NUM_THREADS");
  for (const auto& [threads, levels] :
       std::vector<std::pair<const char*, uint32_t>>{{"1", 0u}, {"2", 1u}, {"5", 3u}, {"16", 4u}, {"0", 0u}}) {
    env.set(threads);
    EXPECT_EQ(dispatch_spread_levels(*ctx), cpu ? levels : 0u) << "LP_NUM_THREADS=" << threads;
  }
}

TEST(RayBatch, LimitsAreCheckedWithTheLimitNamed) {
  VkPhysicalDeviceLimits limits{};
  limits.maxTexelBufferElements = 1u << 16;  // 32768 rays of two texels
  limits.maxStorageBufferRange = 1u << 30;
  limits.maxComputeWorkGroupCount[0] = 8;
  limits.maxComputeWorkGroupCount[1] = 4;
  EXPECT_NO_THROW(RayBatchTracer::check_limits(32 * 64, limits));
  try {
    RayBatchTracer::check_limits(32 * 64 + 1, limits);  // 33 workgroups: a fifth row of 8
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("maxComputeWorkGroupCount"), std::string::npos) << e.what();
  }
  limits.maxComputeWorkGroupCount[1] = 1000;
  try {
    RayBatchTracer::check_limits(32769, limits);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("maxTexelBufferElements"), std::string::npos) << e.what();
  }
  limits.maxTexelBufferElements = 1u << 30;
  limits.maxStorageBufferRange = 1u << 20;  // 32768 answers of 32 bytes
  EXPECT_NO_THROW(RayBatchTracer::check_limits(32768, limits));
  try {
    RayBatchTracer::check_limits(32769, limits);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("maxStorageBufferRange"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace hp
