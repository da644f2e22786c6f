#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include "timing/timeline.hpp"
#include "timing_fixture.hpp"

namespace hp {
namespace {

using nlohmann::json;

std::vector<json> events_of(const json& trace, const std::string& ph, const std::string& cat = "") {
  std::vector<json> out;
  for (const json& e : trace["traceEvents"])
    if (e["ph"] == ph && (cat.empty() || e.value("cat", "") == cat)) out.push_back(e);
  return out;
}

FrameTimings run_of(std::vector<FrameSample> frames) {
  return FrameTimings::from_measured(0, TimingSource::GpuTimestamps, std::move(frames), std::nullopt);
}

TEST(TimelineChecker, AcceptsNestingAndRejectsOverlap) {
  // The checker itself must catch the failure Perfetto punishes, or the other tests prove nothing.
  const json good = {{"traceEvents",
                      {{{"ph", "X"}, {"name", "frame"}, {"pid", 1}, {"tid", 1}, {"ts", 0.0}, {"dur", 10.0}},
                       {{"ph", "X"}, {"name", "a"}, {"pid", 1}, {"tid", 1}, {"ts", 0.0}, {"dur", 4.0}},
                       {{"ph", "X"}, {"name", "b"}, {"pid", 1}, {"tid", 1}, {"ts", 4.0}, {"dur", 6.0}},
                       // Same times on another track do not interact.
                       {{"ph", "X"}, {"name", "c"}, {"pid", 1}, {"tid", 2}, {"ts", 2.0}, {"dur", 20.0}}}}};
  EXPECT_TRUE(check_timeline(good).empty());

  json overlap = good;
  overlap["traceEvents"][2]["ts"] = 3.999;  // b starts 1 ns before a ends
  const auto problems = check_timeline(overlap);
  ASSERT_EQ(problems.size(), 1u);
  EXPECT_NE(problems[0].find("'b'"), std::string::npos) << problems[0];

  json sticks_out = good;
  sticks_out["traceEvents"][2]["dur"] = ns_to_trace_us(6001);  // b ends 1 ns after its frame
  const auto out = check_timeline(sticks_out);
  ASSERT_EQ(out.size(), 1u);
  EXPECT_NE(out[0].find("'b'"), std::string::npos) << out[0];

  json inexact = good;
  inexact["traceEvents"][2]["ts"] = 4.0 - 1e-12;  // rounds to 4000 ns, truncates to 3999
  EXPECT_FALSE(check_timeline(inexact).empty());

  EXPECT_FALSE(check_timeline(json::object()).empty());
  EXPECT_FALSE(check_timeline(json{{"traceEvents", {{{"ph", "X"}, {"ts", 1.0}}}}}).empty());
}

TEST(Timeline, OverlappedFramesGetATrackOfTheirOwnWithNoPassInside) {
  std::vector<FrameSample> frames;
  for (std::uint64_t i = 0; i < 3; ++i) frames.push_back(test::synthetic_frame(i));
  // Each overlapped frame runs 650 us after its measured frame's start (the measured frame takes 600 us).
  std::vector<FrameSpan> overlapped;
  for (std::uint64_t i = 0; i < 3; ++i) {
    const std::uint64_t b = 5'000'000'000ull + i * 1'000'000 + 650'000;
    overlapped.push_back({b, b + 300'000});
  }
  const FrameTimings t =
      FrameTimings::from_measured(0, TimingSource::GpuTimestamps, frames, std::nullopt, {}, overlapped);
  TimelineFixes fixes;
  const json trace = build_timeline(t, &fixes);
  EXPECT_TRUE(check_timeline(trace).empty());
  EXPECT_EQ(fixes.total(), 0u);
  std::vector<json> spans;
  for (const json& e : events_of(trace, "X", "frame"))
    if (e["name"] == "frame (overlapped)") spans.push_back(e);
  ASSERT_EQ(spans.size(), 3u);
  const int tid = spans[0]["tid"];
  for (const json& e : events_of(trace, "X", "pass")) EXPECT_NE(e["tid"], tid) << "no pass on the overlapped track";
  for (const json& e : events_of(trace, "X", "frame")) {
    if (e["name"] == "frame") {
      EXPECT_NE(e["tid"], tid);
    }
  }
  EXPECT_DOUBLE_EQ(spans[1]["ts"].get<double>(), 1650.0);  // time base: the first measured frame's start
  EXPECT_DOUBLE_EQ(spans[1]["dur"].get<double>(), 300.0);
  bool named = false;
  for (const json& e : events_of(trace, "M"))
    named = named || (e["tid"] == tid && e["args"].value("name", "") == "frame as recorded (passes free to overlap)");
  EXPECT_TRUE(named);
  EXPECT_EQ(trace["otherData"]["pass_isolation"], "serialized");
  // Host-timed overlapped frames all start at 0 on their own clock: no track for them.
  const FrameTimings host = FrameTimings::from_measured(0, TimingSource::CpuWall, frames, std::nullopt, {}, overlapped);
  for (const json& e : events_of(build_timeline(host), "X")) EXPECT_NE(e["name"], "frame (overlapped)");
}

TEST(Timeline, MicrosecondsComeBackAsExactNanoseconds) {
  // Both importer conversions (truncate, round) and a text round trip must give the nanoseconds.
  std::size_t adjusted = 0;
  for (std::uint64_t ns = 0; ns < 300'000; ++ns) {
    const std::uint64_t big = ns * 7'919'999 + 123;  // up to ~40 minutes of timeline too
    for (std::uint64_t v : {ns, big}) {
      const double us = ns_to_trace_us(v);
      if (us != static_cast<double>(v) / 1000.0) ++adjusted;
      ASSERT_EQ(static_cast<std::uint64_t>(us * 1000.0), v) << v;
      ASSERT_EQ(static_cast<std::uint64_t>(std::llround(us * 1000.0)), v) << v;
    }
  }
  // The plain quotient does fall short for some values, so the adjustment is doing work.
  EXPECT_GT(adjusted, 0u);
  const double text_round_trip = json::parse(json(ns_to_trace_us(600'003)).dump()).get<double>();
  EXPECT_EQ(static_cast<std::uint64_t>(text_round_trip * 1000.0), 600'003u);
}

TEST(Timeline, WellFormedRunNestsAndHasEveryPart) {
  std::vector<FrameSample> frames;
  for (std::uint64_t i = 0; i < 5; ++i) frames.push_back(test::synthetic_frame(i));
  const FrameTimings run = run_of(frames);
  TimelineFixes fixes;
  const json trace = build_timeline(run, &fixes);

  EXPECT_EQ(fixes, TimelineFixes{});  // nothing needed fixing
  EXPECT_TRUE(check_timeline(trace).empty());

  // Metadata names the process and the one queue track.
  const auto meta = events_of(trace, "M");
  ASSERT_GE(meta.size(), 2u);
  EXPECT_EQ(meta[0]["name"], "process_name");
  EXPECT_EQ(meta[0]["args"]["name"], "hybridprof");
  EXPECT_EQ(meta[1]["name"], "thread_name");
  EXPECT_EQ(meta[1]["args"]["name"], "graphics queue");

  // One frame event per frame, 600 us + i ns long; the time base puts the first at 0.
  const auto frame_events = events_of(trace, "X", "frame");
  ASSERT_EQ(frame_events.size(), 5u);
  EXPECT_DOUBLE_EQ(frame_events[0]["ts"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(frame_events[0]["dur"].get<double>(), 600.0);
  EXPECT_DOUBLE_EQ(frame_events[3]["ts"].get<double>(), 3000.0);
  EXPECT_DOUBLE_EQ(frame_events[3]["dur"].get<double>(), 600.003);
  EXPECT_EQ(events_of(trace, "X", "pass").size(), 15u);

  // Counter tracks: rays and nodes per frame, summed over passes, plus one closing sample each.
  const auto counters = events_of(trace, "C");
  ASSERT_EQ(counters.size(), 2u * 5u + 2u);
  EXPECT_EQ(counters[0]["name"], "rays_cast");
  EXPECT_EQ(counters[0]["args"]["rays_cast"], 8192);
  EXPECT_EQ(counters[1]["name"], "nodes_visited");
  EXPECT_EQ(counters[1]["args"]["nodes_visited"], 130'000);
  EXPECT_EQ(trace["otherData"]["timing_source"], "gpu-timestamps");
}

TEST(Timeline, OverlappingPassesAreFixedDeterministically) {
  // Frame [0, 1000] ns (explicit). Input passes on one queue:
  //   a [100, 400], b [300, 600] (overlaps a by 100), c [550, 1200] (overlaps b, leaves the frame),
  //   d [50, 80] (given last but earliest: sorting must put it first, untouched).
  FrameSample f;
  f.begin_ns = 1'000'000;
  f.end_ns = 1'001'000;
  const std::uint64_t t = 1'000'000;
  f.passes = {{"a", t + 100, t + 400}, {"b", t + 300, t + 600}, {"c", t + 550, t + 1200}, {"d", t + 50, t + 80}};
  const FrameTimings run = run_of({f});

  // The raw samples overlap: written as they are, the checker rejects them.
  json raw = {{"traceEvents", json::array()}};
  for (const PassSample& p : f.passes)
    raw["traceEvents"].push_back({{"ph", "X"},
                                  {"name", p.pass},
                                  {"pid", 1},
                                  {"tid", 1},
                                  {"ts", static_cast<double>(p.begin_ns - t) / 1000.0},
                                  {"dur", static_cast<double>(p.end_ns - p.begin_ns) / 1000.0}});
  EXPECT_FALSE(check_timeline(raw).empty());

  TimelineFixes fixes;
  const json trace = build_timeline(run, &fixes);
  EXPECT_TRUE(check_timeline(trace).empty()) << check_timeline(trace).front();
  EXPECT_EQ(fixes.passes_clamped, 1u);  // c cut to the frame's end
  EXPECT_EQ(fixes.passes_trimmed, 2u);  // b starts at 400, c at 600
  EXPECT_EQ(fixes.frames_trimmed, 0u);
  EXPECT_EQ(trace["otherData"]["passes_trimmed"], 2);

  const auto passes = events_of(trace, "X", "pass");
  ASSERT_EQ(passes.size(), 4u);
  // In time order: d, a, b, c; ts relative to the frame start, in microseconds.
  EXPECT_EQ(passes[0]["name"], "d");
  EXPECT_DOUBLE_EQ(passes[0]["ts"].get<double>(), 0.05);
  EXPECT_EQ(passes[1]["name"], "a");
  EXPECT_DOUBLE_EQ(passes[1]["dur"].get<double>(), 0.3);
  EXPECT_EQ(passes[2]["name"], "b");
  EXPECT_DOUBLE_EQ(passes[2]["ts"].get<double>(), 0.4);
  EXPECT_DOUBLE_EQ(passes[2]["dur"].get<double>(), 0.2);
  EXPECT_EQ(passes[3]["name"], "c");
  EXPECT_DOUBLE_EQ(passes[3]["ts"].get<double>(), 0.6);
  EXPECT_DOUBLE_EQ(passes[3]["dur"].get<double>(), 0.4);
  // The raw duration is kept in args for the reader.
  EXPECT_EQ(passes[3]["args"]["duration_ns"], 650);

  // Same input, same output: the fix does not depend on anything but the samples.
  EXPECT_EQ(build_timeline(run), trace);
}

TEST(Timeline, OverlappingFramesAndSeveralQueues) {
  // Frame 1 starts 50 ns before frame 0 ends (pipelined submits); a compute-queue pass gets its own
  // track with its own frame event.
  FrameSample f0, f1;
  f0.passes = {{"gbuffer", 1000, 2000}, {"shadows", 1500, 1900, "compute"}};
  f1.passes = {{"gbuffer", 1950, 3000}};
  const FrameTimings run = run_of({f0, f1});
  TimelineFixes fixes;
  const json trace = build_timeline(run, &fixes);
  EXPECT_TRUE(check_timeline(trace).empty());
  EXPECT_EQ(fixes.frames_trimmed, 1u);
  EXPECT_EQ(fixes.passes_clamped, 1u);  // frame 1's gbuffer now starts at 2000

  const auto meta = events_of(trace, "M");
  ASSERT_EQ(meta.size(), 5u);  // process, 2 x (thread_name, thread_sort_index)
  EXPECT_EQ(meta[3]["args"]["name"], "compute queue");
  const auto frames = events_of(trace, "X", "frame");
  ASSERT_EQ(frames.size(), 3u);  // frame 0 on both tracks, frame 1 on graphics only
  EXPECT_EQ(frames[1]["tid"], 2);
  EXPECT_DOUBLE_EQ(frames[2]["ts"].get<double>(), 1.0);
  EXPECT_TRUE(events_of(trace, "C").empty());  // no counters recorded
}

TEST(Timeline, WrittenFileParses) {
  const auto dir = std::filesystem::temp_directory_path() / ("hp_timeline_test_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::vector<FrameSample> frames;
  for (std::uint64_t i = 0; i < 200; ++i) frames.push_back(test::synthetic_frame(i));
  const TimelineFixes fixes = write_timeline(dir / "run.trace.json", run_of(frames));
  EXPECT_EQ(fixes.total(), 0u);
  std::ifstream in(dir / "run.trace.json");
  const json trace = json::parse(in);
  EXPECT_TRUE(check_timeline(trace).empty());
  EXPECT_EQ(events_of(trace, "X", "frame").size(), 200u);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace hp
