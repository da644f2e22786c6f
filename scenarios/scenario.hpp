// Scenario files: what one matrix cell renders and measures, and matrices of them.
//
// A scenario is a JSON object (schema in docs/scenarios.md); every key is optional and has a default,
// an unknown key, a wrong type or an impossible value is an hp::InputError naming the file and the key path.
// A matrix file is {"base": {scenario}, "axes": {"key.path": [values...]}, "exclude": [{"key.path": value}]},
// expanded as the cartesian product of the axes (the first axis varies slowest), minus the excluded
// combinations. A plain scenario file is a matrix of one cell.
#pragma once

#include "frame_settings.hpp"

#include <glm/vec3.hpp>

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace hp {

struct Scenario {
  std::string name;                    ///< label for reports (not part of the id)
  std::string scene = "builtin:pica";  ///< as the file writes it (part of the id)
  /// The scene to load: `scene` itself for a built-in or an absolute path, else `scene` relative to the folder
  /// of the scenario file it came from (so a matrix runs the same from any working directory).
  std::string scene_path = "builtin:pica";
  std::string scene_where;  ///< "FILE: scene" for the error of a scene that does not load
  std::optional<glm::vec3> camera_position, camera_target;
  std::optional<float> camera_fov_deg;
  std::optional<glm::vec3> light_direction;
  std::optional<float> light_intensity;
  FrameSettings frame;   ///< resolution, passes and their options, BVH build
  uint32_t frames = 10;  ///< measured frames
  uint32_t warmup = 3;   ///< discarded frames before them
  /// Also measure the timestamp queries' overhead: as many frames again without queries, interleaved with
  /// the measured ones (ProfileOptions::measure_query_overhead). Off unless asked: it doubles the frames.
  bool query_overhead = false;
  /// Also time, beside each measured (serialized) frame, the frame as the application records it, with
  /// no dependency added between passes (ProfileOptions::measure_overlap): what overlapping the passes
  /// saves. On unless turned off.
  bool overlap = true;
  std::string cache_preset = "vega56";
  /// Memory-trace capture for the cache simulator: the passes to trace (empty = none), every k-th
  /// workgroup, whether the trace file is kept beside the results, the image address layout.
  std::vector<std::string> trace_passes;
  uint32_t trace_sample_every = 1;
  uint32_t trace_sample_block = 1;  ///< workgroups per sampled burst (CaptureOptions::sample_block)
  /// Replay a sampled trace on the cache model scaled down by k (cachesim::scale_for_sampling); measured
  /// in sweep_cache_sampling.json to cut the L1 hit-rate error of sampled traces several times over.
  bool trace_scale_model = true;
  bool trace_keep = false;
  bool trace_tiled_images = true;
  /// A documented knob for validating the regression gate: the named pass does this much extra work
  /// (the shadow pass re-traces the first `inject_fraction` of the image rows). 0 = off.
  std::string inject_pass = "shadows";
  float inject_fraction = 0.0f;
  /// The whole world (geometry, camera, clip planes) scaled about the origin, then translated: the same
  /// image at another scale or far from the origin (numerical hard cases). The reference stays unscaled.
  double world_scale = 1.0;
  glm::dvec3 world_translate{0.0};
  /// Speed against error: after the timed frames, accumulation restarts and `error_frames` frames are
  /// rendered; that image is compared with the CPU reference (reference/compare.hpp).
  bool error = false;
  uint32_t error_frames = 16;
  uint32_t reference_samples = 256;
  double error_threshold = 0.1;
  bool error_flip = true;

  /// The canonical configuration: every field, defaults filled, keys sorted; the id hashes it.
  nlohmann::json canonical() const;
  /// A stable id: 16 hex digits of a 64-bit FNV-1a hash of canonical().dump().
  std::string id() const;
};

/// Parses one scenario object. `file` and `path` prefix every error ("FILE: path.key: reason").
Scenario parse_scenario(const nlohmann::json& j, const std::string& file, const std::string& path = "");

struct Matrix {
  std::string file;
  std::string name;
  std::vector<std::string> axes;                 ///< axis key paths, in file order
  std::vector<Scenario> cells;                   ///< expanded, excludes removed, in deterministic order
  std::vector<nlohmann::json> cell_axis_values;  ///< per cell: {"axis": value} of its coordinates
  /// The matrix's "report" object (trade-off sections of the report; docs/speed-vs-error.md), copied
  /// into every result line. Null when absent.
  nlohmann::json report;
  /// The matrix's "expect" object: per cell name of "cells", the results a test holds it to (hard cases).
  nlohmann::json expect;
  /// "rounds": the runner measures every cell in this many interleaved rounds (each round visits the cells
  /// in a fresh shuffled order and times frames/rounds of each cell's frames); 1 measures the cells one
  /// after another. At most the smallest cell's "frames".
  std::uint32_t rounds = 1;
};

/// Expands a matrix (or single scenario) document. `axis_order` lists the axes in file order (nlohmann::json
/// objects are key-sorted); without it the axes vary in key order.
Matrix parse_matrix(const nlohmann::json& doc, const std::string& file,
                    const std::vector<std::string>& axis_order = {});
constexpr std::uint32_t kMaxRounds = 1000;
/// Sets the matrix's rounds (a file's "rounds", or `run --rounds`): InputError starting with `where` when
/// outside 1..kMaxRounds or above a cell's frames.
void set_rounds(Matrix& m, std::uint32_t rounds, const std::string& where);
/// Reads and expands a scenario or matrix file (errors name the file; broken JSON gives line/column).
Matrix load_matrix(const std::string& path);

/// "K/N" (1 <= K <= N): this shard runs the cells whose index i has i % N == K - 1.
struct Shard {
  uint32_t index = 1, count = 1;
  bool contains(size_t cell) const { return cell % count == index - 1; }
};
Shard parse_shard(const std::string& text);  // throws InputError naming --shard

/// Which cells of the matrix the filters select (all with none). InputError naming the filter when one
/// names no axis or the filters together select no cell.
std::vector<bool> select_cells(const Matrix& matrix, const std::vector<std::string>& filters);

}  // namespace hp
