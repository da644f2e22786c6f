// `hybridprof gate`: compares a candidate run with a baseline run and answers with an exit code CI can
// trust: 0 pass, 1 regression, 2 cannot compare, 4 inconclusive (a timing comparison with too few samples
// to ever fail, and no regression found).
//
// Rules:
//  - Cells pair up by match_key (canonical config without `inject`). A cell on one side only: exit 2.
//  - Deterministic metrics (counters per pass, BVH nodes/leaves/depth/SAH cost, triangle count, cache
//    counts) must be equal; a policy file may allow a relative tolerance per metric name. Otherwise
//    the metric fails (exit 1).
//  - Timings, per (cell, pass): a two-sided Mann-Whitney U test of candidate against baseline samples,
//    Holm-adjusted across every (cell, pass) comparison of the run. Fail when the adjusted p <= alpha
//    AND the median ratio candidate/baseline > 1 + threshold; warn when significant and the ratio
//    > 1 + warn. Significant speed-ups and small significant changes pass.
//  - Sides measured on a different device name, driver, core count or LP_NUM_THREADS: timings are
//    not compared and the gate exits 2 with the reason. The deterministic metrics are still compared
//    and shown, but the exit code stays 2 (the run as a whole is not a valid comparison); to gate only
//    the deterministic metrics across machines (a committed baseline), use deterministic_only.
//  - Two separate runs (folders) compare timings only when the machine was in the same state for both: the
//    same CPU governor and 1-minute loads (over every cell's start and end) within max(0.5, cores / 4) of
//    each other, both recorded. Otherwise timings are not compared and the verdict is INCONCLUSIVE (exit 4)
//    naming both loads, with a pointer to `gate --ab`, which interleaves fresh processes instead.
//  - Fresh processes (--ab): a slowdown fails (or warns) only above the noise floor too, the larger side's
//    change between its odd and its even processes (an A/A measured beside the comparison); a significant
//    slowdown above `warn` but inside the floor is "within noise floor".
//  - Samples: from two folders, the raw per-frame samples; from `--ab`, one median per fresh process
//    (frames within one process are not independent across processes), runs interleaved A/B/B/A.
#pragma once

#include "cell_result.hpp"

#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace hp {

struct GatePolicy {
  double threshold = 0.10;  ///< fail above this slowdown (median ratio - 1), when significant
  double warn = 0.05;       ///< warn above this slowdown, when significant
  double alpha = 0.05;      ///< family-wise level of the Holm-corrected U tests
  /// Relative tolerance per deterministic metric: the full name ("shadows/nodes_visited",
  /// "bvh.sah_cost") or a counter name for every pass ("nodes_visited"). Absent: exact.
  std::map<std::string, double> tolerances;
};

/// Reads a policy file {"threshold", "warn", "alpha", "tolerances": {name: fraction}} over `base`
/// (keys absent keep base's values). InputError naming the file and key for anything else.
GatePolicy load_policy(const std::string& path, GatePolicy base = {});
/// InputError unless 0 <= warn <= threshold, 0 < alpha < 1, tolerances >= 0.
void validate_policy(const GatePolicy& policy, const std::string& where);

struct GateSide {
  std::string label;
  std::vector<CellResult> cells;               ///< one per cell (in --ab: the first run's)
  std::map<std::string, PassSamples> samples;  ///< by match_key: per pass, the samples tested
  std::string sample_kind = "frames";          ///< "frames" or "process medians"
  std::vector<std::string> problems;           ///< reasons this side cannot be compared
};

/// A run folder: samples are the raw frames of each cell.
GateSide side_from_dir(const std::string& dir);
/// Several fresh-process runs of one side: samples are each run's per-pass median; the runs must
/// hold the same cells with identical deterministic metrics (else a problem is recorded).
GateSide side_from_runs(const std::vector<std::string>& dirs, const std::string& label);

/// Why two separate runs' timings cannot be compared though they ran on one device and driver: loads that
/// differ (or were not recorded), another CPU governor. Empty: comparable.
std::vector<std::string> machine_state_differences(const std::vector<CellResult>& baseline,
                                                   const std::vector<CellResult>& candidate);

/// "device: 'A' vs 'B'" lines for the fields that make timings incomparable.
std::vector<std::string> environment_differences(const Environment& baseline, const Environment& candidate);

struct GateRow {
  std::string cell, metric, baseline, candidate, change;
  std::optional<double> p_raw, p_holm;
  /// "pass", "pass (faster)", "cannot fail", "WARN", "FAIL", "identical", "within tolerance", "within noise
  /// floor ±X%"
  std::string verdict;
};

struct GateOptions {
  GatePolicy policy;
  bool deterministic_only = false;  ///< skip timings (and the environment check that guards them)
  bool verbose = false;             ///< list identical deterministic metrics too
};

struct GateOutcome {
  int exit_code = 0;
  std::vector<GateRow> rows;
  std::vector<std::string> cannot_compare;  ///< non-empty: exit 2
  std::vector<std::string> notes;
  size_t identical = 0, timing_comparisons = 0, fails = 0, warns = 0;
  size_t cannot_fail = 0;  ///< timing comparisons whose smallest possible Holm-adjusted p exceeds alpha
  /// Why the two runs' timings were not compared (separate runs whose machine state differed): INCONCLUSIVE.
  std::vector<std::string> incomparable;
};

GateOutcome run_gate(const GateSide& baseline, const GateSide& candidate, const GateOptions& options);

/// The table and the verdict lines, as printed by the command.
std::string format_gate(const GateOutcome& outcome);

struct AbOptions {
  std::string baseline_cmd, candidate_cmd;  ///< each run as `CMD run SCENARIO --out DIR` by /bin/sh
  std::string scenario;
  int trials = 5;        ///< fresh processes per side
  std::string work_dir;  ///< empty: a new folder under the system's temp folder
  bool keep = false;     ///< keep the run folders (else removed after success)
  /// Called after each process: processes done, processes in all (both sides), and which one finished
  /// ("baseline 3/11"). The command shows it as progress with an ETA; unset, nothing is said.
  std::function<void(int done, int total, const std::string& process)> on_process;
};

/// Runs both commands alternately (A B B A A B ...: a drift in machine load hits both sides alike),
/// each in a fresh process with its own output folder, and returns the two sides. InputError when a
/// command fails (naming it and its log file).
std::pair<GateSide, GateSide> run_ab(const AbOptions& options);

}  // namespace hp
