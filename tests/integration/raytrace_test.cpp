// The GPU ray-tracing passes against the C++ reference traversal, on the very rays the shaders cast (the
// shaders dump them), and the properties the study's experiments rely on.
#include "cpu_agreement.hpp"
#include "error.hpp"
#include "vulkan_env.hpp"

#include "bvh/traverse.hpp"
#include "frame.hpp"
#include "scene/load.hpp"
#include "vk/timestamps.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>

namespace hp {
namespace {

FrameSettings rt_settings(uint32_t w, uint32_t h) { return rt_test_settings(w, h); }

void check_against_cpu(const std::string& spec, FrameSettings s) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene(spec);
  const Camera cam = scene.has_camera ? scene.camera : auto_frame(scene, float(s.width) / float(s.height));
  Frame frame(*ctx, scene, cam, s);
  frame.render();
  const auto shadows = frame.rt_passes()->read_shadow_dump(*ctx);
  const Agreement sa = compare(frame, shadows, true, (spec + " shadows").c_str());
  EXPECT_GT(sa.rays, size_t(s.width) * s.height / 10) << "too few shadow rays to prove anything";
  EXPECT_EQ(sa.equal, sa.rays) << "the passes run the reference's traversal: every ray the same answer";
  if (s.rt.reflections) {
    const auto refl = frame.rt_passes()->read_reflection_dump(*ctx);
    const Agreement ra = compare(frame, refl, false, (spec + " reflections").c_str());
    EXPECT_GT(ra.rays, 0u) << "no reflective pixel";
    EXPECT_EQ(ra.equal, ra.rays);
  }
}

TEST(RayTrace, PicaMatchesCpuReference) { check_against_cpu("builtin:pica", rt_settings(320, 180)); }

TEST(RayTrace, CornellRobustOffsetMatchesCpuReference) {
  FrameSettings s = rt_settings(200, 150);
  s.rt.offset = ShadowOffset::robust;
  s.rt.roughness_threshold = 1.01f;  // every pixel reflects: more closest-hit rays
  check_against_cpu("builtin:cornell", s);
}

TEST(RayTrace, SoupAndObjectBvhMatchCpuReference) {
  FrameSettings s = rt_settings(240, 136);
  s.geometry = GeometryLayout::soup;
  s.bvh.granularity = bvh::Granularity::object;
  check_against_cpu("builtin:pica", s);
}

TEST(RayTrace, SharedSceneMatchesCpuReference) {
  const auto path = std::filesystem::path(HP_SHARED_DIR) / "scenes/DamagedHelmet/DamagedHelmet.gltf";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent";
  FrameSettings s = rt_settings(200, 200);
  s.rt.offset = ShadowOffset::robust;
  s.rt.roughness_threshold = 1.01f;
  check_against_cpu(path.string(), s);
}

Image4f render_color(vk::Context& ctx, const Scene& scene, FrameSettings s, uint32_t frames) {
  Frame frame(ctx, scene, scene.camera, s);
  for (uint32_t i = 0; i < frames; ++i) frame.render();
  return frame.read_color();
}

TEST(RayTrace, IndexedAndSoupGiveBitIdenticalImages) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s = rt_settings(192, 108);
  s.rt.dump_rays = false;
  s.geometry = GeometryLayout::indexed;
  const Image4f a = render_color(*ctx, scene, s, 3);
  s.geometry = GeometryLayout::soup;
  const Image4f b = render_color(*ctx, scene, s, 3);
  ASSERT_EQ(a.rgba.size(), b.rgba.size());
  size_t differing = 0;
  for (size_t i = 0; i < a.rgba.size(); ++i) differing += std::memcmp(&a.rgba[i], &b.rgba[i], 4) != 0;
  EXPECT_EQ(differing, 0u) << "indexed vs soup: channels that differ";
}

double rel_mse(const Image4f& x, const Image4f& ref, double eps) {
  double sum = 0.0;
  size_t n = 0;
  for (size_t i = 0; i < x.rgba.size(); ++i) {
    if (i % 4 == 3) continue;
    const double d = double(x.rgba[i]) - ref.rgba[i];
    sum += d * d / (double(ref.rgba[i]) * ref.rgba[i] + eps);
    ++n;
  }
  return sum / double(n);
}

TEST(RayTrace, SharedAndPerThreadJitterConverge) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s = rt_settings(160, 90);
  s.rt.dump_rays = false;
  s.rt.shadows = false;
  s.rt.roughness_threshold = 0.6f;  // include rough reflectors, where the jitter matters
  s.rt.jitter = JitterMode::shared;
  const Image4f shared1 = render_color(*ctx, scene, s, 1);
  const Image4f shared64 = render_color(*ctx, scene, s, 64);
  s.rt.jitter = JitterMode::per_thread;
  const Image4f thread1 = render_color(*ctx, scene, s, 1);
  const Image4f thread64 = render_color(*ctx, scene, s, 64);
  const double early = rel_mse(shared1, thread1, 0.01);
  const double late = rel_mse(shared64, thread64, 0.01);
  std::printf("relMSE(shared, per-thread), eps 0.01: 1 frame %.3g, 64 frames %.3g\n", early, late);
  EXPECT_LT(late, 2e-3) << "the two jitter modes must estimate the same image";
  EXPECT_LT(late, 0.25 * early) << "accumulation must bring them together";
}

TEST(RayTrace, CountersAreDeterministicAndCountTheRays) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s = rt_settings(128, 72);
  s.rt.counters = true;
  RayCounters c[2];
  size_t dumped_shadow_rays = 0;
  for (int run = 0; run < 2; ++run) {
    Frame frame(*ctx, scene, scene.camera, s);
    frame.render();
    c[run] = frame.read_counters();
    if (run == 0) {
      for (const auto& d : frame.rt_passes()->read_shadow_dump(*ctx)) dumped_shadow_rays += d.hit.z;
    }
  }
  EXPECT_TRUE(c[0] == c[1]) << "counters differ between two identical runs";
  EXPECT_EQ(c[0].shadow_rays, dumped_shadow_rays);
  EXPECT_GT(c[0].shadow_nodes, c[0].shadow_rays) << "every ray visits at least the root";
  EXPECT_GT(c[0].reflection_rays, 0u);
  EXPECT_GT(c[0].reflection_tris, 0u);
}

TEST(RayTrace, ReflectionGridFollowsTheScale) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:cornell");
  for (uint32_t div : {1u, 2u, 4u}) {
    FrameSettings s = rt_settings(101, 67);  // ragged: not a multiple of 8 nor of the divisor
    s.rt.reflection_divisor = div;
    s.rt.roughness_threshold = 1.01f;
    Camera inside = scene.camera;
    inside.position = {0.0f, 1.0f, 0.9f};  // inside the box: walls fill the whole frame
    Frame frame(*ctx, scene, inside, s);
    frame.render();
    const Image4f r = frame.read_aov(Aov::reflection);
    EXPECT_EQ(r.width, (101 + div - 1) / div);
    EXPECT_EQ(r.height, (67 + div - 1) / div);
    // The last column and row (the ragged edge) are traced, not left empty.
    EXPECT_EQ(r.at(r.width - 1, r.height / 2)[3], 1.0f) << "divisor " << div;
    EXPECT_EQ(r.at(r.width / 2, r.height - 1)[3], 1.0f) << "divisor " << div;
  }
}

TEST(RayTrace, NoRaysNoBvh) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:cornell");
  FrameSettings s;
  s.width = 64;
  s.height = 48;
  Frame frame(*ctx, scene, scene.camera, s);
  const FrameTiming t = frame.render();
  EXPECT_EQ(frame.rt_geometry(), nullptr) << "a frame without traced rays must not build a BVH";
  ASSERT_EQ(t.passes.size(), 2u);
  EXPECT_EQ(t.passes[0].name, "gbuffer");
  EXPECT_EQ(t.passes[1].name, "composite");
}

// Audit find (2026-11-30): a frame without reflections still held full-size reflection and accumulation
// images, and a shadow-only frame the slot -> scene map that only closest-hit rays read.
TEST(RayTrace, AShadowOnlyFrameHoldsNothingForReflections) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:cornell");
  FrameSettings s;
  s.width = 64;
  s.height = 48;
  s.rt.shadows = true;
  Frame frame(*ctx, scene, scene.camera, s);
  frame.render();
  const RtResources& rt = *frame.rt_passes();
  EXPECT_EQ(rt.shadow_mask().width(), 64u);
  EXPECT_EQ(rt.reflection_accum().width(), 1u);
  EXPECT_EQ(rt.reflection_accum().height(), 1u);
  EXPECT_LE(frame.rt_scene()->slot_scene().size(), 48u) << "the slot map is a stand-in";
  const Image4f mask = frame.read_aov(Aov::shadow);
  size_t dark = 0;
  for (size_t i = 0; i < mask.rgba.size(); i += 4) dark += mask.rgba[i] == 0.0f;
  EXPECT_GT(dark, 0u) << "the shadow pass still works";
  EXPECT_THROW(frame.read_aov(Aov::reflection), InputError);
}

// Audit find (2026-11-30): ticks were masked to timestampValidBits but not unwrapped, so a frame across the
// counter's wrap had a pass ending before it began, and the run aborted.
TEST(Timestamps, AFrameAcrossTheCounterWrapStaysOrdered) {
  const uint64_t mask = (uint64_t(1) << 36) - 1;
  const uint64_t first = mask - 100;  // 101 ticks before the wrap
  const double begin = vk::unwrapped_timestamp_ns(first, first, mask, 1.0);
  const double end = vk::unwrapped_timestamp_ns(50, first, mask, 1.0);  // after the wrap
  EXPECT_EQ(end - begin, 151.0);
  // Bits above the valid ones are ignored; without a wrap the value is the tick itself.
  EXPECT_EQ(vk::unwrapped_timestamp_ns((uint64_t(7) << 40) | 1000, 500, mask, 2.0), 2000.0);
}

TEST(RayTrace, TimestampsAreOrderedPerPass) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s = rt_settings(96, 54);
  s.rt.dump_rays = false;
  Frame frame(*ctx, scene, scene.camera, s);
  const FrameTiming t = frame.render();
  ASSERT_EQ(t.passes.size(), 5u);
  EXPECT_EQ(t.source, frame.timestamps_supported() ? "gpu-timestamps" : "cpu-wall");
  for (size_t i = 0; i < t.passes.size(); ++i) {
    EXPECT_GT(t.passes[i].begin_ns, 0u);
    EXPECT_GT(t.passes[i].end_ns, t.passes[i].begin_ns) << t.passes[i].name;
    if (i) {
      EXPECT_GE(t.passes[i].begin_ns, t.passes[i - 1].end_ns) << t.passes[i].name;
    }
  }
}

// Reflections only, with counters, at 160x90: what the compaction tests compare.
FrameSettings reflections_only() {
  FrameSettings s;
  s.width = 160;
  s.height = 90;
  s.rt.shadows = false;
  s.rt.reflections = true;
  s.rt.counters = true;
  return s;
}

// The compaction path (the study's 4.2): every valid ray and only those, the same image as the direct
// path whatever the sort key with write-back by index, and misplaced writes counted with reprojection.
TEST(Compaction, KeepsExactlyTheValidRaysAndMatchesTheDirectPath) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s = reflections_only();
  s.rt.jitter = JitterMode::per_thread;
  s.rt.roughness_threshold = 0.6f;
  Frame direct(*ctx, scene, scene.camera, s);
  direct.render();
  const Image4f want = direct.read_aov(Aov::reflection);
  const RayCounters want_counts = direct.read_counters();
  size_t valid = 0;
  for (size_t i = 0; i < want.rgba.size(); i += 4) valid += want.rgba[i + 3] > 0.5f;
  ASSERT_GT(valid, 1000u);
  EXPECT_EQ(want_counts.reflection_rays, valid);

  for (SortKey key : {SortKey::none, SortKey::octant, SortKey::direction, SortKey::origin}) {
    SCOPED_TRACE(to_string(key));
    FrameSettings c = s;
    c.rt.reflection_path = ReflectionPath::compact;
    c.rt.sort = key;
    Frame compact(*ctx, scene, scene.camera, c);
    const FrameTiming t = compact.render();
    EXPECT_EQ(compact.rt_passes()->read_compacted_count(*ctx), valid) << "compaction lost or invented rays";
    const Image4f got = compact.read_aov(Aov::reflection);
    ASSERT_EQ(got.rgba.size(), want.rgba.size());
    size_t differing = 0;
    for (size_t i = 0; i < want.rgba.size(); ++i) differing += std::memcmp(&want.rgba[i], &got.rgba[i], 4) != 0;
    EXPECT_EQ(differing, 0u) << "write-back by index must reproduce the direct pass exactly";
    const RayCounters counts = compact.read_counters();
    EXPECT_EQ(counts.reflection_rays, want_counts.reflection_rays);
    EXPECT_EQ(counts.reflection_nodes, want_counts.reflection_nodes) << "the same rays, the same traversals";
    EXPECT_EQ(counts.reprojection_misplaced, 0u);
    std::vector<std::string> names;
    for (const auto& p : t.passes) names.push_back(p.name);
    const bool has_sort = std::find(names.begin(), names.end(), "sort") != names.end();
    EXPECT_EQ(has_sort, key != SortKey::none) << "the sort runs only when a key is chosen";
    EXPECT_NE(std::find(names.begin(), names.end(), "compact"), names.end());
    EXPECT_NE(std::find(names.begin(), names.end(), "consume"), names.end());
  }
}

TEST(Compaction, ReprojectionWritebackCountsMisplacedRays) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s = reflections_only();
  s.rt.reflection_path = ReflectionPath::compact;
  s.rt.writeback = Writeback::reproject;
  s.rt.offset = ShadowOffset::normal_bias;
  s.rt.bias = 0.1f;  // the study's offset moves origins off their pixel, so some land elsewhere
  Frame frame(*ctx, scene, scene.camera, s);
  frame.render();
  const RayCounters c = frame.read_counters();
  std::printf("reprojection write-back: %llu of %llu rays written to another cell, %llu reflective cells unwritten\n",
              (unsigned long long)c.reprojection_misplaced, (unsigned long long)c.reflection_rays,
              (unsigned long long)c.reprojection_unwritten);
  EXPECT_GT(c.reprojection_misplaced, 0u);
  EXPECT_LT(c.reprojection_misplaced, c.reflection_rays);
  EXPECT_GT(c.reprojection_unwritten, 0u);
  EXPECT_LE(c.reprojection_unwritten, c.reprojection_misplaced) << "only a misplaced ray can leave its cell empty";
  // With write-back by index nothing is misplaced or left out.
  s.rt.writeback = Writeback::index;
  Frame exact(*ctx, scene, scene.camera, s);
  exact.render();
  const Image4f r = exact.read_aov(Aov::reflection);
  size_t written = 0;
  for (size_t i = 3; i < r.rgba.size(); i += 4) written += r.rgba[i] > 0.5f;
  EXPECT_EQ(written, exact.rt_passes()->read_compacted_count(*ctx));
}

}  // namespace
}  // namespace hp
