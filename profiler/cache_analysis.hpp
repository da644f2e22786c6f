// From a trace file to the tables a report shows: per pass the study's L1/L2 hit/miss table with rates,
// requests vs sectors, DRAM bytes; the same per buffer; per-pixel L1/L2 miss heatmaps (PNG); and L1/L2
// miss-ratio curves (exact, one pass by stack distance). Vulkan-free.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

namespace hp {

struct CacheAnalysisOptions {
  std::string preset = "vega56";  ///< name or JSON path (cachesim::find_preset)
  std::string heatmap_dir;        ///< where heatmaps are written ("" = none)
  std::string heatmap_prefix;     ///< file name prefix, e.g. the cell id
  bool curves = true;             ///< L1 and L2 miss-ratio curves
  /// > 1: the trace records 1 in this many workgroups; replay it on the preset scaled down by as much
  /// (cachesim::scale_for_sampling).
  uint32_t scale_for_sampling = 1;
};

/// Replays every pass of `trace_path` and returns {"preset", "passes": [...]} (schema in README, "Cache
/// tables"). Throws hp::InputError for a bad trace or preset.
nlohmann::json analyse_trace(const std::string& trace_path, const CacheAnalysisOptions& options);

}  // namespace hp
