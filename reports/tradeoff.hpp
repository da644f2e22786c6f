// "Speed against error": the report sections a matrix asks for in its "report" object (copied by the
// runner into every results line), the metric names they use, and the Pareto front.
//
// The spec, all keys optional:
//   "report": {
//     "tradeoffs": [{"title": "...", "x": "<metric>", "y": "<metric>", "x_label": "...", "y_label": "...",
//                    "log_x": false, "log_y": false, "columns": ["<metric>", ...]}],
//     "cache_sampling": true,   // sampled cache traces against the full trace of the same config
//     "depth_error": true       // world-position reconstruction error per distance bin
//   }
//
// Metric names:
//   time:<pass>[+<pass>...]   median over the measured frames of the per-frame sum of those passes (ms),
//                             with the order-statistic 95% CI of that median; time:frame = every pass
//   image_time:<passes>       time:<passes> (median and CI) times error.frames: the GPU time spent on the
//                             accumulated image that the error metrics compare (ms)
//   per_ray:<pass>/<counter>  the counter's sum over the measured frames / the pass's rays_cast sum
//   /<json pointer>           a number in the results line ("/error/image/relmse", "/bvh/build_ms",
//                             "/cache/simulation_s"); the timing object ("/result") is not reachable
// A value that is missing, null or not a number is "not available": that cell is left out of the
// section and a footnote says so. A malformed name is an InputError naming it and the section.
#pragma once

#include "cell_result.hpp"
#include "report.hpp"

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace hp {

/// Which points are on the Pareto front when both coordinates are minimised: no other point is <= in
/// both and < in at least one. Duplicates of a front point are all on the front; a point with a NaN
/// coordinate is never on it (and dominates nothing).
/// The number at `key` of a JSON object, if it is one.
std::optional<double> number_at(const nlohmann::json& j, const char* key);
/// The axis values that tell `c` apart from the other cells in `among` ("k=4, block=2"), axes whose last
/// component is in `skip_leaves` left out; the cell's label when none differs.
std::string varying_label(const CellResult& c, const std::vector<const CellResult*>& among,
                          const std::vector<std::string>& skip_leaves = {});

std::vector<bool> pareto_front(const std::vector<std::pair<double, double>>& pts);

/// One resolved metric of one cell. For times, `ci` is the 95% CI of the median (absent with fewer
/// than 6 frames, where no interval reaches 95%).
struct MetricValue {
  double value = 0.0;
  std::optional<std::pair<double, double>> ci;
  bool is_time = false;  ///< milliseconds
};

/// Throws InputError ("<context>: bad metric '<name>': why") when `name` is not a metric name.
void check_metric(const std::string& name, const std::string& context);

/// The metric's value for this cell, nullopt when not available; `why` (when given) then says why.
/// InputError as check_metric for a malformed name.
std::optional<MetricValue> resolve_metric(const CellResult& cell, const std::string& name, const std::string& context,
                                          std::string* why = nullptr);

/// counter / rays_cast of one pass over the measured frames; nullopt when the pass cast no rays.
std::optional<double> per_ray(const Counters& counters, const std::string& pass, const std::string& counter);

/// The "report" object the cells carry (the first non-null one), or null.
nlohmann::json report_spec(const std::vector<CellResult>& cells);

/// The "## Error metrics" paragraph (formulas, with the constants the data used) when any cell has an
/// "error" object, else "".
std::string error_metrics_section(const std::vector<CellResult>& cells);

/// The small table of one cell's error numbers for its own section, "" when it has none.
std::string error_table(const CellResult& cell);

/// The sections the spec asks for ("## Speed against error": trade-offs, cache sampling, depth error),
/// with their charts appended to `charts`. "" when the cells carry no spec. InputError for a bad spec.
std::string tradeoff_sections(const std::vector<CellResult>& cells, std::vector<ReportFile>& charts);

}  // namespace hp
