// Per-frame timing samples and the collector that turns a run of frames into per-pass statistics.
//
// The caller (the frame's timestamp-query code) converts ticks to nanoseconds with
// timestampPeriod and masks them with timestampValidBits before building a PassSample; everything
// here works on plain nanoseconds and knows nothing about Vulkan.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "timing/counters.hpp"
#include "timing/stats.hpp"

namespace hp {

// One pass of one frame: begin/end on the timing source's clock, in nanoseconds.
struct PassSample {
  std::string pass;
  std::uint64_t begin_ns = 0;
  std::uint64_t end_ns = 0;
  // The queue the pass ran on; one timeline track per queue.
  std::string queue = "graphics";

  std::uint64_t duration_ns() const { return end_ns >= begin_ns ? end_ns - begin_ns : 0; }
  bool operator==(const PassSample&) const = default;
};

struct FrameSample {
  std::vector<PassSample> passes;
  // CPU wall time of the frame (record + submit + wait), from a steady clock.
  std::uint64_t cpu_wall_ns = 0;
  // The frame's own span on the timing source's clock (e.g. a TOP_OF_PIPE timestamp before the first
  // pass and one after the last). Absent: the span of the passes (earliest begin, latest end).
  std::optional<std::uint64_t> begin_ns;
  std::optional<std::uint64_t> end_ns;
  // Work counters of this frame (empty when the scenario does not ask for them).
  Counters counters;
  // The round of an interleaved run this frame was measured in (0 in a run of one round): the runner
  // visits every cell once per round, so frames of one round ran close together in time.
  std::uint32_t round = 0;

  // Span actually used: the explicit one, else the passes'; {0, 0} for a frame with neither.
  std::uint64_t span_begin_ns() const;
  std::uint64_t span_end_ns() const;
  std::uint64_t duration_ns() const { return span_end_ns() - span_begin_ns(); }
  bool operator==(const FrameSample&) const = default;
};

enum class TimingSource {
  GpuTimestamps,  // vkCmdWriteTimestamp around each pass
  CpuWall,        // the queue has no timestamp support: CPU clock around submit/wait per pass
};

// What keeps one pass's interval free of another pass's work.
enum class PassIsolation {
  // An execution dependency (ALL_COMMANDS -> ALL_COMMANDS) before every pass boundary timestamp: a pass
  // starts only when the previous one is done, so each interval holds one pass. A device that overlaps
  // independent passes (Mesa 25 lavapipe, every GPU) loses that overlap in these frames; the frame as the
  // application records it is timed beside them (FrameTimings::overlapped()).
  Serialized,
  // One submission per pass, waited for on the host (TimingSource::CpuWall).
  HostSubmissions,
  // Boundary timestamps with no added dependency (results written before isolation existed): on a device
  // that overlaps passes a boundary can fall inside the next pass's work, and an interval may hold parts
  // of two passes.
  Unisolated,
};
// "serialized" / "host-submissions" / "unisolated".
std::string_view to_string(PassIsolation isolation);
// Inverse of to_string; throws std::invalid_argument on anything else.
PassIsolation pass_isolation_from_string(std::string_view text);

// The span of a frame on the timing source's clock.
struct FrameSpan {
  std::uint64_t begin_ns = 0;
  std::uint64_t end_ns = 0;
  std::uint64_t duration_ns() const { return end_ns >= begin_ns ? end_ns - begin_ns : 0; }
  bool operator==(const FrameSpan&) const = default;
};

// "gpu-timestamps" / "cpu-wall".
std::string_view to_string(TimingSource source);
// Inverse of to_string; throws std::invalid_argument on anything else.
TimingSource timing_source_from_string(std::string_view text);

// Cost of the queries themselves: median frame time over frames with and without the timestamp
// queries, measured and filled in by the caller; and, when the frames were interleaved in pairs, the
// paired estimate: the median of each pair's relative difference (with - without) / without, with its
// distribution-free 95% CI. Pairing adjacent frames cancels the drift of a shared machine, which moves
// the two medians apart by several percent from run to run.
struct QueryOverhead {
  double frame_ns_with_queries = 0.0;
  double frame_ns_without_queries = 0.0;
  std::uint32_t frames = 0;               // frames per side
  std::optional<double> paired_fraction;  // median of the pairs' relative differences
  MedianCi paired_fraction_ci;            // its order-statistic CI (valid from 6 pairs)

  double overhead_ns() const { return frame_ns_with_queries - frame_ns_without_queries; }
  // overhead_ns / frame_ns_without_queries; 0 when the baseline is 0. Target: under 0.01.
  double overhead_fraction() const;
  bool operator==(const QueryOverhead&) const = default;
};

// The overhead of frames with queries over their paired frames without (same length, pairs by index).
QueryOverhead paired_query_overhead(std::span<const double> with_queries, std::span<const double> without_queries);

// The frame as the application records it (no dependency added between passes, timestamps only at the
// frame's start and end) against the serialized frames' sum of pass times. Frame i of each kind ran next
// to the other (alternating which went first), so the paired differences cancel the machine's drift.
struct OverlapSummary {
  std::uint32_t frames = 0;     // pairs
  Summary overlapped_frame_ns;  // the overlapped frames' spans
  Summary serialized_sum_ns;    // per serialized frame: the sum of its pass times
  // Median of the pairs' (serialized sum - overlapped span), in ns and as a fraction of the serialized
  // sum, with their order-statistic CIs (valid from 6 pairs). Positive: overlap saves time.
  std::optional<double> saving_ns;
  MedianCi saving_ns_ci;
  std::optional<double> saving_fraction;
  MedianCi saving_fraction_ci;
  bool operator==(const OverlapSummary&) const = default;
};

// The frames without queries beside the measured ones (profile_frames), raw, so that the rounds of an
// interleaved cell can be pooled into one paired estimate: CPU wall times, one per measured frame.
struct QueryOverheadSamples {
  std::vector<double> with_queries, without_queries;
};

// Pairs serialized frame sums with the overlapped spans (same length, pairs by index).
OverlapSummary paired_overlap(std::span<const double> serialized_sum_ns, std::span<const double> overlapped_ns);

struct PassSummary {
  std::string pass;
  Summary duration_ns;
  bool operator==(const PassSummary&) const = default;
};

struct TimingSummary {
  TimingSource source = TimingSource::GpuTimestamps;
  PassIsolation pass_isolation = PassIsolation::Serialized;
  std::uint32_t warmup_frames = 0;
  std::uint32_t measured_frames = 0;
  // One per pass name in order of first appearance. A pass recorded several times in one frame
  // contributes the sum of its durations as that frame's sample; a pass absent from some frames has
  // a smaller count.
  std::vector<PassSummary> passes;
  Summary frame_ns;     // frame span on the timing source's clock
  Summary cpu_wall_ns;  // CPU wall time per frame
  std::optional<QueryOverhead> query_overhead;
  std::optional<OverlapSummary> overlap;  // when overlapped frames were timed beside the measured ones
  bool operator==(const TimingSummary&) const = default;
};

// Collects a run: discards the first `warmup` frames (the first runs on lavapipe are 5-60% slower),
// then keeps `measured` frames with their raw samples.
class FrameTimings {
 public:
  FrameTimings(std::uint32_t warmup, std::uint32_t measured, TimingSource source);

  // Hands over one frame. Returns true while more frames are wanted (so `while (t.add(f()))` runs
  // exactly warmup + measured frames). Throws std::logic_error once the run is complete, and
  // std::invalid_argument for a pass ending before it begins.
  bool add(FrameSample frame);

  bool complete() const { return measured_.size() == measured_wanted_; }
  std::uint32_t warmup_frames() const { return warmup_wanted_; }
  std::uint32_t warmup_seen() const { return warmup_seen_; }
  std::uint32_t measured_wanted() const { return measured_wanted_; }
  const std::vector<FrameSample>& measured() const { return measured_; }
  TimingSource source() const { return source_; }

  void set_query_overhead(const QueryOverhead& overhead) { overhead_ = overhead; }
  const std::optional<QueryOverhead>& query_overhead() const { return overhead_; }

  // How the passes of the measured frames were kept apart. Default: Serialized for GPU timestamps,
  // HostSubmissions for CPU wall clocks.
  PassIsolation pass_isolation() const { return isolation_; }
  void set_pass_isolation(PassIsolation isolation) { isolation_ = isolation; }

  // The frames as the application records them, one per measured frame and run next to it (empty when
  // not measured). Summarized as TimingSummary::overlap once there is one per measured frame.
  void add_overlapped(FrameSpan span) { overlapped_.push_back(span); }
  const std::vector<FrameSpan>& overlapped() const { return overlapped_; }

  // Per-pass and whole-frame statistics over the measured frames (at least one needed, else
  // std::logic_error).
  TimingSummary summarize(const SummaryOptions& options = {}) const;

  // Sum of every measured frame's counters.
  Counters total_counters() const;

  // Compute-shader invocations per pass in one frame (counter::compute_invocations), from pipeline
  // statistics queries recorded in a frame outside the timed ones, so that those carry timestamps only
  // (profile_frames); empty when not counted. Invocations are fixed by the dispatch sizes, so one
  // frame's count holds for every frame of the run.
  void set_frame_invocations(Counters per_frame) { invocations_ = std::move(per_frame); }
  const Counters& frame_invocations() const { return invocations_; }

  // Rebuilds a finished collector from stored frames (reading a result back).
  static FrameTimings from_measured(std::uint32_t warmup, TimingSource source, std::vector<FrameSample> measured,
                                    std::optional<QueryOverhead> overhead, Counters frame_invocations = {},
                                    std::vector<FrameSpan> overlapped = {},
                                    std::optional<PassIsolation> isolation = std::nullopt);

  bool operator==(const FrameTimings&) const = default;

  // The rounds of one interleaved cell pooled into one run: the measured frames in round order, each
  // marked with its round (its index in `rounds`), the overlapped frames likewise, the query-overhead
  // pairs of every round in one paired estimate (from `overhead`, one entry per round; empty entries where
  // none was measured), warm-up and invocation counts of the first round. At least one round, every round
  // of the same timing source and isolation, else std::invalid_argument.
  static FrameTimings pool_rounds(const std::vector<FrameTimings>& rounds,
                                  const std::vector<QueryOverheadSamples>& overhead);

 private:
  std::uint32_t warmup_wanted_ = 0;
  std::uint32_t measured_wanted_ = 0;
  std::uint32_t warmup_seen_ = 0;
  TimingSource source_ = TimingSource::GpuTimestamps;
  std::vector<FrameSample> measured_;
  std::optional<QueryOverhead> overhead_;
  Counters invocations_;
  PassIsolation isolation_ = PassIsolation::Serialized;
  std::vector<FrameSpan> overlapped_;
};

}  // namespace hp
