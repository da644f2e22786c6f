// Runs every cell of a matrix and appends one JSON line per finished cell to OUT/results.jsonl (flushed
// and synced), so an interrupted run loses no finished cell and a re-run resumes where it stopped.
#pragma once

#include "scenario.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace hp {

struct RunOptions {
  std::string out_dir;
  Shard shard;
  std::string device;     ///< as `render --device`
  bool validate = false;  ///< Khronos validation layer; any message fails the cell
  bool progress = true;   ///< a progress line with ETA on stderr when it is a terminal
};

struct RunSummary {
  size_t cells = 0;        ///< in the matrix
  size_t in_shard = 0;     ///< of them, this shard's
  size_t already_done = 0; ///< found in results.jsonl and skipped
  size_t ran = 0;
};

/// Runs the matrix. Throws hp::InputError / hp::DeviceError as the CLI expects.
RunSummary run_matrix(const Matrix& matrix, const RunOptions& options);

/// Reads OUT/results.jsonl: one JSON object per complete line (a partial last line from an interrupted
/// write is ignored). Throws InputError naming the file and line for a corrupt line.
std::vector<nlohmann::json> read_results(const std::string& out_dir);

/// Joins shard directories into `out_dir` (results de-duplicated by cell id, images copied).
size_t merge_results(const std::string& out_dir, const std::vector<std::string>& shard_dirs);

}  // namespace hp
