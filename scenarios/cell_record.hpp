// One line of OUT/results.jsonl: what the runner measured for one matrix cell, as the runner writes it
// (to_json) and as the reports read it back (parse_cell_record). One struct, one writer, one reader, so
// the two sides cannot disagree about a field.
//
// The line ("schema": "hybridprof.cell", "version": 1; keys sorted, as nlohmann::json dumps them):
//   id, matrix, name, axes: {axis key path: value}, config: canonical scenario (Scenario::canonical),
//   result: timing result (profiler/timing/result_json.hpp), load_1min: {start, end} (null: unreadable;
//   absent in lines written before it existed), rounds?: the interleaved rounds (CellRounds), scene: {triangles}, bvh?: {build_ms, nodes, leaves,
//   max_depth, sah_cost} (absent: no ray traced), accel?: the driver's acceleration structure (CellAccel;
//   ray-query and pipeline cells), cache?: cache-simulator tables, error?: error against the
//   CPU reference, report?: the matrix's "report" object, expect?: {spec, unmet: [sentences]},
//   images: {name: "cells/<id>/<file>.png"}, wall_s; stale?: {measured_by, reused_by}, added to the line by
//   `run --reuse-stale` (not part of the record: the runner marks lines it did not measure).
#pragma once

#include "timing/result_json.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace hp {

/// The machine's 1-minute load average as the cell started and once its timed frames were done.
struct CellLoad {
  std::optional<double> start, end;  ///< null in the line: unreadable
  bool operator==(const CellLoad&) const = default;
};

/// How an interleaved run measured the cell: the matrix's rounds, and per round where the cell came in
/// that round's shuffled order, how many frames it timed, the load around them and whether its frame
/// was built anew for the visit (else kept alive from the previous round).
struct CellRoundVisit {
  std::uint32_t round = 0, position = 0, cells = 0;  ///< position of `cells` in the round's order (0-based)
  std::uint32_t frames = 0;
  bool rebuilt = false;
  CellLoad load;
  bool operator==(const CellRoundVisit&) const = default;
};
struct CellRounds {
  std::uint32_t count = 1;  ///< the matrix's rounds
  std::uint64_t seed = 0;   ///< of the rounds' shuffled orders
  std::vector<CellRoundVisit> visits;
  bool operator==(const CellRounds&) const = default;
};
/// {round, position, cells, frames, rebuilt, load_1min: {start, end}}
void to_json(nlohmann::json& j, const CellRoundVisit& v);
/// Reads one visit back; InputError starting with `where` and naming the field.
CellRoundVisit parse_round_visit(const nlohmann::json& v, const std::string& where);
/// {count, seed, visits: [visit, ...]}
void to_json(nlohmann::json& j, const CellRounds& r);

/// The BVH the ray-tracing passes traversed (bvh::bvh_stats and the build time).
struct CellBvh {
  double build_ms = 0.0;
  std::uint64_t nodes = 0, leaves = 0;
  int max_depth = 0;
  double sah_cost = 0.0;
  bool operator==(const CellBvh&) const = default;
};
void to_json(nlohmann::json& j, const CellBvh& b);  ///< {build_ms, nodes, leaves, max_depth, sah_cost}

/// The driver's acceleration structure of a ray-query or pipeline cell (AsBuildStats).
struct CellAccel {
  std::string traversal, order;  ///< "ray-query" | "pipeline"; "leaf" | "scene" | "morton"
  std::string layout = "flat";   ///< "flat" | "instances" (absent in lines written before it: flat)
  std::uint64_t blas_count = 1, instances = 1;
  bool compacted = false;
  double build_ms = 0.0;
  bool build_timed_on_device = false;  ///< build_ms from timestamps (else host wall time)
  std::uint64_t triangles = 0, blas_bytes = 0, tlas_bytes = 0, scratch_bytes = 0;
  bool operator==(const CellAccel&) const = default;
};
/// {traversal, order, layout, blas_count, instances, compacted, build_ms, build_timed_on_device, triangles,
/// blas_bytes, tlas_bytes, scratch_bytes}
void to_json(nlohmann::json& j, const CellAccel& a);

/// A matrix's expectations of one "cells" case and the sentences of those the cell did not meet.
struct CellExpect {
  nlohmann::json spec;  ///< the matrix's "expect" entry, as the matrix file states it (checked there)
  std::vector<std::string> unmet;
  bool operator==(const CellExpect&) const = default;
};

struct CellRecord {
  explicit CellRecord(TimingResult r) : result(std::move(r)) {}

  std::string id, matrix, name;
  /// {axis key path: value}. JSON: an axis value is any value the scenario key takes (string, number,
  /// list, object).
  nlohmann::json axes = nlohmann::json::object();
  /// The canonical scenario (Scenario::canonical()), whose dump the id hashes. JSON: it is compared and
  /// hashed as JSON (reports' match keys), and lines written by older builds hold older key sets.
  nlohmann::json config = nlohmann::json::object();
  /// The timed frames. Written through timing_result_json, which derives the summary from the frames;
  /// read back with the summary as stored.
  TimingResult result;
  std::optional<CellLoad> load_1min;       ///< absent in lines written before it existed
  std::optional<CellRounds> rounds;        ///< "rounds": absent in lines written before runs had rounds
  std::optional<std::uint64_t> triangles;  ///< "scene": {"triangles"}
  std::optional<CellBvh> bvh;              ///< absent when no ray was traced
  std::optional<CellAccel> accel;          ///< "accel": present for the driver traversals only
  /// Cache-simulator tables (CacheAnalysis::finish, plus each pass's "capture" and "trace_file"). JSON:
  /// written by hp_cache_analysis, whose tables grow with the model (buffers, heatmaps, curves).
  nlohmann::json cache;
  /// Error against the CPU reference (compare_with_reference, plus "frames" and "reference"). JSON: written
  /// by hp_reference, its sections depend on the passes compared (shadow?, depth?, flip_mean?).
  nlohmann::json error;
  /// The matrix's "report" object (trade-off sections), copied into every line. JSON: its shape is checked
  /// by parse_matrix and its metric names by the report (reports/tradeoff.cpp), which knows them.
  nlohmann::json report;
  std::optional<CellExpect> expect;
  std::map<std::string, std::string> images;  ///< {"color": "cells/<id>/color.png", ...}
  double wall_s = 0.0;                        ///< the cell's wall time, scene load to last image
};

bool operator==(const CellRecord& a, const CellRecord& b);

/// The results.jsonl line of a record (one object; dump() it for the line).
nlohmann::json to_json(const CellRecord& record);

/// Parses one results.jsonl line. Throws InputError starting with `where` and naming the field
/// ("WHERE: field 'id' missing or not a string", "WHERE: result: field 'frames' ..."). Keys it does not
/// know are ignored, so a line from a newer build still reads.
CellRecord parse_cell_record(const nlohmann::json& line, const std::string& where);

}  // namespace hp
