// Runs every cell of a matrix and appends one JSON line per finished cell to OUT/results.jsonl (flushed
// and synced), so an interrupted run loses no finished cell and a re-run resumes where it stopped. The
// matrix's "rounds" interleave the cells: every round visits each cell still to run once, in a fresh
// shuffled order, and times its share of the frames; each finished round is a line of OUT/rounds.jsonl
// (removed once every cell has its record), so an interrupted run loses no finished round either. OUT
// belongs to one matrix (OUT/matrix.json: its name and a hash of its cells' ids): another matrix's run into
// it, or a merge of different matrices, is an InputError; a finished cell measured by another build (git
// commit) or device and driver is removed and run again.
#pragma once

#include "cell_record.hpp"
#include "scenario.hpp"
#include "scene/scene.hpp"
#include "vk/context.hpp"

#include <nlohmann/json.hpp>

#include <atomic>
#include <string>
#include <vector>

namespace hp {

struct RunOptions {
  std::string out_dir;
  Shard shard;
  std::string device;     ///< as `render --device`
  bool validate = false;  ///< Khronos validation layer; any message fails the cell
  /// Progress on stderr: one line updated in place with an ETA on a terminal, else one line per visit (a CI
  /// log); `run --quiet` turns it off.
  bool progress = true;
  /// Set (by a SIGINT handler) to stop: the visit under way finishes and is journalled, no further visit
  /// starts, and run_matrix returns with RunSummary::interrupted. Null: never.
  const std::atomic<bool>* stop = nullptr;
  /// Only the cells every filter selects (`run --filter`): a cell id, or AXIS=VALUE with AXIS an axis key
  /// path or its last component and VALUE as the axis value reads ("soup", "2", "128x72" or JSON).
  std::vector<std::string> filters;
  /// Interleaved rounds: the most cells' frames kept alive between their rounds (`run --live-frames`);
  /// beyond it the least recently used is destroyed and built again at its next visit.
  size_t live_frames = 8;
  /// `run --reuse-stale`: a finished cell measured by another build or driver is kept and marked
  /// ("stale": {"measured_by", "reused_by"} in its line; the report says so and compares no time with it)
  /// instead of being run again.
  bool reuse_stale = false;
};

struct RunSummary {
  size_t cells = 0;         ///< in the matrix
  size_t in_shard = 0;      ///< of them, this shard's (among those the filters select)
  size_t already_done = 0;  ///< found in results.jsonl and skipped
  size_t stale = 0;         ///< found, but measured by another build or driver: removed and run again
  size_t stale_reused = 0;  ///< of the already done, stale ones kept and marked (RunOptions::reuse_stale)
  size_t ran = 0;
  /// Cells this device cannot run (a driver traversal it lacks): "<id> (<name>): <reason>", also listed in
  /// OUT/unsupported.json for the report. Not failures: the rest of the matrix runs.
  std::vector<std::string> unsupported;
  bool interrupted = false;      ///< stopped by RunOptions::stop before every cell had its record
  size_t rounds_journalled = 0;  ///< then: finished rounds of unfinished cells kept in OUT/rounds.jsonl
};

/// Why `ctx` cannot run cell `s` (its traversal needs ray queries or ray-tracing pipelines the device lacks),
/// or "" when it can.
std::string unsupported_reason(const vk::Context& ctx, const Scenario& s);

/// Runs the matrix. Throws hp::InputError / hp::DeviceError as the CLI expects.
RunSummary run_matrix(const Matrix& matrix, const RunOptions& options);

/// What a cell renders: the loaded scene with the scenario's light, camera and world transform applied,
/// and the untransformed scene and camera its CPU reference renders.
struct CellScene {
  Scene scene;
  Camera camera;
  Scene reference_scene;
  Camera reference_camera;
};
CellScene prepare_cell_scene(const Scenario& s, const Scene& loaded);

/// Checks one cell's measurements (its record's "error") against its expectations (a matrix's "expect"
/// entry): max_non_finite, max_acne_fraction and max_leak_fraction (of the compared pixels),
/// max_coverage_mismatch_fraction (of all pixels), max_relmse, max_depth_rel. One sentence per unmet expectation; a missing measurement is unmet.
/// "gpu_equals_cpu" is checked by the hard-case test (it needs the rays the shaders cast), not here.
std::vector<std::string> unmet_expectations(const CellRecord& cell, const nlohmann::json& expect);

/// Reads OUT/results.jsonl: one JSON object per complete line (a partial last line from an interrupted
/// write is ignored). Throws InputError naming the file and line for a corrupt line.
std::vector<nlohmann::json> read_results(const std::string& out_dir);

/// Joins shard directories into `out_dir` (results de-duplicated by cell id, images copied).
size_t merge_results(const std::string& out_dir, const std::vector<std::string>& shard_dirs);

}  // namespace hp
