#include "frame_profiler.hpp"

#include "timing/stats.hpp"

#include <algorithm>

namespace hp {

std::string host_timing_note(bool asked) {
  return std::string(asked ? "passes timed on the host as asked (--host-timing)"
                           : "this queue has no timestamp support (timestampValidBits = 0), so passes are timed "
                             "on the host") +
         ": one submission per pass, each time including its submit and wait (labelled cpu-wall); the query "
         "overhead is not measured";
}

DeviceDescription describe_device(const vk::Context& ctx) {
  const vk::DeviceInfo& i = ctx.info();
  return {i.name, i.type, i.driver_name, i.driver_info, i.driver_version, i.api_version};
}

FrameSample to_frame_sample(const FrameTiming& timing, const RayCounters* c) {
  FrameSample s;
  for (const auto& p : timing.passes) s.passes.push_back({p.name, p.begin_ns, p.end_ns, "graphics"});
  s.cpu_wall_ns = timing.cpu_wall_ns;
  if (c) {
    s.counters.set("shadows", counter::rays_cast, c->shadow_rays);
    s.counters.set("shadows", counter::nodes_visited, c->shadow_nodes);
    s.counters.set("shadows", counter::triangles_tested, c->shadow_tris);
    s.counters.set("reflections", counter::rays_cast, c->reflection_rays + c->reflection_shadow_rays);
    s.counters.set("reflections", "reflection_rays", c->reflection_rays);
    s.counters.set("reflections", "shadow_rays_at_hits", c->reflection_shadow_rays);
    s.counters.set("reflections", counter::nodes_visited, c->reflection_nodes);
    s.counters.set("reflections", counter::triangles_tested, c->reflection_tris);
    if (c->reprojected) {
      s.counters.set("reflections", "reprojection_misplaced", c->reprojection_misplaced);
      s.counters.set("reflections", "reprojection_unwritten", c->reprojection_unwritten);
    }
  }
  return s;
}

FrameTimings profile_frames(Frame& frame, const ProfileOptions& o, QueryOverheadSamples* overhead_samples) {
  const bool gpu = frame.timestamps_supported();
  FrameTimings timings(o.warmup, o.frames, gpu ? TimingSource::GpuTimestamps : TimingSource::CpuWall);
  const bool counters =
      frame.settings().rt.counters && (frame.settings().rt.shadows || frame.settings().rt.reflections);
  // The first frame records no query. On lavapipe (Mesa 22.3) timestamps or pipeline statistics in a
  // Frame's very first frame leave its G-buffer pass slower in every later frame, timed or not (19-24 ms
  // instead of 13-18 ms at 640x360; a 320x180 G-buffer + composite frame 20 ms instead of 10-13 ms:
  // docs/timing.md, "The first frame"). One frame without queries first avoids it: the first warm-up frame, or an
  // extra frame without warm-up. Invocation counts come from a frame of their own too, so that the timed
  // frames carry timestamps only: the last warm-up frame when there are two or more (its times are
  // discarded anyway), else one extra frame after the first.
  const bool statistics = o.count_invocations && frame.pipeline_statistics_available();
  auto count_invocations = [&] {
    const FrameTiming t = frame.render(FrameQueries::pipeline_statistics);
    Counters per_frame;
    for (const auto& [pass, n] : t.compute_invocations) per_frame.set(pass, counter::compute_invocations, n);
    timings.set_frame_invocations(std::move(per_frame));
    return t;
  };
  if (o.warmup == 0 && (gpu || statistics)) frame.render(FrameQueries::none);
  bool counted = false;
  uint32_t done = 0;
  const auto progress = [&] {
    if (o.on_frame) o.on_frame(++done, o.warmup + o.frames);
  };
  for (uint32_t i = 0; i < o.warmup; ++i) {
    const bool count = statistics && i > 0 && i + 1 == o.warmup;
    counted = counted || count;
    timings.add(to_frame_sample(i == 0  ? frame.render(FrameQueries::none)
                                : count ? count_invocations()
                                        : frame.render(),
                                nullptr));
    progress();
  }
  if (statistics && !counted) count_invocations();
  std::vector<double> with_queries, without_queries;
  // The overlapped frame repeats the measured frame's sample (Frame::render_overlapped): the same work.
  auto overlapped = [&](bool previous) {
    const FrameTiming f = frame.render_overlapped(previous);
    timings.add_overlapped({f.span->begin_ns, f.span->end_ns});
  };
  for (uint32_t i = 0; i < o.frames; ++i) {
    // Frames without queries alternate before and after the measured one (A B B A ...), so that neither
    // side is always the first after a readback; the overlapped frames alternate the other way round, so
    // each of the two kinds of extra frame is next to the measured one.
    const bool overhead = o.measure_query_overhead && gpu;
    if (overhead && i % 2 == 1) without_queries.push_back(double(frame.render(FrameQueries::none).cpu_wall_ns));
    if (o.measure_overlap && i % 2 == 0) overlapped(false);
    const FrameTiming t = frame.render();
    with_queries.push_back(double(t.cpu_wall_ns));
    RayCounters c;
    if (counters) c = frame.read_counters();
    if (o.measure_overlap && i % 2 == 1) overlapped(true);
    timings.add(to_frame_sample(t, counters ? &c : nullptr));
    if (overhead && i % 2 == 0) without_queries.push_back(double(frame.render(FrameQueries::none).cpu_wall_ns));
    progress();
  }
  // Frame i with queries pairs with the frame without that ran next to it (after it for even i, before
  // it for odd i): both vectors hold one entry per i.
  if (!without_queries.empty()) {
    timings.set_query_overhead(paired_query_overhead(with_queries, without_queries));
    if (overhead_samples) *overhead_samples = {std::move(with_queries), std::move(without_queries)};
  }
  return timings;
}

}  // namespace hp
