// `hybridprof report OUT`: a markdown report over OUT/results.jsonl with SVG charts beside it.
//
// Sections: environment (with a warning when cells ran on different devices, drivers, thread
// counts or commits); charts (per-pass median times with 95% CI error bars; time against every
// numeric axis); per cell: pass timings (median, 95% CI, frames, CV), work counters (rays per frame,
// nodes and triangles per ray, Mrays/s = rays per frame / median pass time), BVH statistics, cache
// tables when the cell has a "cache" object, the final images; comparisons along each axis (every
// pair of values with the other axes held equal: change in median pass time with a Mann-Whitney
// p-value over the raw frame samples, change in counters, one sentence each) with the study's
// Table 1 beside the geometry and jitter axes.
#pragma once

#include "cell_result.hpp"

#include <string>
#include <vector>

namespace hp {

/// A file written beside report.md (path relative to the output folder).
struct ReportFile {
  std::string path;
  std::string content;
};

struct Report {
  std::string markdown;
  std::vector<ReportFile> charts;  ///< "charts/*.svg"
  /// findings.json: every pass-time comparison of the comparisons section with its verdict ("faster",
  /// "slower", "no change", "inconclusive"), the same as the markdown says.
  std::string findings;
};

/// Builds the report for these cells (at least one). `unsupported`: OUT/unsupported.json's list (cells the
/// device could not run, hybridprof run's RunSummary::unsupported), named in a section of their own. Pure:
/// writes nothing.
Report build_report(const std::vector<CellResult>& cells, const nlohmann::json& unsupported = nlohmann::json::array());

/// Reads OUT/results.jsonl, writes OUT/report.md, OUT/findings.json and OUT/charts/*.svg (each to a temporary file
/// renamed into place). Returns the report's path. InputError for a missing or bad results file.
std::string write_report(const std::string& out_dir);

}  // namespace hp
