// The machine-readable timing result: environment, per-pass statistics, raw per-frame samples and
// counters in one JSON document, and the way back from it.
//
// Schema ("schema": "hybridprof.timings", "version": 1); nanoseconds and raw counts throughout:
//   environment: {cpu_model, core_count, lp_num_threads, build_type, compiler, git_commit, date_utc,
//                 hostname, os, load_1min (null: unreadable; absent when read: null), cpu_governor,
//                 device: {name, type, driver_name, driver_info, driver_version, api_version}}
//   timing: {source: "gpu-timestamps"|"cpu-wall",
//            pass_isolation: "serialized"|"host-submissions"|"unisolated" (absent when read: unisolated
//                            for GPU timestamps, written before isolation existed),
//            overlap: null | {frames, overlapped_frame_ns: Summary, serialized_sum_ns: Summary,
//                             saving_ns, saving_ns_ci, saving_fraction, saving_fraction_ci},
//            warmup_frames, measured_frames,
//            query_overhead: null | {frame_ns_with_queries, frame_ns_without_queries, frames,
//                                    overhead_ns, overhead_fraction, paired_fraction,
//                                    paired_fraction_ci},
//            frame_ns: Summary, cpu_wall_ns: Summary,
//            passes: [{pass, duration_ns: Summary}, ...]}
//   Summary: {count, min, max, median, mean, p95, stddev|null, cv|null, quantile_definition: "type7",
//             median_ci: CI, median_ci_bootstrap: CI|null}
//   CI: {method, level, low, high, coverage, lower_rank, upper_rank, valid}
//   frames: [{index, begin_ns, end_ns (null when derived from the passes), cpu_wall_ns,
//             passes: [{pass, queue, begin_ns, end_ns}], counters: {pass: {name: value}}}]
//   overlapped_frames: [{begin_ns, end_ns}]  (the frames as the application records them, one beside
//             each measured frame; [] when not measured; optional when read)
//   counters: {pass: {name: value}}  (sum over the measured frames)
//   invocations_per_frame: {pass: {compute_invocations: value}}  (pipeline statistics of one frame
//             rendered outside the timed ones; {} when not counted; optional when read)
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>

#include "timing/counters.hpp"
#include "timing/environment.hpp"
#include "timing/frame_timings.hpp"
#include "timing/stats.hpp"

namespace hp {

// nlohmann-json conversions (found by ADL, so `nlohmann::json j = summary;` works). The from_json
// side throws hp::InputError naming the missing or mistyped field.
void to_json(nlohmann::json& j, const MedianCi& ci);
void from_json(const nlohmann::json& j, MedianCi& ci);
void to_json(nlohmann::json& j, const Summary& s);
void from_json(const nlohmann::json& j, Summary& s);
void to_json(nlohmann::json& j, const Counters& c);
void from_json(const nlohmann::json& j, Counters& c);
void to_json(nlohmann::json& j, const DeviceDescription& d);
void from_json(const nlohmann::json& j, DeviceDescription& d);
void to_json(nlohmann::json& j, const Environment& e);
void from_json(const nlohmann::json& j, Environment& e);
void to_json(nlohmann::json& j, const QueryOverhead& q);
void from_json(const nlohmann::json& j, QueryOverhead& q);
void to_json(nlohmann::json& j, const OverlapSummary& o);
void from_json(const nlohmann::json& j, OverlapSummary& o);

// A result read back.
struct TimingResult {
  Environment environment;
  FrameTimings timings;   // the measured frames, as a complete collector
  TimingSummary summary;  // as stored (not recomputed)
  Counters counters;      // totals as stored
};

// The whole document for a finished run (summary computed here with `options`).
nlohmann::json timing_result_json(const Environment& env, const FrameTimings& timings,
                                  const SummaryOptions& options = {});

// Parses a document written by timing_result_json. Throws hp::InputError naming the field.
TimingResult parse_timing_result(const nlohmann::json& doc);

// Writes `doc` (indented) through an AtomicFile (core/atomic_file.hpp): a reader never sees half a file.
// Throws hp::InputError naming the path when it cannot.
void write_json_atomically(const std::filesystem::path& path, const nlohmann::json& doc, int indent = 1);

// timing_result_json + write_json_atomically.
void write_timing_result(const std::filesystem::path& path, const Environment& env, const FrameTimings& timings,
                         const SummaryOptions& options = {});

// Reads and parses a result file; errors (unreadable, not JSON, bad field) name the file.
TimingResult read_timing_result(const std::filesystem::path& path);

}  // namespace hp
