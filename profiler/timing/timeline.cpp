#include "timing/timeline.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <utility>

#include "timing/result_json.hpp"

namespace hp {

using nlohmann::json;

namespace {

constexpr int kPid = 1;

struct Span {
  std::uint64_t begin;
  std::uint64_t end;
};

}  // namespace

double ns_to_trace_us(std::uint64_t ns) {
  const double target = static_cast<double>(ns);
  double us = target / 1000.0;
  // One step up is enough: the quotient is correctly rounded, so us*1000 is within an ulp of ns.
  while (us * 1000.0 < target) us = std::nextafter(us, std::numeric_limits<double>::infinity());
  return us;
}

// One frame's span and its passes on one queue's track: passes clamped to the frame and trimmed so that
// none starts before the previous one ends (ties keep input order); `fixes` counts what was moved.
template <class ToUs>
void add_frame_track(json& events, const FrameSample& f, std::size_t i, Span frame, int tid,
                     const std::vector<std::size_t>& indices, const ToUs& us, TimelineFixes& fixes) {
  events.push_back({{"ph", "X"},
                    {"name", "frame"},
                    {"cat", "frame"},
                    {"pid", kPid},
                    {"tid", tid},
                    {"ts", us(frame.begin)},
                    {"dur", ns_to_trace_us(frame.end - frame.begin)},
                    {"args", {{"frame", i}, {"frame_ns", f.duration_ns()}, {"cpu_wall_ns", f.cpu_wall_ns}}}});

  std::vector<Span> spans;
  for (std::size_t k : indices) {
    const PassSample& p = f.passes[k];
    Span s{std::clamp(p.begin_ns, frame.begin, frame.end), std::clamp(p.end_ns, frame.begin, frame.end)};
    if (s.begin != p.begin_ns || s.end != p.end_ns) ++fixes.passes_clamped;
    spans.push_back(s);
  }
  std::vector<std::size_t> order(indices.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    if (spans[a].begin != spans[b].begin) return spans[a].begin < spans[b].begin;
    return spans[a].end < spans[b].end;
  });
  std::uint64_t prev_end = frame.begin;
  for (std::size_t o : order) {
    Span s = spans[o];
    if (s.begin < prev_end) {
      s.begin = prev_end;
      s.end = std::max(s.end, s.begin);
      ++fixes.passes_trimmed;
    }
    prev_end = s.end;
    const PassSample& p = f.passes[indices[o]];
    events.push_back({{"ph", "X"},
                      {"name", p.pass},
                      {"cat", "pass"},
                      {"pid", kPid},
                      {"tid", tid},
                      {"ts", us(s.begin)},
                      {"dur", ns_to_trace_us(s.end - s.begin)},
                      {"args", {{"frame", i}, {"duration_ns", p.duration_ns()}}}});
  }
}

// The frames timed as the application records them (Frame::render_overlapped), on track `tid`.
template <class ToUs>
void add_overlapped_track(json& events, const FrameTimings& timings, int tid, const ToUs& us, TimelineFixes& fixes) {
  events.push_back({{"ph", "M"},
                    {"name", "thread_name"},
                    {"pid", kPid},
                    {"tid", tid},
                    {"args", {{"name", "frame as recorded (passes free to overlap)"}}}});
  events.push_back(
      {{"ph", "M"}, {"name", "thread_sort_index"}, {"pid", kPid}, {"tid", tid}, {"args", {{"sort_index", tid}}}});
  std::uint64_t prev_end = 0;
  for (std::size_t i = 0; i < timings.overlapped().size(); ++i) {
    Span o{timings.overlapped()[i].begin_ns, timings.overlapped()[i].end_ns};
    if (i > 0 && o.begin < prev_end) {
      o.begin = prev_end;
      o.end = std::max(o.end, o.begin);
      ++fixes.frames_trimmed;
    }
    prev_end = o.end;
    events.push_back({{"ph", "X"},
                      {"name", "frame (overlapped)"},
                      {"cat", "frame"},
                      {"pid", kPid},
                      {"tid", tid},
                      {"ts", us(o.begin)},
                      {"dur", ns_to_trace_us(o.end - o.begin)},
                      {"args", {{"paired_with_frame", i}, {"frame_ns", timings.overlapped()[i].duration_ns()}}}});
  }
}

json build_timeline(const FrameTimings& timings, TimelineFixes* fixes_out, const TimelineOptions& options) {
  const std::vector<FrameSample>& frames = timings.measured();
  TimelineFixes fixes;

  // Common time base: the earliest timestamp of the run is 0.
  std::uint64_t t0 = std::numeric_limits<std::uint64_t>::max();
  for (const FrameSample& f : frames) {
    t0 = std::min(t0, f.span_begin_ns());
    for (const PassSample& p : f.passes) t0 = std::min(t0, p.begin_ns);
  }
  // The overlapped frames share the clock only when they come from the device's timestamps (host-timed
  // frames start at 0 each).
  const bool overlapped_track = timings.source() == TimingSource::GpuTimestamps && !timings.overlapped().empty();
  if (overlapped_track)
    for (const FrameSpan& o : timings.overlapped()) t0 = std::min(t0, o.begin_ns);
  if (frames.empty() && !overlapped_track) t0 = 0;
  const auto us = [t0](std::uint64_t ns) { return ns_to_trace_us(ns - t0); };

  // Tracks: one per queue, numbered in order of first appearance, so the file is deterministic.
  std::vector<std::string> queues;
  for (const FrameSample& f : frames)
    for (const PassSample& p : f.passes)
      if (std::find(queues.begin(), queues.end(), p.queue) == queues.end()) queues.push_back(p.queue);
  const auto tid_of = [&](const std::string& queue) {
    return static_cast<int>(std::find(queues.begin(), queues.end(), queue) - queues.begin()) + 1;
  };

  json events = json::array();
  events.push_back(
      {{"ph", "M"}, {"name", "process_name"}, {"pid", kPid}, {"tid", 0}, {"args", {{"name", options.process_name}}}});
  for (std::size_t q = 0; q < queues.size(); ++q) {
    const int tid = static_cast<int>(q) + 1;
    events.push_back({{"ph", "M"},
                      {"name", "thread_name"},
                      {"pid", kPid},
                      {"tid", tid},
                      {"args", {{"name", queues[q] + " queue"}}}});
    events.push_back(
        {{"ph", "M"}, {"name", "thread_sort_index"}, {"pid", kPid}, {"tid", tid}, {"args", {{"sort_index", tid}}}});
  }

  static constexpr const char* counter_names[] = {counter::rays_cast, counter::nodes_visited};
  std::map<std::string, bool> counter_present;
  for (const FrameSample& f : frames)
    for (const auto& [pass, counters] : f.counters.passes())
      for (const char* name : counter_names)
        if (counters.contains(name)) counter_present[name] = true;

  std::uint64_t prev_frame_end = 0;
  bool have_prev = false;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const FrameSample& f = frames[i];
    Span frame{f.span_begin_ns(), f.span_end_ns()};
    if (have_prev && frame.begin < prev_frame_end) {
      frame.begin = prev_frame_end;
      frame.end = std::max(frame.end, frame.begin);
      ++fixes.frames_trimmed;
    }
    prev_frame_end = frame.end;
    have_prev = true;

    // Group this frame's passes by track, keeping input order for the tie-break.
    std::map<int, std::vector<std::size_t>> by_track;
    for (std::size_t k = 0; k < f.passes.size(); ++k) by_track[tid_of(f.passes[k].queue)].push_back(k);

    for (auto& [tid, indices] : by_track) add_frame_track(events, f, i, frame, tid, indices, us, fixes);

    if (options.counter_tracks) {
      for (const char* name : counter_names) {
        if (!counter_present[name]) continue;
        events.push_back({{"ph", "C"},
                          {"name", name},
                          {"pid", kPid},
                          {"ts", us(frame.begin)},
                          {"args", {{name, f.counters.total(name)}}}});
        // The last sample would otherwise have no extent: repeat it at the end of the last frame.
        if (i + 1 == frames.size()) {
          events.push_back({{"ph", "C"},
                            {"name", name},
                            {"pid", kPid},
                            {"ts", us(frame.end)},
                            {"args", {{name, f.counters.total(name)}}}});
        }
      }
    }
  }

  // The frames as the application records them: one span each on a track of their own (no pass inside:
  // with the passes free to overlap, no boundary between them can be timed).
  if (overlapped_track) add_overlapped_track(events, timings, static_cast<int>(queues.size()) + 1, us, fixes);

  if (fixes_out != nullptr) *fixes_out = fixes;
  return {{"traceEvents", std::move(events)},
          {"displayTimeUnit", "ns"},
          {"otherData",
           {{"timing_source", std::string(to_string(timings.source()))},
            {"pass_isolation", std::string(to_string(timings.pass_isolation()))},
            {"time_base_ns", t0},
            {"frames_trimmed", fixes.frames_trimmed},
            {"passes_clamped", fixes.passes_clamped},
            {"passes_trimmed", fixes.passes_trimmed}}}};
}

TimelineFixes write_timeline(const std::filesystem::path& path, const FrameTimings& timings,
                             const TimelineOptions& options) {
  TimelineFixes fixes;
  // Compact output: a long run has many thousands of events.
  write_json_atomically(path, build_timeline(timings, &fixes, options), -1);
  return fixes;
}

std::vector<std::string> check_timeline(const json& trace) {
  std::vector<std::string> problems;
  if (!trace.is_object() || !trace.contains("traceEvents") || !trace["traceEvents"].is_array()) {
    problems.push_back("no \"traceEvents\" array");
    return problems;
  }
  struct Event {
    std::int64_t begin, end;
    std::size_t index;
    std::string name;
  };
  std::map<std::pair<std::int64_t, std::int64_t>, std::vector<Event>> tracks;
  const json& events = trace["traceEvents"];
  for (std::size_t i = 0; i < events.size(); ++i) {
    const json& e = events[i];
    const std::string where = "event " + std::to_string(i);
    if (!e.is_object() || !e.contains("ph") || !e["ph"].is_string()) {
      problems.push_back(where + ": no \"ph\"");
      continue;
    }
    const std::string ph = e["ph"];
    if (ph == "C" && !(e.contains("ts") && e["ts"].is_number() && e.contains("args") && e["args"].is_object())) {
      problems.push_back(where + ": counter event without ts or args");
    }
    if (ph != "X") continue;
    if (!e.contains("ts") || !e["ts"].is_number() || !e.contains("dur") || !e["dur"].is_number() ||
        !e.contains("pid") || !e["pid"].is_number_integer() || !e.contains("tid") || !e["tid"].is_number_integer()) {
      problems.push_back(where + ": X event needs numeric ts, dur, pid, tid");
      continue;
    }
    const double ts = e["ts"];
    const double dur = e["dur"];
    if (ts < 0 || dur < 0) {
      problems.push_back(where + ": negative ts or dur");
      continue;
    }
    // Whole nanoseconds, the resolution the importer keeps.
    const std::int64_t begin = std::llround(ts * 1000.0);
    const std::int64_t end = begin + std::llround(dur * 1000.0);
    if (static_cast<std::int64_t>(ts * 1000.0) != begin || static_cast<std::int64_t>(dur * 1000.0) != end - begin) {
      problems.push_back(where + ": ts or dur is not a whole nanosecond when truncated");
    }
    tracks[{e["pid"].get<std::int64_t>(), e["tid"].get<std::int64_t>()}].push_back(
        {begin, end, i, e.value("name", std::string())});
  }
  for (auto& [track, list] : tracks) {
    // Parents before children: earlier begin first, then the longer event, then file order.
    std::stable_sort(list.begin(), list.end(), [](const Event& a, const Event& b) {
      if (a.begin != b.begin) return a.begin < b.begin;
      return a.end > b.end;
    });
    std::vector<const Event*> open;
    for (const Event& e : list) {
      while (!open.empty() && open.back()->end <= e.begin) open.pop_back();
      if (!open.empty() && e.end > open.back()->end) {
        problems.push_back("pid " + std::to_string(track.first) + " tid " + std::to_string(track.second) + ": event " +
                           std::to_string(e.index) + " '" + e.name + "' [" + std::to_string(e.begin) + ", " +
                           std::to_string(e.end) + "] ns overlaps event " + std::to_string(open.back()->index) + " '" +
                           open.back()->name + "' [" + std::to_string(open.back()->begin) + ", " +
                           std::to_string(open.back()->end) + "] ns without nesting");
      }
      open.push_back(&e);
    }
  }
  return problems;
}

}  // namespace hp
