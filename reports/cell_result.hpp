// One matrix cell read back from OUT/results.jsonl, and the views of it that the report, the
// Google Benchmark export and the gate share: raw per-pass samples, deterministic metrics, labels.
#pragma once

#include "timing/result_json.hpp"

#include <nlohmann/json.hpp>

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace hp {

struct CellResult {
  explicit CellResult(TimingResult t) : timing(std::move(t)) {}

  std::string id, matrix, name;
  nlohmann::json axes = nlohmann::json::object();    ///< {axis key path: value}
  nlohmann::json config = nlohmann::json::object();  ///< canonical scenario
  TimingResult timing;
  std::optional<std::uint64_t> triangles;  ///< scene.triangles
  nlohmann::json bvh;                      ///< {build_ms, nodes, leaves, max_depth, sah_cost} or null (no rays traced)
  nlohmann::json images = nlohmann::json::object();  ///< {"color": "cells/<id>/color.png", ...}
  /// Cache-simulator tables, when the scenario traced passes (null otherwise), as analyse_trace
  /// writes them: {preset, passes: [{pass, l1: {requests, hits, misses, hit_rate, ...}, l2: {...},
  /// buffers: {name: {l1_requests, l1_misses, l2_requests, l2_misses, ...}}, mrc, heatmaps}]}.
  nlohmann::json cache;
  /// The matrix file's "report" object (the runner copies it into every line), or null.
  nlohmann::json report;
  /// Error against a reference render, when the scenario asked for it (null otherwise):
  /// {reference: {id, samples, render_s, cached}, frames, image: {pixels, mse, relmse, relmse_eps,
  /// psnr_db (null: infinite), psnr_peak, max_abs, over_threshold, threshold, non_finite, flip_mean?},
  /// shadow?: {compared, acne, leaks, coverage_mismatch}, depth?: {pixels, mean_rel, max_rel, bins: [...]}}.
  nlohmann::json error;
  /// The whole line without its "result" (timing) object: what JSON-pointer metrics read.
  nlohmann::json line = nlohmann::json::object();
  std::string where;  ///< "DIR/results.jsonl:LINE", for messages
};

/// Parses one results.jsonl line; errors (InputError) start with `where`.
CellResult parse_cell(const nlohmann::json& line, const std::string& where);

/// Every cell of OUT/results.jsonl. InputError when the file is missing, empty or has a bad line.
std::vector<CellResult> load_cells(const std::string& out_dir);

/// Raw per-frame samples (ns) per pass, in the order passes first appear. A pass recorded several
/// times in a frame contributes the sum, as the timing summary does.
using PassSamples = std::vector<std::pair<std::string, std::vector<double>>>;
PassSamples pass_samples(const TimingResult& timing);
/// One series of a cell's times: per frame, the sum of the passes `in` selects (frames with none of them
/// left out), and per round the median of those sums (round_medians[r] for the r-th round that has any).
struct TimeSeries {
  std::vector<double> frames, round_medians;
};
TimeSeries summed_pass_series(const TimingResult& timing, const std::function<bool(const std::string&)>& in);

/// The lowest and highest 1-minute load the cell recorded, at its start and end ("load_1min") and around
/// each visit of its rounds (unreadable values left out); nullopt when it recorded none.
std::optional<std::pair<double, double>> recorded_load(const CellResult& c);

/// The metrics that must not change between runs of one configuration on one driver, flattened to
/// names: "<pass>/<counter>" (sums over the measured frames), "bvh.nodes", "bvh.leaves",
/// "bvh.max_depth", "bvh.sah_cost", "scene.triangles", and "cache/<pass>/l1/hits"-style names for
/// every number of each traced pass's cache tables (miss-ratio curve points left out: they follow
/// from the counts). bvh.build_ms is a timing and is left out.
std::map<std::string, double> deterministic_metrics(const CellResult& cell);

/// Which cells two runs pair up: the canonical config without the gate-validation knob `inject`
/// (that knob stands in for a code change, so it must not make the cells different cells).
std::string match_key(const CellResult& cell);
/// As match_key, and the config values at these JSON pointers ("/trace/sample_every") left out too.
std::string match_key_ignoring(const CellResult& cell, const std::vector<std::string>& pointers);

/// A readable value of an axis: strings as they are, [128,72] as "128x72", other JSON dumped.
std::string axis_value_text(const nlohmann::json& value);

/// "geometry=soup, jitter=shared", or the cell's name, or its id when it has neither.
std::string cell_label(const CellResult& cell);

/// The last component of an axis key path ("passes.shadows" -> "shadows").
std::string axis_leaf(const std::string& axis);

/// printf-style formatting of one number, for tables and sentences (shared by the report and the gate).
std::string format_number(const char* format, double value);

}  // namespace hp
