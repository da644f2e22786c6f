// `hybridprof report OUT --format gbench`: the timings as Google Benchmark JSON (the layout benchmark
// 1.7 writes with --benchmark_out_format=json, --benchmark_repetitions and UseManualTime), so the tools
// people already use with it (compare.py, github-action-benchmark) read our results.
//
// One benchmark per cell and pass, named "<matrix>/<axis>:<value>/.../<pass>/manual_time" (the cell id
// when the cell has no axes), so two exports of the same matrix pair up by name in compare.py. Each
// measured frame is one repetition ("run_type": "iteration", "iterations": 1, "repetitions" = frames),
// followed by the mean, median, stddev and cv aggregates. GPU passes have no CPU time of their own:
// "cpu_time" repeats "real_time" (compare.py's CPU column then equals the time column).
#pragma once

#include "cell_result.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace hp {

/// "ns", "us", "ms" (default) or "s"; InputError for anything else.
double time_unit_divisor(const std::string& unit);

/// The benchmark name of one cell's pass (without "/manual_time").
std::string gbench_name(const CellResult& cell, const std::string& pass);

/// The whole document.
nlohmann::json gbench_export(const std::vector<CellResult>& cells, const std::string& time_unit = "ms");

/// Reads OUT/results.jsonl and writes `path` (default OUT/gbench.json) atomically; returns the path.
std::string write_gbench_export(const std::string& out_dir, const std::string& path = "",
                                const std::string& time_unit = "ms");

}  // namespace hp
