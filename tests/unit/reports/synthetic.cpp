#include "synthetic.hpp"
#include "common/scratch_dir.hpp"

#include "timing/result_json.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <random>
#include <unistd.h>

namespace hp::test {

using json = nlohmann::json;
namespace fs = std::filesystem;

std::vector<double> samples(double median_ns, double spread, std::size_t n, std::uint64_t seed) {
  std::vector<double> v(n);
  // Evenly spaced quantiles plus a seed-dependent sub-step offset: no ties, a known median.
  std::mt19937_64 rng(seed);
  const double offset = double(rng() % 1000) / 1000.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double u = n == 1 ? 0.0 : -1.0 + 2.0 * (double(i) + offset * 0.5) / double(n - 1);
    v[i] = std::round(median_ns * (1.0 + spread * std::clamp(u, -1.0, 1.0)));
  }
  std::shuffle(v.begin(), v.end(), rng);
  return v;
}

std::vector<std::pair<std::string, std::vector<double>>> passes(std::size_t n, std::uint64_t seed, double spread,
                                                                double shadows_scale) {
  const std::pair<const char*, double> medians_ms[] = {{"gbuffer", 12.0},
                                                       {"shadows", 3.0 * shadows_scale},
                                                       {"reflections", 7.0},
                                                       {"accumulate", 0.2},
                                                       {"composite", 0.7}};
  std::vector<std::pair<std::string, std::vector<double>>> out;
  std::uint64_t s = seed * 131;
  for (const auto& [pass, ms] : medians_ms) out.push_back({pass, samples(ms * 1e6, spread, n, ++s)});
  return out;
}

json line(const SynthCell& c) {
  Environment env;
  env.cpu_model = "AMD EPYC";
  env.core_count = c.cores;
  env.lp_num_threads = c.lp_num_threads;
  env.build_type = "Release";
  env.compiler = "gcc 12.2.0";
  env.git_commit = c.commit;
  env.date_utc = "2026-11-23T11:14:36Z";
  env.hostname = "vm";
  env.os = "Linux";
  env.device = {c.device, "cpu", "llvmpipe", c.driver_info, "22.3.6", "1.3.230"};
  const std::size_t n = c.passes.empty() ? 0 : c.passes.front().second.size();
  std::vector<FrameSample> frames;
  std::uint64_t t = 1'000'000;
  for (std::size_t f = 0; f < n; ++f) {
    FrameSample fs;
    for (const auto& [pass, durations] : c.passes) {
      fs.passes.push_back({pass, t, t + std::uint64_t(durations[f]), "graphics"});
      t += std::uint64_t(durations[f]) + 1000;
    }
    fs.cpu_wall_ns = t;
    fs.counters = c.counters_per_frame;
    fs.round = std::uint32_t(f % c.rounds);
    frames.push_back(fs);
  }
  std::vector<FrameSpan> overlapped;
  for (double d : c.overlapped_ns) {
    overlapped.push_back({t, t + std::uint64_t(d)});
    t += std::uint64_t(d) + 1000;
  }
  const FrameTimings timings =
      FrameTimings::from_measured(2, TimingSource::GpuTimestamps, frames, std::nullopt, {}, overlapped);
  json config = {{"scene", "builtin:pica"},
                 {"frames", n},
                 {"inject", {{"pass", "shadows"}, {"fraction", c.inject_fraction}}}};
  for (const auto& [k, v] : c.axes.items()) config[k] = v;
  if (!c.config_patch.is_null()) config.merge_patch(c.config_patch);
  json j;
  j["schema"] = "hybridprof.cell";
  j["version"] = 1;
  j["config"] = config;
  // As the runner: the id hashes the whole config (inject included).
  j["id"] = std::to_string(std::hash<std::string>{}(config.dump()) & 0xffffffffffffull);
  j["matrix"] = c.matrix;
  j["name"] = c.matrix;
  j["axes"] = c.axes;
  j["result"] = timing_result_json(env, timings);
  j["scene"] = {{"triangles", c.triangles}};
  j["bvh"] = c.bvh;
  j["images"] = {{"color", "cells/" + j["id"].get<std::string>() + "/color.png"},
                 {"shadow", "cells/" + j["id"].get<std::string>() + "/shadow.png"}};
  if (!c.cache.is_null()) j["cache"] = c.cache;
  if (!c.report.is_null()) j["report"] = c.report;
  if (!c.error.is_null()) j["error"] = c.error;
  j["wall_s"] = 1.0;
  if (c.load) j["load_1min"] = {{"start", c.load->first}, {"end", c.load->second}};
  if (c.rounds > 1) {
    json visits = json::array();
    for (std::uint32_t r = 0; r < c.rounds; ++r)
      visits.push_back({{"round", r},
                        {"position", 0},
                        {"cells", 1},
                        {"frames", n / c.rounds},
                        {"rebuilt", r == 0},
                        {"load_1min", {{"start", 0.5}, {"end", 0.6}}}});
    j["rounds"] = {{"count", c.rounds}, {"seed", 7}, {"visits", visits}};
  }
  return j;
}

json error_json(double relmse, std::optional<double> psnr_db, int frames, double depth_scale) {
  json bins = json::array();
  for (double near : {0.5, 1.0, 2.0, 4.0, 8.0}) {
    bins.push_back({{"near", near},
                    {"far", near * 2},
                    {"pixels", 1000},
                    {"mean_rel", depth_scale * 1e-7 * near},
                    {"max_rel", depth_scale * 1e-6 * near}});
  }
  return {{"reference", {{"id", "0123456789abcdef"}, {"samples", 256}, {"render_s", 12.3}, {"cached", true}}},
          {"frames", frames},
          {"image",
           {{"pixels", 921600},
            {"mse", relmse / 20},
            {"relmse", relmse},
            {"relmse_eps", 0.01},
            {"psnr_db", psnr_db ? json(*psnr_db) : json(nullptr)},
            {"psnr_peak", 1.0},
            {"max_abs", 0.8},
            {"over_threshold", 120},
            {"threshold", 0.1},
            {"non_finite", 0},
            {"flip_mean", 0.05}}},
          {"shadow", {{"compared", 800000}, {"acne", 12}, {"leaks", 3}, {"coverage_mismatch", 40}}},
          {"depth",
           {{"pixels", 900000}, {"mean_rel", depth_scale * 1e-6}, {"max_rel", depth_scale * 1e-4}, {"bins", bins}}}};
}

json cache_json(const std::string& pass, double l1_hits, double l1_misses, double l2_hits, double l2_misses,
                double buffer_requests, double buffer_misses, double simulation_s) {
  return {{"preset", "vega56"},
          {"simulation_s", simulation_s},
          {"passes",
           {{{"pass", pass},
             {"l1", {{"requests", l1_hits + l1_misses}, {"hits", l1_hits}, {"misses", l1_misses}}},
             {"l2", {{"requests", l2_hits + l2_misses}, {"hits", l2_hits}, {"misses", l2_misses}}},
             {"buffers",
              {{"bvh_nodes",
                {{"l1_requests", buffer_requests},
                 {"l1_misses", buffer_misses},
                 {"l2_requests", buffer_misses},
                 {"l2_misses", 7}}}}}}}}};
}

CellResult cell(const SynthCell& c) { return parse_cell(line(c), "synthetic"); }

void write_results(const std::string& dir, const std::vector<json>& lines) {
  fs::create_directories(dir);
  std::ofstream out(fs::path(dir) / "results.jsonl", std::ios::trunc);
  for (const json& l : lines) out << l.dump() << "\n";
}

std::string temp_dir(const std::string& name) {
  const fs::path p = scratch_dir() / name;
  fs::remove_all(p);
  fs::create_directories(p);
  return p.string();
}

}  // namespace hp::test
