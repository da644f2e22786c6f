// A real profiled run: warm-up discarded, statistics over the measured frames, counters identical frame to
// frame (the scene and camera do not change), a timeline that nests per track, a result that round-trips.
#include "vulkan_env.hpp"

#include "frame_profiler.hpp"
#include "scene/load.hpp"
#include "timing/result_json.hpp"
#include "timing/timeline.hpp"

#include <filesystem>

namespace hp {
namespace {

TEST(Profile, RealRunGivesNestedTimelineAndStableCounters) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s;
  s.width = 96;
  s.height = 54;
  s.rt.shadows = true;
  s.rt.reflections = true;
  s.rt.counters = true;
  s.rt.jitter = JitterMode::shared;
  Frame frame(*ctx, scene, scene.camera, s);
  ProfileOptions o;
  o.warmup = 2;
  o.frames = 6;
  const FrameTimings t = profile_frames(frame, o);
  ASSERT_TRUE(t.complete());
  ASSERT_EQ(t.measured().size(), 6u);
  ASSERT_TRUE(frame.first_frame_queries().has_value());
  EXPECT_EQ(*frame.first_frame_queries(), FrameQueries::none) << "no query in the Frame's first frame";
  const TimingSummary sum = t.summarize();
  ASSERT_EQ(sum.passes.size(), 5u);
  for (const auto& p : sum.passes) {
    EXPECT_EQ(p.duration_ns.count, 6u) << p.pass;
    EXPECT_GT(p.duration_ns.min, 0.0) << p.pass;
    EXPECT_LE(p.duration_ns.median_ci.low, p.duration_ns.median) << p.pass;
    EXPECT_GE(p.duration_ns.median_ci.high, p.duration_ns.median) << p.pass;
  }
  ASSERT_TRUE(sum.query_overhead.has_value());
  EXPECT_EQ(sum.query_overhead->frames, 6u);
  EXPECT_EQ(sum.pass_isolation, PassIsolation::Serialized);
  // The frame as the application records it, one beside each measured frame, summed against its passes.
  ASSERT_EQ(t.overlapped().size(), 6u);
  ASSERT_TRUE(sum.overlap.has_value());
  EXPECT_EQ(sum.overlap->frames, 6u);
  EXPECT_GT(sum.overlap->overlapped_frame_ns.min, 0.0);
  ASSERT_TRUE(sum.overlap->saving_ns.has_value());
  EXPECT_TRUE(sum.overlap->saving_ns_ci.valid);
  // Shadow work does not depend on the frame (no jitter): identical counters in every measured frame.
  // Reflection work varies with the per-frame jitter offset, so only its presence is checked.
  const auto& frames = t.measured();
  for (const auto& f : frames) {
    EXPECT_EQ(f.counters.get("shadows", counter::nodes_visited),
              frames[0].counters.get("shadows", counter::nodes_visited));
    EXPECT_EQ(f.counters.get("shadows", counter::rays_cast), frames[0].counters.get("shadows", counter::rays_cast));
    EXPECT_GT(f.counters.get("reflections", counter::rays_cast), 0u);
  }
  EXPECT_GT(frames[0].counters.get("shadows", counter::rays_cast), 0u);
  // Pipeline statistics: every invocation of the 8x8-tiled dispatch counts, the ragged edge's idle lanes too.
  VkPhysicalDeviceFeatures features{};
  vkGetPhysicalDeviceFeatures(ctx->physical_device(), &features);
  // They are counted in an untimed frame, so no measured frame carries them.
  if (features.pipelineStatisticsQuery) {
    const Counters& inv = t.frame_invocations();
    EXPECT_EQ(inv.get("shadows", counter::compute_invocations), 96u * 56u);
    EXPECT_EQ(inv.get("composite", counter::compute_invocations), 96u * 56u);
    EXPECT_EQ(inv.get("reflections", counter::compute_invocations), 96u * 56u);
    EXPECT_EQ(inv.passes().count("gbuffer"), 0u) << "the G-buffer is not a compute pass";
  } else {
    EXPECT_TRUE(t.frame_invocations().empty());
  }
  for (const auto& f : frames) EXPECT_EQ(f.counters.total(counter::compute_invocations), 0u);

  TimelineFixes fixes;
  const nlohmann::json timeline = build_timeline(t, &fixes);
  const std::vector<std::string> problems = check_timeline(timeline);
  EXPECT_TRUE(problems.empty()) << problems.front();
  EXPECT_EQ(fixes.passes_trimmed + fixes.passes_clamped + fixes.frames_trimmed, 0u)
      << "GPU timestamps of one queue must already nest";
  size_t overlapped_events = 0;
  for (const auto& e : timeline["traceEvents"]) overlapped_events += e.value("name", "") == "frame (overlapped)";
  EXPECT_EQ(overlapped_events, 6u) << "one span per overlapped frame, on a track of its own";

  const auto path = std::filesystem::temp_directory_path() / ("hp_profile_" + std::to_string(::getpid()) + ".json");
  write_timing_result(path, capture_environment(describe_device(*ctx)), t);
  const TimingResult back = read_timing_result(path);
  EXPECT_EQ(back.environment.device.name, ctx->info().name);
  EXPECT_EQ(back.summary, sum);
  EXPECT_EQ(back.timings.frame_invocations(), t.frame_invocations());
  EXPECT_EQ(back.timings.overlapped(), t.overlapped());
  EXPECT_EQ(back.timings.summarize(), sum) << "the stored raw samples give the stored summary";
  EXPECT_FALSE(back.environment.device.driver_version.empty());
  EXPECT_EQ(back.environment.device.driver_version, ctx->info().driver_version);
  std::filesystem::remove(path);
}

// The overlapped frames repeat a measured frame's sample and leave the accumulation as it was: the final
// image and every counter are those of a run without them, bit for bit.
TEST(Profile, OverlappedFramesChangeNeitherImageNorCounters) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:pica");
  FrameSettings s;
  s.width = 64;
  s.height = 40;
  s.rt.shadows = true;
  s.rt.reflections = true;
  s.rt.counters = true;
  s.rt.jitter = JitterMode::per_thread;
  auto run = [&](bool overlap) {
    Frame frame(*ctx, scene, scene.camera, s);
    ProfileOptions o;
    o.warmup = 1;
    o.frames = 5;
    o.measure_query_overhead = false;
    o.measure_overlap = overlap;
    const FrameTimings t = profile_frames(frame, o);
    EXPECT_EQ(t.overlapped().size(), overlap ? 5u : 0u);
    EXPECT_EQ(frame.samples_accumulated(), 1u + 5u + (frame.pipeline_statistics_available() ? 1u : 0u));
    return std::pair{frame.read_color().rgba, t.total_counters()};
  };
  const auto [with_image, with_counters] = run(true);
  const auto [without_image, without_counters] = run(false);
  EXPECT_EQ(with_counters, without_counters);
  EXPECT_GT(with_counters.get("reflections", counter::rays_cast), 0u);
  ASSERT_EQ(with_image.size(), without_image.size());
  size_t differing = 0;
  for (size_t i = 0; i < with_image.size(); ++i) differing += with_image[i] != without_image[i];
  EXPECT_EQ(differing, 0u) << "of " << with_image.size() << " channel values";
}

// The driver version every result records: Mesa's release from driverInfo (lavapipe's driverVersion field
// reads 0.0.1 whatever the release), NVIDIA's own bit layout, the API layout for other vendors.
TEST(DeviceInfo, DriverVersionNamesTheRelease) {
  EXPECT_EQ(vk::driver_version_string("Mesa 25.0.7-2~bpo12+1 (LLVM 15.0.6)", 0x10005, VK_MAKE_API_VERSION(0, 0, 0, 1)),
            "25.0.7-2~bpo12+1");
  EXPECT_EQ(vk::driver_version_string("Mesa 22.3.6", 0x10005, 1), "22.3.6");
  EXPECT_EQ(vk::driver_version_string("580.95.05", 0x10DE, (580u << 22) | (95u << 14) | (5u << 6)), "580.95.5.0");
  EXPECT_EQ(vk::driver_version_string("", 0x1002, VK_MAKE_API_VERSION(0, 2, 0, 301)), "2.0.301");
}

// The fallback for a queue without timestamps, run on purpose: each pass is its own submission timed on the
// host, in order and without overlap, labelled cpu-wall; no query overhead is measured (there are no
// queries), the counters are still read, and the timeline still nests.
TEST(Profile, HostTimingFallbackTimesEachPassInOrder) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:cornell");
  FrameSettings s;
  s.width = 48;
  s.height = 32;
  s.rt.shadows = true;
  s.rt.reflections = true;
  s.rt.counters = true;
  s.host_timing = true;
  Frame frame(*ctx, scene, scene.camera, s);
  ASSERT_FALSE(frame.timestamps_supported());
  ProfileOptions o;
  o.warmup = 1;
  o.frames = 3;
  const FrameTimings t = profile_frames(frame, o);
  EXPECT_EQ(t.source(), TimingSource::CpuWall);
  EXPECT_FALSE(t.query_overhead().has_value());
  const std::vector<std::string> order = {"gbuffer", "shadows", "reflections", "accumulate", "composite"};
  for (const FrameSample& f : t.measured()) {
    ASSERT_EQ(f.passes.size(), order.size());
    for (size_t k = 0; k < order.size(); ++k) {
      EXPECT_EQ(f.passes[k].pass, order[k]);
      EXPECT_GT(f.passes[k].end_ns, f.passes[k].begin_ns) << order[k];
      if (k > 0) {
        EXPECT_LE(f.passes[k - 1].end_ns, f.passes[k].begin_ns) << order[k];
      }
    }
    EXPECT_LE(f.passes.back().end_ns, f.cpu_wall_ns) << "passes lie inside the frame's own wall time";
    EXPECT_GT(f.counters.get("shadows", counter::rays_cast), 0u);
  }
  EXPECT_EQ(t.summarize().source, TimingSource::CpuWall);
  const std::vector<std::string> problems = check_timeline(build_timeline(t));
  EXPECT_TRUE(problems.empty()) << problems.front();
  EXPECT_NE(host_timing_note(true).find("cpu-wall"), std::string::npos);
  EXPECT_NE(host_timing_note(false).find("timestampValidBits = 0"), std::string::npos);
}

// Without warm-up, extra untimed frames come before the measured ones (they accumulate like any frame):
// one without queries, the Frame's first, and one counting the invocations; the measured frames still
// carry no pipeline statistics.
TEST(Profile, InvocationsWithoutWarmupTakeOneExtraFrame) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:cornell");
  FrameSettings s;
  s.width = 40;
  s.height = 24;
  s.rt.shadows = true;
  s.rt.counters = true;
  Frame frame(*ctx, scene, scene.camera, s);
  ProfileOptions o;
  o.warmup = 0;
  o.frames = 2;
  o.measure_query_overhead = false;
  EXPECT_FALSE(frame.first_frame_queries().has_value());
  const FrameTimings t = profile_frames(frame, o);
  ASSERT_EQ(t.measured().size(), 2u);
  EXPECT_EQ(frame.first_frame_queries(), std::optional<FrameQueries>(FrameQueries::none));
  for (const auto& f : t.measured()) EXPECT_EQ(f.counters.total(counter::compute_invocations), 0u);
  // 2 measured frames, the first frame without queries, and a frame counting the invocations.
  const bool stats = frame.pipeline_statistics_available();
  EXPECT_EQ(frame.samples_accumulated(), 2u + (frame.timestamps_supported() || stats ? 1u : 0u) + (stats ? 1u : 0u));
  if (frame.pipeline_statistics_available()) {
    EXPECT_EQ(t.frame_invocations().get("shadows", counter::compute_invocations), 40u * 24u);
  } else {
    EXPECT_TRUE(t.frame_invocations().empty());
  }
}

// Audit find (2026-11-30): a frame with no ray-tracing pass still rendered an extra frame to count
// invocations it never reports (the counters come with the ray passes).
TEST(Profile, NoRayPassNoInvocationFrame) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:cornell");
  FrameSettings s;
  s.width = 40;
  s.height = 24;
  s.rt.counters = true;  // asked for, but there is nothing to count
  Frame frame(*ctx, scene, scene.camera, s);
  EXPECT_FALSE(frame.pipeline_statistics_available());
  ProfileOptions o;
  o.warmup = 1;
  o.frames = 2;
  o.measure_query_overhead = false;
  const FrameTimings t = profile_frames(frame, o);
  EXPECT_TRUE(t.frame_invocations().empty());
  EXPECT_EQ(frame.samples_accumulated(), 3u) << "1 warm-up + 2 measured frames, no extra counting frame";
}

}  // namespace
}  // namespace hp
