#include "cache_analysis.hpp"

#include "colormap.hpp"

#include "cachesim/preset.hpp"
#include "cachesim/simulator.hpp"
#include "image/image.hpp"
#include "trace/trace_file.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <stdexcept>

namespace hp {

using json = nlohmann::json;

namespace {

json level_json(const cachesim::LevelStats& l) {
  return {{"requests", l.requests},          {"hits", l.hits},       {"misses", l.misses},
          {"hit_rate", l.hit_rate()},        {"sectors", l.sectors}, {"sector_hits", l.sector_hits},
          {"sector_misses", l.sector_misses}};
}

// The heatmaps' ramp (core/colormap.hpp) for miss counts, log-scaled to the maximum, in linear light.
void ramp(float t, float* rgb) {
  const std::array<float, 3> c = miss_ramp_srgb(t);
  for (int i = 0; i < 3; ++i) rgb[i] = srgb_to_linear(c[size_t(i)]);
}

uint32_t max_count(const std::vector<uint32_t>& counts) {
  uint32_t m = 0;
  for (uint32_t c : counts) m = std::max(m, c);
  return m;
}

// Per-invocation counts back to pixels: 8x8 workgroups in row-major dispatch order.
std::string write_heatmap(const std::vector<uint32_t>& counts, const trace::PassInfo& pass, uint32_t width,
                          uint32_t height, const std::string& path) {
  const uint32_t wx = pass.dispatch.workgroup_count[0];
  const uint32_t lx = pass.dispatch.workgroup_size[0], ly = pass.dispatch.workgroup_size[1];
  const uint32_t maxc = max_count(counts);
  Image4f img(width, height);
  for (size_t inv = 0; inv < counts.size(); ++inv) {
    const uint64_t wg = inv / (uint64_t(lx) * ly), local = inv % (uint64_t(lx) * ly);
    const uint32_t x = uint32_t((wg % wx) * lx + local % lx), y = uint32_t((wg / wx) * ly + local / lx);
    if (x >= width || y >= height) continue;
    float* px = img.at(x, y);
    ramp(maxc ? std::log1p(float(counts[inv])) / std::log1p(float(maxc)) : 0.0f, px);
    px[3] = 1.0f;
  }
  write_image(path, img);
  return path;
}

json curve_json(const cachesim::MissRatioCurve& c) {
  // Sizes in bytes at powers of two (and half-steps) from 1 KiB to past the footprint: enough points to
  // draw the curve; every value is exact (the histogram holds all distances).
  json pts = json::array();
  const uint64_t foot = std::max<uint64_t>(c.footprint_lines(), 1);
  for (double kib = 1.0; kib <= 1024.0 * 1024.0; kib *= std::sqrt(2.0)) {
    const uint64_t bytes = uint64_t(kib * 1024.0);
    const uint64_t lines = std::max<uint64_t>(1, bytes / c.line_bytes);
    pts.push_back({bytes, c.miss_ratio(lines)});
    if (lines > foot * 2) break;
  }
  return {{"line_bytes", c.line_bytes},
          {"accesses", c.accesses},
          {"cold", c.cold},
          {"footprint_bytes", c.footprint_lines() * c.line_bytes},
          {"points", pts}};
}

}  // namespace

json l1_by_counting_json(const cachesim::L1Lookups& l, uint64_t misses) {
  json out = json::object();
  for (cachesim::HitCounting c :
       {cachesim::HitCounting::request, cachesim::HitCounting::quarter_wave, cachesim::HitCounting::lane}) {
    const uint64_t lookups = l.of(c), hits = lookups - misses;
    out[cachesim::to_string(c)] = {{"lookups", lookups},
                                   {"hits", hits},
                                   {"misses", misses},
                                   {"hit_rate", lookups ? double(hits) / double(lookups) : 0.0}};
  }
  return out;
}

CacheAnalysis::CacheAnalysis(const trace::TraceHeader& header, const CacheAnalysisOptions& o)
    : header_(header), options_(o) {
  const cachesim::Preset preset = cachesim::scale_for_sampling(cachesim::find_preset(o.preset), o.scale_for_sampling);
  cachesim::SimOptions so;
  so.per_invocation = !o.heatmap_dir.empty();
  so.l1_mrc = so.l2_mrc = o.curves;
  sim_ = std::make_unique<cachesim::Simulator>(preset, header_, so);
  out_["preset"] = preset.name;
  out_["passes"] = json::array();
}

CacheAnalysis::~CacheAnalysis() = default;

uint32_t CacheAnalysis::begin_pass(const trace::PassInfo& pass) {
  if (in_pass_) end_pass();
  sim_->begin_pass(pass);
  passes_.push_back(pass);
  in_pass_ = true;
  return uint32_t(passes_.size() - 1);
}

void CacheAnalysis::write_records(uint32_t pass, std::span<const trace::TraceRecord> records, uint64_t first_workgroup,
                                  uint64_t end_workgroup) {
  if (!in_pass_ || pass + 1 != passes_.size())
    throw std::logic_error("CacheAnalysis: records for a pass that is not the current one");
  // A capture hands over what the GPU wrote: check it as a trace file's records are checked.
  trace::validate_records("pass '" + passes_.back().name + "'", header_, passes_.back(), records, first_workgroup,
                          end_workgroup);
  write_validated(records, first_workgroup, end_workgroup);
}

void CacheAnalysis::write_validated(std::span<const trace::TraceRecord> records, uint64_t first_workgroup,
                                    uint64_t end_workgroup) {
  if (!in_pass_) throw std::logic_error("CacheAnalysis: records outside a pass");
  const auto t0 = std::chrono::steady_clock::now();
  sim_->feed(records, first_workgroup, end_workgroup);
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void CacheAnalysis::end_pass() {
  in_pass_ = false;
  const auto t0 = std::chrono::steady_clock::now();
  const trace::PassInfo& info = passes_.back();
  const cachesim::PassResult r = sim_->end_pass();
  const CacheAnalysisOptions& o = options_;
  json pj;
  pj["pass"] = info.name;
  pj["records"] = r.lane_accesses;
  pj["lane_accesses"] = r.lane_accesses;
  pj["peak_resident_records"] = r.peak_resident_records;
  pj["l1"] = level_json(r.stats.l1);
  pj["l2"] = level_json(r.stats.l2);
  pj["l1_hit_counting"] = cachesim::to_string(r.l1_hit_counting);  // the counting of "l1" and buffers' l1_requests
  pj["l1_by_counting"] = l1_by_counting_json(r.l1_lookups, r.stats.l1.misses);
  pj["stores"] = r.stats.stores;
  pj["atomics"] = r.stats.atomics;
  pj["dram_read_bytes"] = r.stats.dram_read_bytes;
  pj["dram_write_bytes"] = r.stats.dram_write_bytes;
  json buffers = json::object();
  for (const trace::BufferInfo& b : header_.buffers) {
    const cachesim::BufferStats& bs = r.buffers[b.id];
    if (bs.l1_requests == 0 && bs.l2_requests == 0) continue;
    buffers[b.name] = {{"l1_requests", bs.l1_requests},
                       {"l1_misses", bs.l1_misses},
                       {"l2_requests", bs.l2_requests},
                       {"l2_misses", bs.l2_misses},
                       {"dram_read_bytes", bs.dram_read_bytes},
                       {"l1_by_counting", l1_by_counting_json(r.buffer_l1_lookups[b.id], bs.l1_misses)}};
  }
  pj["buffers"] = buffers;
  if (o.curves) pj["mrc"] = {{"l1", curve_json(r.l1_curve)}, {"l2", curve_json(r.l2_curve)}};
  // Per-pixel heatmaps for the passes whose invocations are pixels (8x8 groups over the image or the
  // reflection grid); the 1D passes (consume: one invocation per compacted ray, the sort kernels) have none.
  if (!o.heatmap_dir.empty() && info.dispatch.workgroup_size[1] > 1) {
    // The pass's own pixel grid: shadows cover the image; reflections their (possibly reduced) grid.
    uint32_t w = header_.image_width, h = header_.image_height;
    if (info.name == "reflections") {
      for (const auto& b : header_.buffers) {
        if (b.name == "reflection") w = b.width, h = b.height;
      }
    }
    const std::filesystem::path dir(o.heatmap_dir);
    pj["heatmaps"] = {{"l1_misses", write_heatmap(r.l1_misses, info, w, h,
                                                  (dir / (o.heatmap_prefix + info.name + "_l1_misses.png")).string())},
                      {"l2_misses", write_heatmap(r.l2_misses, info, w, h,
                                                  (dir / (o.heatmap_prefix + info.name + "_l2_misses.png")).string())}};
    // The count at the top of each heatmap's log scale (its colour bar in the report).
    pj["heatmap_max"] = {{"l1_misses", max_count(r.l1_misses)}, {"l2_misses", max_count(r.l2_misses)}};
  }
  out_["passes"].push_back(pj);
  seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

json CacheAnalysis::finish() {
  if (in_pass_) end_pass();
  out_["dram_writeback_bytes"] = sim_->finish();
  out_["simulation_s"] = seconds_;
  return std::move(out_);
}

json analyse_trace(const std::string& trace_path, const CacheAnalysisOptions& o) {
  trace::TraceReader reader(trace_path);
  CacheAnalysis analysis(reader.header(), o);
  for (uint32_t p = 0; p < reader.passes().size(); ++p) {
    analysis.begin_pass(reader.passes()[p]);
    reader.read_slices(p, [&](std::span<const trace::TraceRecord> recs, uint64_t first, uint64_t end) {
      analysis.write_validated(recs, first, end);
    });
  }
  return analysis.finish();
}

}  // namespace hp
