// Runs a Frame W + F times and turns what it reports into the profiler's timing model: per-pass GPU
// intervals, CPU wall time, deterministic counters, the environment, and the overhead of the timestamp
// queries themselves (frames with and without them, interleaved).
#pragma once

#include "frame.hpp"
#include "timing/environment.hpp"
#include "timing/frame_timings.hpp"
#include "vk/context.hpp"

#include <functional>

namespace hp {

struct ProfileOptions {
  uint32_t warmup = 3;   ///< frames run and discarded first (lavapipe's first frames are 5-60% slower)
  uint32_t frames = 10;  ///< measured frames
  /// Also run `frames` frames without queries, interleaved with the measured ones, and record the
  /// difference of the median CPU wall times as the query overhead.
  bool measure_query_overhead = true;
  /// Also run, beside each measured frame, the frame as the application records it (FrameQueries::
  /// frame_span: no dependency added between passes), for FrameTimings::overlapped(): what overlapping
  /// passes saves against the serialized frames whose pass times the tables show.
  bool measure_overlap = true;
  /// Count compute invocations (pipeline statistics) in a frame outside the timed ones. A later round of
  /// an interleaved cell has them from its first round already.
  bool count_invocations = true;
  /// Called after each warm-up and measured frame with (frames done, frames in all): progress for a command.
  std::function<void(uint32_t done, uint32_t total)> on_frame;
};

/// The one-line note for a run whose passes are timed on the host (Frame::timestamps_supported() false):
/// why — the queue has no timestamps, or `asked` (FrameSettings::host_timing) — and what the times include.
std::string host_timing_note(bool asked);

/// The device part of the environment.
DeviceDescription describe_device(const vk::Context& ctx);

/// One Frame::render() result as a FrameSample; `counters` (may be null) become per-pass counters
/// (rays_cast, nodes_visited, triangles_tested under "shadows" and "reflections").
FrameSample to_frame_sample(const FrameTiming& timing, const RayCounters* counters);

/// Profiles `frame`: W warm-up frames, then F measured ones. Counters are read after each measured frame
/// when the frame's settings ask for them (outside the timed interval). The first warm-up frame records
/// no query (on lavapipe, queries in a Frame's first frame slow its G-buffer pass for good; with W = 0 an
/// extra frame does this). Compute invocations per pass (pipeline statistics) are counted in the last
/// warm-up frame (with W < 2, in one extra frame after the first) and stored as
/// FrameTimings::frame_invocations(): the measured frames record timestamps and nothing else.
/// `overhead_samples` (optional) receives the raw CPU wall times behind the query overhead, for pooling the
/// rounds of an interleaved cell (FrameTimings::pool_rounds).
FrameTimings profile_frames(Frame& frame, const ProfileOptions& options,
                            QueryOverheadSamples* overhead_samples = nullptr);

}  // namespace hp
