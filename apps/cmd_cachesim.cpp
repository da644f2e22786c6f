// `hybridprof cachesim`: replays memory traces through the GPU cache model.
//   hybridprof cachesim TRACE --preset vega56 [--out result.json] [--mrc curves.csv] [--shards RATE]
//                             [--l1-hit-counting request|quarter_wave|lane]
//                             [--export-din FILE [--export-pass NAME] [--export-cu N]]
//     per-pass and per-buffer L1/L2 tables of a trace file written by `hybridprof trace`.
//   hybridprof cachesim --din FILE --l1 16k:64:4 --l2 4m:64:16 [--mrc curves.csv]
//     a Dinero IV text trace through one L1 and an L2 (LRU, write-allocate) with Dinero's counting.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>

#include "apps/cli_util.hpp"
#include "atomic_file.hpp"
#include "cache_analysis.hpp"
#include "cachesim/din_replay.hpp"
#include "cachesim/preset.hpp"
#include "cachesim/simulator.hpp"
#include "commands.hpp"
#include "error.hpp"
#include "output_path.hpp"
#include "report.hpp"
#include "trace/din.hpp"
#include "trace/trace_file.hpp"

namespace hp::cli {

namespace {

using namespace hp::cachesim;

struct CachesimArgs {
  std::string trace_path, din_path, preset = "vega56", out_path, mrc_path, export_din_path, export_pass;
  std::string l1 = "16k:64:4", l2 = "4m:64:16";
  std::string l1_hit_counting;  // empty: the preset's
  double shards = 1.0;
  uint32_t export_cu = 0;
  uint32_t scale_model = 1;
  bool per_invocation = false;
  bool quiet = false;
};

std::string pct(uint64_t part, uint64_t whole) {
  char b[32];
  std::snprintf(b, sizeof b, "%.2f%%", whole ? 100.0 * double(part) / double(whole) : 0.0);
  return b;
}

void print_level(const char* name, const LevelStats& s) {
  std::printf("  %-3s %14llu %14llu %14llu %9s %14llu %14llu\n", name, (unsigned long long)s.requests,
              (unsigned long long)s.hits, (unsigned long long)s.misses, pct(s.hits, s.requests).c_str(),
              (unsigned long long)s.sectors, (unsigned long long)s.sector_misses);
}

nlohmann::json level_json(const LevelStats& s) {
  return {{"requests", s.requests},
          {"hits", s.hits},
          {"misses", s.misses},
          {"hit_rate", s.hit_rate()},
          {"line_hits", s.line_hits},
          {"line_misses", s.line_misses},
          {"sectors", s.sectors},
          {"sector_hits", s.sector_hits},
          {"sector_misses", s.sector_misses}};
}

nlohmann::json curve_json(const MissRatioCurve& c) {
  nlohmann::json pts = nlohmann::json::array();
  for (uint64_t lines = 1; lines <= std::max<uint64_t>(c.footprint_lines(), 1) * 2; lines *= 2)
    pts.push_back({{"size_bytes", lines * c.line_bytes}, {"miss_ratio", c.miss_ratio(lines)}});
  return {{"sampling_rate", c.sampling_rate}, {"accesses", c.accesses}, {"cold", c.cold}, {"points", pts}};
}

// The outputs are checked before the replay: a bad --mrc path fails at once, not after --out was written.
void check_outputs(const CachesimArgs& a) {
  if (!a.out_path.empty()) check_output_path(a.out_path, "--out");
  if (!a.mrc_path.empty()) check_output_path(a.mrc_path, "--mrc");
  if (!a.export_din_path.empty()) check_output_path(a.export_din_path, "--export-din");
}

// One replayed pass: its tables printed, its JSON returned, its miss-ratio curves appended to `csv`.
nlohmann::json report_pass(const PassResult& r, const trace::TraceHeader& header, const SimOptions& opt,
                           bool per_invocation, std::string& csv) {
  const auto& s = r.stats;
  std::printf(
      "\npass '%s': %llu lane accesses, %llu workgroups, %llu wavefront steps, %u slice(s) (at most %llu "
      "records held at once)\n",
      r.name.c_str(), (unsigned long long)r.lane_accesses, (unsigned long long)r.workgroups,
      (unsigned long long)r.wave_steps, r.slices, (unsigned long long)r.peak_resident_records);
  std::printf("  %-3s %14s %14s %14s %9s %14s %14s\n", "", "requests", "hits", "misses", "hit rate", "sectors",
              "sector misses");
  print_level("L1", s.l1);
  print_level("L2", s.l2);
  std::printf("  L1 by counting (the L1 row: per %s; misses %llu under each):\n", to_string(r.l1_hit_counting),
              (unsigned long long)s.l1.misses);
  for (HitCounting c : {HitCounting::request, HitCounting::quarter_wave, HitCounting::lane}) {
    const uint64_t lookups = r.l1_lookups.of(c);
    std::printf("    %-12s %14llu lookups %14llu hits %9s\n", to_string(c), (unsigned long long)lookups,
                (unsigned long long)(lookups - s.l1.misses), pct(lookups - s.l1.misses, lookups).c_str());
  }
  std::printf("  stores %llu, atomics %llu (write through the L1 / performed at the L2)\n",
              (unsigned long long)s.stores, (unsigned long long)s.atomics);
  std::printf("  DRAM read %llu bytes, written back %llu bytes\n", (unsigned long long)s.dram_read_bytes,
              (unsigned long long)s.dram_write_bytes);
  std::printf("  %-20s %12s %12s %9s %12s %12s %9s %14s\n", "buffer", "L1 requests", "L1 misses", "L1 miss",
              "L2 requests", "L2 misses", "L2 miss", "DRAM read B");
  nlohmann::json buffers = nlohmann::json::array();
  for (const auto& b : header.buffers) {
    const BufferStats& bs = r.buffers[b.id];
    if (!bs.l1_requests && !bs.l2_requests) continue;
    std::printf("  %-20s %12llu %12llu %9s %12llu %12llu %9s %14llu\n", b.name.c_str(),
                (unsigned long long)bs.l1_requests, (unsigned long long)bs.l1_misses,
                pct(bs.l1_misses, bs.l1_requests).c_str(), (unsigned long long)bs.l2_requests,
                (unsigned long long)bs.l2_misses, pct(bs.l2_misses, bs.l2_requests).c_str(),
                (unsigned long long)bs.dram_read_bytes);
    buffers.push_back({{"id", b.id},
                       {"name", b.name},
                       {"l1_requests", bs.l1_requests},
                       {"l1_misses", bs.l1_misses},
                       {"l2_requests", bs.l2_requests},
                       {"l2_misses", bs.l2_misses},
                       {"dram_read_bytes", bs.dram_read_bytes},
                       {"l1_by_counting", l1_by_counting_json(r.buffer_l1_lookups[b.id], bs.l1_misses)}});
  }
  nlohmann::json pj = {{"name", r.name},
                       {"lane_accesses", r.lane_accesses},
                       {"wave_steps", r.wave_steps},
                       {"slices", r.slices},
                       {"peak_resident_records", r.peak_resident_records},
                       {"workgroups", r.workgroups},
                       {"l1", level_json(s.l1)},
                       {"l2", level_json(s.l2)},
                       {"l1_hit_counting", to_string(r.l1_hit_counting)},
                       {"l1_by_counting", l1_by_counting_json(r.l1_lookups, s.l1.misses)},
                       {"stores", s.stores},
                       {"atomics", s.atomics},
                       {"dram_read_bytes", s.dram_read_bytes},
                       {"dram_write_bytes", s.dram_write_bytes},
                       {"buffers", buffers}};
  if (opt.l2_mrc) {
    pj["l1_mrc"] = curve_json(r.l1_curve);
    pj["l2_mrc"] = curve_json(r.l2_curve);
    std::ostringstream c;
    write_mrc_csv(c, "l1", r.l1_curve);
    write_mrc_csv(c, "l2", r.l2_curve);
    std::istringstream lines(c.str());
    for (std::string line; std::getline(lines, line);) csv += r.name + "," + line + "\n";
  }
  if (per_invocation) {
    pj["l1_misses_per_invocation"] = r.l1_misses;
    pj["l2_misses_per_invocation"] = r.l2_misses;
  }
  return pj;
}

void run_trace(const CachesimArgs& a) {
  check_outputs(a);
  Preset preset = scale_for_sampling(find_preset(a.preset), a.scale_model);
  if (!a.l1_hit_counting.empty() && !parse_hit_counting(a.l1_hit_counting, preset.l1_hit_counting))
    throw InputError("--l1-hit-counting: '" + a.l1_hit_counting + "' is not request, quarter_wave or lane");
  trace::TraceReader reader(a.trace_path);
  const auto& header = reader.header();
  if (!a.export_din_path.empty()) {
    if (!a.export_pass.empty() && std::none_of(reader.passes().begin(), reader.passes().end(),
                                               [&](const auto& p) { return p.name == a.export_pass; }))
      throw InputError("--export-pass: no pass named '" + a.export_pass + "' in " + a.trace_path);
    if (a.export_cu >= preset.compute_units)
      throw InputError("--export-cu: compute unit " + std::to_string(a.export_cu) + " does not exist (preset '" +
                       preset.name + "' has " + std::to_string(preset.compute_units) + ")");
  }
  SimOptions opt;
  opt.per_invocation = a.per_invocation;
  opt.l1_mrc = opt.l2_mrc = !a.mrc_path.empty() || !a.out_path.empty();
  opt.mrc_sampling_rate = a.shards;
  Simulator sim(preset, header, opt);

  std::printf(
      "preset %s: %u CUs, wave%u, max %u waves/CU, %s coalescing\n  L1 %s per CU, lookups and hits counted per "
      "%s\n  L2 %s\n",
      preset.name.c_str(), preset.compute_units, preset.wave_width, preset.max_waves_per_cu,
      preset.coalescing == Coalescing::line ? "line" : "sector", describe(preset.l1).c_str(),
      to_string(preset.l1_hit_counting), describe(preset.l2).c_str());
  nlohmann::json out = {{"trace", a.trace_path}, {"preset", preset.name}, {"passes", nlohmann::json::array()}};
  std::string csv = "pass,level,size_bytes,lines,miss_ratio\n";
  bool exported = a.export_din_path.empty();
  for (uint32_t p = 0; p < reader.passes().size(); ++p) {
    const auto& pass = reader.passes()[p];
    // The Dinero export watches this very replay (the request stream does not depend on cache state).
    const bool export_here =
        !a.export_din_path.empty() && (a.export_pass.empty() ? p == 0 : pass.name == a.export_pass);
    // An AtomicFile, committed when the pass is replayed: a failed replay leaves no file behind.
    std::optional<AtomicFile> din;
    uint64_t din_lines = 0;
    if (export_here) {
      din.emplace(a.export_din_path);
      sim.set_observer(din_observer(din->stream(), preset, a.export_cu, false, din_lines));
    }
    // Slice by slice as captured: memory bounded by the largest slice, whatever the frame's size.
    // Progress: the pass's records replayed so far, out of the count in the file.
    sim.begin_pass(pass);
    Progress progress("hybridprof cachesim: " + pass.name + " records", a.quiet);
    const uint64_t total = reader.record_count(p);
    feed_slices(sim, reader, p, [&](uint64_t done) {
      // Lane accesses, not file bytes: a version-2 file codes a record in about 2 bytes.
      char detail[48];
      std::snprintf(detail, sizeof(detail), "%.1f M lane accesses", double(done) / 1e6);
      progress.update(done, total, detail);
    });
    const PassResult r = sim.end_pass();
    if (export_here) {
      sim.set_observer(nullptr);
      din->commit();
      std::printf("exported %llu L1 requests of CU %u in pass '%s' to %s\n", (unsigned long long)din_lines, a.export_cu,
                  pass.name.c_str(), a.export_din_path.c_str());
      exported = true;
    }
    out["passes"].push_back(report_pass(r, header, opt, a.per_invocation, csv));
  }
  if (!exported) throw InputError("--export-pass: no pass named '" + a.export_pass + "' in " + a.trace_path);
  const uint64_t flushed = sim.finish();
  std::printf("\nend of frame: %llu dirty bytes written back from the L2\n", (unsigned long long)flushed);
  out["final_writeback_bytes"] = flushed;
  if (!a.out_path.empty()) write_file_atomically(a.out_path, out.dump(1) + "\n");
  if (!a.mrc_path.empty()) write_file_atomically(a.mrc_path, csv);
}

void print_din_level(const char* name, const DinLevelStats& s) {
  std::printf(
      "%s\n  demand fetches %14llu   (read %llu, write %llu)\n  demand misses  %14llu   (read %llu, write %llu)\n"
      "  miss ratio     %14.6f\n",
      name, (unsigned long long)s.fetches, (unsigned long long)s.read_fetches, (unsigned long long)s.write_fetches,
      (unsigned long long)s.misses, (unsigned long long)s.read_misses, (unsigned long long)s.write_misses,
      s.miss_ratio());
}

void run_din(const CachesimArgs& a) {
  check_outputs(a);
  const CacheConfig l1 = parse_cache_spec(a.l1, "--l1");
  const CacheConfig l2 = parse_cache_spec(a.l2, "--l2");
  // Streamed: a fixed read buffer and one batch of parsed accesses, however large the file.
  uint64_t references = 0;
  const DinResult r = replay_din_file(a.din_path, l1, l2, !a.mrc_path.empty(), references);
  std::printf("%llu references from %s\nL1: %s, write-allocate, write-back\nL2: %s\n", (unsigned long long)references,
              a.din_path.c_str(), describe(l1).c_str(), describe(l2).c_str());
  print_din_level("l1 (data)", r.l1);
  std::printf("  copies back    %14llu\n", (unsigned long long)r.l1_copies_back);
  print_din_level("l2 (unified; demand fetches are the L1 misses)", r.l2);
  if (!a.mrc_path.empty()) {
    std::ostringstream c;
    c << "level,size_bytes,lines,miss_ratio\n";
    write_mrc_csv(c, "l1", r.l1_curve);
    write_mrc_csv(c, "l2", r.l2_curve);
    write_file_atomically(a.mrc_path, c.str());
  }
}

}  // namespace

void add_cachesim_command(CLI::App& app) {
  auto args = std::make_shared<CachesimArgs>();
  CLI::App* cmd = app.add_subcommand("cachesim", "Replay a memory trace through a GPU cache model");
  auto* trace_opt = cmd->add_option("trace", args->trace_path, "Trace file written by `hybridprof trace`");
  auto* din_opt = cmd->add_option("--din", args->din_path, "Dinero IV text trace (r|w ADDR SIZE) to replay instead");
  trace_opt->excludes(din_opt);
  // Options of one mode given in the other are errors, not silently ignored.
  auto* preset = cmd->add_option("--preset", args->preset, "GPU preset name (vega56, ga102, h100) or JSON file")
                     ->capture_default_str();
  auto* out =
      cmd->add_option("--out", args->out_path,
                      "Write per-pass and per-buffer results, with the miss-ratio curves, as JSON (trace files)");
  cmd->add_option("--mrc", args->mrc_path, "Write L1/L2 miss-ratio curves (CSV)");
  auto* shards = cmd->add_option("--shards", args->shards, "Sample miss-ratio curves at this rate (SHARDS), 1 = exact")
                     ->check(finite_range(1e-6, 1.0));
  cmd->add_flag("--quiet", args->quiet, "no progress lines on stderr (trace replay)");
  auto* per_inv =
      cmd->add_flag("--per-invocation", args->per_invocation, "Include per-invocation L1/L2 miss counts in --out")
          ->needs(out);
  auto* scale =
      cmd->add_option(
             "--scale-model", args->scale_model,
             "The trace records 1 in K workgroups (trace --sample-every K): replay it on 1/K of the CUs and L2")
          ->check(CLI::Range(1u, 0xFFFFFu))
          ->capture_default_str();
  auto* hit_counting =
      cmd->add_option("--l1-hit-counting", args->l1_hit_counting,
                      "Count the L1 table's lookups and hits per request, quarter_wave or lane (default: the "
                      "preset's l1_hit_counting; misses and the L2 are the same under each, and --out has all three)");
  auto* export_din =
      cmd->add_option("--export-din", args->export_din_path, "Write one CU's coalesced L1 load stream as Dinero text");
  cmd->add_option("--export-pass", args->export_pass, "Pass to export (default: the first)")->needs(export_din);
  cmd->add_option("--export-cu", args->export_cu, "Compute unit to export")->capture_default_str()->needs(export_din);
  auto* l1 = cmd->add_option("--l1", args->l1, "Dinero replay L1 as SIZE:LINE:ASSOC")->capture_default_str();
  auto* l2 = cmd->add_option("--l2", args->l2, "Dinero replay L2 as SIZE:LINE:ASSOC")->capture_default_str();
  for (CLI::Option* o : {preset, out, shards, per_inv, scale, hit_counting, export_din}) din_opt->excludes(o);
  trace_opt->excludes(l1)->excludes(l2);
  cmd->callback([args] {
    if (!args->din_path.empty())
      run_din(*args);
    else if (!args->trace_path.empty())
      run_trace(*args);
    else
      throw InputError("cachesim: give a trace file or --din FILE");
  });
}

}  // namespace hp::cli
