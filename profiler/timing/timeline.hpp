// The run as a Chrome Trace Event / Perfetto JSON timeline: {"traceEvents": [...]}, which
// ui.perfetto.dev and chrome://tracing open.
//
// Layout: pid 1 is the process ("hybridprof"); each queue is a thread track (tid 1, 2, ... in order
// of first appearance), named by "M" metadata events. Per measured frame and per queue that ran a
// pass in it: one "X" complete event "frame N" (cat "frame") spanning the frame, and one "X" event per
// pass (cat "pass") nested inside it. Counter tracks ("C" events, one per frame at the frame's start,
// plus a closing sample at the end of the last frame) carry rays cast and nodes visited summed over
// the frame's passes, when the frames have counters. The measured frames' passes are serialized
// (PassIsolation), so no pass interval holds another pass's work. The frames timed as the application
// records them (FrameTimings::overlapped(), GPU timestamps only) get a track of their own after the
// queues: one "frame (overlapped)" X event each and no pass inside, since with the passes free to overlap
// no boundary between them can be timed. ts/dur are microseconds as floats; the time base is the
// earliest timestamp of the measured and overlapped frames (it becomes 0).
//
// Perfetto drops X events on one track that overlap without nesting, so the builder enforces strict
// nesting, deterministically, and counts what it changed:
//   - a frame that starts before the previous frame ends starts at that end instead;
//   - a pass is clamped into its (possibly trimmed) frame;
//   - passes of one frame on one track are sorted by (begin, end, input order) and a pass that starts
//     before the previous one ends starts at that end instead (zero duration when fully covered).
// The raw samples in the JSON result stay untouched; only the picture is adjusted.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "timing/frame_timings.hpp"

namespace hp {

struct TimelineFixes {
  std::size_t frames_trimmed = 0;  // frame starts moved to the previous frame's end
  std::size_t passes_clamped = 0;  // passes cut to their frame's span
  std::size_t passes_trimmed = 0;  // pass starts moved to the previous pass's end on the track
  std::size_t total() const { return frames_trimmed + passes_clamped + passes_trimmed; }
  bool operator==(const TimelineFixes&) const = default;
};

struct TimelineOptions {
  std::string process_name = "hybridprof";
  bool counter_tracks = true;
};

// Builds the trace document for the measured frames of `timings`; `fixes` (optional) receives what
// the nesting rules changed. The document also carries "otherData" {timing_source, fixes}.
nlohmann::json build_timeline(const FrameTimings& timings, TimelineFixes* fixes = nullptr,
                              const TimelineOptions& options = {});

// Nanoseconds as the microsecond double the trace holds, chosen so that both ways importers turn it
// back into nanoseconds (older Perfetto truncates ts*1000, newer rounds it) give `ns` exactly; a
// plain ns/1000.0 can come back 1 ns short under truncation and break nesting at shared edges.
double ns_to_trace_us(std::uint64_t ns);

// build_timeline written atomically (temporary file + rename); returns the fixes.
TimelineFixes write_timeline(const std::filesystem::path& path, const FrameTimings& timings,
                             const TimelineOptions& options = {});

// Checks a trace document the way Perfetto's importer needs it: "traceEvents" is an array; each
// event has ph, and X events have numeric ts >= 0 and dur >= 0, pid and tid; on each (pid, tid), X
// events nest strictly (each either contains the next or ends before it starts, compared in whole
// nanoseconds after rounding ts*1000), and ts*1000, dur*1000 truncate and round to the same
// nanosecond (so importers of either kind agree). Returns one message per problem; empty means well formed.
std::vector<std::string> check_timeline(const nlohmann::json& trace);

}  // namespace hp
