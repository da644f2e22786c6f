// The report section a matrix asks for with `"report": {"cache_sampling": true}`: the cache simulator's
// hit rates on sampled traces (`trace.sample_every` k > 1) against the same configuration traced in full,
// per pass and level, with the simulator's time against that error (scenarios/sweep_cache_sampling.json).
#pragma once

#include "cell_result.hpp"
#include "report.hpp"

#include <string>
#include <vector>

namespace hp {

std::string cache_sampling_section(const std::vector<CellResult>& cells, std::vector<ReportFile>& charts);

}  // namespace hp
