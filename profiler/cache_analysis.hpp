// From a trace file to the tables a report shows: per pass the study's L1/L2 hit/miss table with rates,
// requests vs sectors, DRAM bytes; the same per buffer; per-pixel L1/L2 miss heatmaps (PNG); and L1/L2
// miss-ratio curves (exact, one pass by stack distance). Vulkan-free.
#pragma once

#include <nlohmann/json.hpp>

#include <memory>
#include <string>

#include "trace/trace_file.hpp"

namespace hp {

namespace cachesim {
class Simulator;
struct L1Lookups;
}  // namespace cachesim

struct CacheAnalysisOptions {
  std::string preset = "vega56";  ///< name or JSON path (cachesim::find_preset)
  std::string heatmap_dir;        ///< where heatmaps are written ("" = none)
  std::string heatmap_prefix;     ///< file name prefix, e.g. the cell id
  bool curves = true;             ///< L1 and L2 miss-ratio curves
  /// > 1: the trace records 1 in this many workgroups; replay it on the preset scaled down by as much
  /// (cachesim::scale_for_sampling).
  uint32_t scale_for_sampling = 1;
};

/// The cache simulator as a trace sink: a capture streams its slices straight into the replay, so a
/// frame of any size is analysed without a trace file and with at most a couple of slices in memory.
/// finish() returns {"preset", "passes": [...], "dram_writeback_bytes", "simulation_s"}; per pass also
/// "peak_resident_records" (the most records the replay held at once).
class CacheAnalysis final : public trace::TraceSink {
 public:
  CacheAnalysis(const trace::TraceHeader& header, const CacheAnalysisOptions& options);
  ~CacheAnalysis() override;
  uint32_t begin_pass(const trace::PassInfo& pass) override;
  void write_records(uint32_t pass, std::span<const trace::TraceRecord> records, uint64_t first_workgroup,
                     uint64_t end_workgroup) override;
  /// write_records for records already validated against this header (TraceReader::read_slices).
  void write_validated(std::span<const trace::TraceRecord> records, uint64_t first_workgroup, uint64_t end_workgroup);
  nlohmann::json finish();

 private:
  void end_pass();
  trace::TraceHeader header_;
  CacheAnalysisOptions options_;
  std::unique_ptr<cachesim::Simulator> sim_;
  nlohmann::json out_;
  std::vector<trace::PassInfo> passes_;
  bool in_pass_ = false;
  double seconds_ = 0;  // spent replaying and writing results (not capturing or reading)
};

/// The L1 under every counting (cachesim::HitCounting), as the cache tables carry it per pass and per
/// buffer ("l1_by_counting"): {"request" | "quarter_wave" | "lane": {"lookups", "hits", "misses",
/// "hit_rate"}}, misses the same in all three (hits = lookups - misses).
nlohmann::json l1_by_counting_json(const cachesim::L1Lookups& lookups, uint64_t misses);

/// Replays every pass of `trace_path`, slice by slice and returns {"preset", "passes": [...]} (schema: finish() above;
/// docs/memory-traces.md, "Cache tables"). Throws hp::InputError for a bad trace or preset.
nlohmann::json analyse_trace(const std::string& trace_path, const CacheAnalysisOptions& options);

}  // namespace hp
