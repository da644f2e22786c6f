// Synthetic results.jsonl lines for the report and gate tests: real timing results (written by
// timing_result_json) over frames whose pass durations the test chooses, so no Vulkan is needed.
#pragma once

#include "cell_result.hpp"
#include "timing/counters.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace hp::test {

struct SynthCell {
  std::string matrix = "synth";
  nlohmann::json axes = nlohmann::json::object();
  /// Per pass, the duration of each frame in ns (all passes the same frame count).
  std::vector<std::pair<std::string, std::vector<double>>> passes;
  /// Counters of each frame (the result's totals are frames x these).
  Counters counters_per_frame;
  std::string device = "llvmpipe (LLVM 15.0.6, 256 bits)";
  std::string driver_info = "Mesa 22.3.6 (LLVM 15.0.6)";
  std::string lp_num_threads = "unset";
  std::string commit = "abc123";
  std::uint32_t cores = 2;
  std::uint64_t triangles = 59894;
  nlohmann::json bvh = {{"build_ms", 28.0},
                        {"nodes", 69227},
                        {"leaves", 34614},
                        {"max_depth", 19},
                        {"sah_cost", 5.957}};
  nlohmann::json cache;  ///< null: none
  double inject_fraction = 0.0;
  nlohmann::json config_patch;  ///< merged into the canonical config (RFC 7386), e.g. {"trace": {"sample_every": 4}}
  nlohmann::json report;        ///< the matrix's "report" spec copied into the line; null: none
  nlohmann::json error;         ///< the "error" object; null: none
  /// Spans of the frames timed as the application records them, one per frame (empty: not measured).
  std::vector<double> overlapped_ns;
  /// Interleaved rounds: frame f was measured in round f % rounds (1: one round, no "rounds" record).
  std::uint32_t rounds = 1;
  /// The machine's 1-minute load at the cell's start and end ("load_1min"); nullopt: not recorded.
  std::optional<std::pair<double, double>> load = std::pair{0.5, 0.6};
};

/// An "error" object as the runner writes it: image metrics with this relMSE and PSNR (nullopt:
/// identical images, written as null), a shadow block, and a depth block whose bins' mean errors are
/// `depth_scale` times a fixed profile rising with distance.
nlohmann::json error_json(double relmse, std::optional<double> psnr_db, int frames = 16, double depth_scale = 1.0);

/// A "cache" object with one traced pass: L1/L2 hits and misses, one buffer (bvh_nodes) with these
/// L1 requests/misses, and the simulator's wall time.
nlohmann::json cache_json(const std::string& pass, double l1_hits, double l1_misses, double l2_hits, double l2_misses,
                          double buffer_requests, double buffer_misses, double simulation_s);

/// `n` durations around `median_ns`: median_ns * (1 + spread * u), u spread evenly over [-1, 1] in a
/// seed-dependent shuffled order (so two seeds give different but identically distributed samples).
std::vector<double> samples(double median_ns, double spread, std::size_t n, std::uint64_t seed);

/// Five passes named as the renderer names them, each with `n` frames around the given medians (ms).
std::vector<std::pair<std::string, std::vector<double>>> passes(std::size_t n, std::uint64_t seed, double spread = 0.03,
                                                                double shadows_scale = 1.0);

/// The results.jsonl line of a cell.
nlohmann::json line(const SynthCell& cell);
/// The cell as load_cells would return it.
CellResult cell(const SynthCell& cell);

/// Writes DIR/results.jsonl (DIR created) with these lines.
void write_results(const std::string& dir, const std::vector<nlohmann::json>& lines);

/// A fresh empty folder under the test temp folder.
std::string temp_dir(const std::string& name);

}  // namespace hp::test
