#include "report.hpp"

#include "atomic_file.hpp"
#include "error.hpp"
#include "markdown.hpp"
#include "study.hpp"
#include "svg_chart.hpp"
#include "timing/stats.hpp"
#include "tradeoff.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

namespace hp {

using json = nlohmann::json;
namespace fs = std::filesystem;

namespace {

std::string fmt(const char* f, double v) { return format_number(f, v); }
std::string ms(double ns) { return fmt("%.3f", ns / 1e6); }
std::string pct(double ratio) { return fmt("%+.1f%%", (ratio - 1.0) * 100.0); }
std::string p_text(double p) { return p < 0.001 ? "< 0.001" : fmt("%.3f", p); }

// Environment fields that decide whether numbers are comparable, and the rest shown for context.
struct EnvField {
  const char* label;
  std::string (*get)(const Environment&);
  bool must_match;
};
const EnvField kEnv[] = {
    {"device", [](const Environment& e) { return e.device.name; }, true},
    {"driver", [](const Environment& e) { return e.device.driver_name + " / " + e.device.driver_info; }, true},
    {"Vulkan API", [](const Environment& e) { return e.device.api_version; }, false},
    {"CPU", [](const Environment& e) { return e.cpu_model; }, false},
    {"cores", [](const Environment& e) { return std::to_string(e.core_count); }, true},
    {"LP_NUM_THREADS", [](const Environment& e) { return e.lp_num_threads; }, true},
    {"commit", [](const Environment& e) { return e.git_commit; }, true},
    {"build", [](const Environment& e) { return e.build_type + ", " + e.compiler; }, false},
    {"host", [](const Environment& e) { return e.hostname + " (" + e.os + ")"; }, false},
    {"date (UTC)", [](const Environment& e) { return e.date_utc; }, false},
    {"load (1 min) at cell start",
     [](const Environment& e) { return e.load_1min ? format_number("%.2f", *e.load_1min) : std::string("unknown"); },
     false},
    {"CPU governor", [](const Environment& e) { return e.cpu_governor; }, true},
};

// How the cells were measured: interleaved rounds (their number, how often a frame was rebuilt, the load
// over the visits) or one after another.
std::string design_text(const std::vector<CellResult>& cells) {
  std::set<std::uint32_t> counts;
  size_t visits = 0, rebuilt = 0, sequential = 0;
  double load_lo = 1e300, load_hi = -1e300;
  for (const CellResult& c : cells) {
    const json r = c.line.value("rounds", json());
    if (!r.is_object() || r.value("count", 1) < 2) {
      ++sequential;
      continue;
    }
    counts.insert(r["count"].get<std::uint32_t>());
    for (const json& v : r.value("visits", json::array())) {
      ++visits;
      rebuilt += v.value("rebuilt", false) ? 1 : 0;
    }
    if (const auto load = recorded_load(c)) {
      load_lo = std::min(load_lo, load->first);
      load_hi = std::max(load_hi, load->second);
    }
  }
  std::string s;
  if (!counts.empty()) {
    std::string n;
    for (std::uint32_t c : counts) n += (n.empty() ? "" : ", ") + std::to_string(c);
    s += "**Measurement design.** " + std::to_string(cells.size() - sequential) + " cell(s) were measured in " + n +
         " interleaved rounds: each round visited every cell once, in a fresh shuffled order, and timed its share "
         "of the cell's frames, so a drift of the machine reaches every cell alike. Of the " +
         std::to_string(visits) + " visits, " + std::to_string(rebuilt) +
         " built the cell's frame anew (first visits, and frames evicted beyond `run --live-frames`); the others "
         "kept it alive from the previous round and re-warmed it with one frame." +
         (load_hi >= load_lo
              ? " The 1-minute load over the visits ranged " + fmt("%.2f", load_lo) + " … " + fmt("%.2f", load_hi) + "."
              : std::string()) +
         "\n";
  }
  if (sequential > 0) {
    s += std::string(counts.empty() ? "**Measurement design.** " : "") + std::to_string(sequential) +
         " cell(s) were measured in one round, one cell after another: a drift of the machine between them can "
         "read as a change between cells (matrix key `rounds`, or `run --rounds`, interleaves them).\n";
  }
  return s;
}

std::string environment_section(const std::vector<CellResult>& cells) {
  std::string s = "## Environment\n\n| | |\n|---|---|\n";
  std::vector<std::string> differing;
  for (const EnvField& f : kEnv) {
    std::vector<std::string> values;
    for (const CellResult& c : cells) {
      const std::string v = f.get(c.timing.environment);
      if (std::find(values.begin(), values.end(), v) == values.end()) values.push_back(v);
    }
    std::string joined;
    if (std::string(f.label) == "date (UTC)" && values.size() > 1) {
      std::sort(values.begin(), values.end());
      joined = values.front() + " … " + values.back();
    } else if (std::string(f.label).rfind("load", 0) == 0 && values.size() > 1) {
      // A range over the cells, numerically ("unknown" sorts first).
      std::sort(values.begin(), values.end(),
                [](const std::string& a, const std::string& b) { return std::atof(a.c_str()) < std::atof(b.c_str()); });
      joined = values.front() + " … " + values.back();
    } else {
      for (const std::string& v : values) joined += (joined.empty() ? "" : "; ") + v;
    }
    s += std::string("| ") + f.label + " | " + md::escape(joined) + " |\n";
    if (f.must_match && values.size() > 1) differing.push_back(f.label);
  }
  if (!differing.empty()) {
    std::string d;
    for (const std::string& x : differing) d += (d.empty() ? "" : ", ") + x;
    s += "\n> **Warning:** the cells ran with different " + d +
         ". Timings of cells from different environments are not comparable; the comparisons below still "
         "show them.\n";
  }
  const TimingSummary& t = cells.front().timing.summary;
  s += "\nTimes come from " +
       std::string(t.source == TimingSource::GpuTimestamps ? "GPU timestamps" : "CPU wall clocks") +
       " around each pass, after discarded warm-up frames; raw results keep nanoseconds.\n";
  s += "\n" + design_text(cells);
  return s;
}

struct PassStat {
  std::string pass;
  std::vector<double> samples;
  Summary summary;
};
std::vector<PassStat> pass_stats(const CellResult& c) {
  std::vector<PassStat> out;
  for (auto& [pass, samples] : pass_samples(c.timing)) out.push_back({pass, samples, summarize(samples)});
  return out;
}

std::string ci_text(const Summary& s) {
  if (!s.median_ci.valid) return "— (n < 6)";
  return "[" + ms(s.median_ci.low) + ", " + ms(s.median_ci.high) + "]";
}

bool has_pass(const Counters& c, const std::string& pass) { return c.passes().count(pass) > 0; }

// One traced pass of a cell's cache tables (analyse_trace's schema), with the study's four counts.
struct CachePass {
  std::string pass;
  double l1_hits = 0, l1_misses = 0, l2_hits = 0, l2_misses = 0;
  const json* j = nullptr;
  /// L1 hits counted per lane, the study's hardware counter's units (l1_by_counting.lane; absent in tables
  /// written before the model counted them).
  std::optional<double> l1_lane_hits;
};
double num_or0(const json& j, const char* k) { return j.contains(k) && j[k].is_number() ? j[k].get<double>() : 0.0; }
std::vector<CachePass> cache_passes(const CellResult& c) {
  std::vector<CachePass> out;
  if (!c.cache.is_object() || !c.cache.contains("passes") || !c.cache["passes"].is_array()) return out;
  for (const json& p : c.cache["passes"]) {
    if (!p.is_object() || !p.contains("pass") || !p["pass"].is_string()) continue;
    const json l1 = p.value("l1", json::object()), l2 = p.value("l2", json::object());
    out.push_back({p["pass"].get<std::string>(), num_or0(l1, "hits"), num_or0(l1, "misses"), num_or0(l2, "hits"),
                   num_or0(l2, "misses"), &p, std::nullopt});
    const json lane = p.value("l1_by_counting", json::object()).value("lane", json::object());
    if (lane.contains("hits") && lane["hits"].is_number()) out.back().l1_lane_hits = lane["hits"].get<double>();
  }
  return out;
}
std::string rate(double hits, double misses) {
  return hits + misses > 0 ? fmt("%.1f%%", 100.0 * hits / (hits + misses)) : std::string("—");
}

// The cell traced through the driver's acceleration structure (ray-query, pipeline): its traversal is
// opaque, its node and triangle counters are 0 and its cache tables hold the shaders' own accesses only.
std::string traversal_of(const CellResult& c) {
  return c.config.contains("traversal") && c.config["traversal"].is_string() ? c.config["traversal"].get<std::string>()
                                                                             : "compute";
}
bool driver_traversal(const CellResult& c) { return traversal_of(c) != "compute"; }

// "l1_misses" -> "L1 misses".
std::string kind_text(const std::string& kind) {
  std::string t = kind;
  std::replace(t.begin(), t.end(), '_', ' ');
  if (t.size() >= 2 && t[0] == 'l') t[0] = 'L';
  return t;
}

// The cell's cache tables; the colour bars of its heatmaps go to `bars` (none when null).
std::string cache_tables(const CellResult& c, std::vector<ReportFile>* bars) {
  const std::vector<CachePass> passes = cache_passes(c);
  if (passes.empty()) return "";
  std::string s =
      driver_traversal(c)
          ? "\nThis cell traced through the driver's acceleration structure, whose traversal is opaque: the tables "
            "below are the traced shaders' own accesses (G-buffer, the hits' shading, the outputs, the compaction "
            "buffers), not the pass's traversal traffic (its nodes and triangles are the driver's).\n"
          : "";
  s +=
      "\nCache simulation (preset " + c.cache.value("preset", std::string("?")) + ", one traced frame" +
      (c.cache.contains("simulation_s") && c.cache["simulation_s"].is_number()
           ? ", simulated in " + fmt("%.2f", c.cache["simulation_s"].get<double>()) + " s"
           : std::string()) +
      "), in the study's form:\n\n| pass | L1 hit | L1 miss | L2 hit | L2 miss | L1 hit rate | L2 hit rate |\n|---|---|---|---|---|---|---|\n";
  std::string buffers, heatmaps;
  for (const CachePass& p : passes) {
    s += "| " + p.pass + " | " + md::count(p.l1_hits) + " | " + md::count(p.l1_misses) + " | " + md::count(p.l2_hits) +
         " | " + md::count(p.l2_misses) + " | " + rate(p.l1_hits, p.l1_misses) + " | " + rate(p.l2_hits, p.l2_misses) +
         " |\n";
    if (p.j->contains("buffers") && (*p.j)["buffers"].is_object()) {
      for (const auto& [buf, b] : (*p.j)["buffers"].items()) {
        const double l1r = num_or0(b, "l1_requests"), l1m = num_or0(b, "l1_misses");
        const double l2r = num_or0(b, "l2_requests"), l2m = num_or0(b, "l2_misses");
        buffers += "| " + p.pass + " | " + buf + " | " + md::count(l1r) + " | " + md::count(l1m) + " | " +
                   rate(l1r - l1m, l1m) + " | " + md::count(l2r) + " | " + md::count(l2m) + " | " +
                   rate(l2r - l2m, l2m) + " |\n";
      }
    }
    if (p.j->contains("heatmaps") && (*p.j)["heatmaps"].is_object()) {
      for (const auto& [kind, path] : (*p.j)["heatmaps"].items()) {
        if (!path.is_string()) continue;
        heatmaps +=
            "[![" + p.pass + " " + kind + "](" + path.get<std::string>() + ")](" + path.get<std::string>() + ")\n";
        // Its colour bar, where the tables say what the top of its scale is (tables from before they did: none).
        const json top = p.j->value("heatmap_max", json::object()).value(kind, json());
        if (top.is_number_integer() && top.get<std::int64_t>() >= 0 && bars) {
          const std::string file = "charts/heatmap_" + c.id + "_" + p.pass + "_" + kind + ".svg";
          bars->push_back({file, svg::render_colour_bar(p.pass + " " + kind_text(kind) + " per pixel (log scale)",
                                                        top.get<std::uint64_t>())});
          heatmaps += "![colour bar](" + file + ")\n\n";
        }
      }
    }
  }
  if (!buffers.empty()) {
    s +=
        "\nPer buffer:\n\n| pass | buffer | L1 requests | L1 misses | L1 hit rate | L2 requests | L2 misses | L2 hit rate |\n"
        "|---|---|---|---|---|---|---|---|\n" +
        buffers;
  }
  if (!heatmaps.empty())
    s += "\nMiss heatmaps (misses per pixel on a log scale, black none; each with its colour bar):\n\n" + heatmaps +
         "\n";
  return s;
}

// How the pass times were kept apart, and what the frame as the application records it costs beside
// them: a paragraph under a cell's pass table.
std::string overlap_text(const TimingSummary& t) {
  std::string s;
  switch (t.pass_isolation) {
    case PassIsolation::Serialized:
      s = "\nPasses are serialized for these times (an execution dependency at every pass boundary), so each "
          "interval holds one pass.";
      break;
    case PassIsolation::HostSubmissions:
      s = "\nPasses are timed on the host, one submission each (submit and wait included).";
      break;
    case PassIsolation::Unisolated:
      s = "\nThese pass times come from boundary timestamps with no dependency added between passes (a result "
          "written before pass isolation existed): where the device overlaps passes, an interval may hold "
          "parts of two passes.";
      break;
  }
  if (!t.overlap) return s + "\n";
  const OverlapSummary& o = *t.overlap;
  auto interval = [](const MedianCi& ci) {
    return ci.valid ? " (95% CI " + ms(ci.low) + " to " + ms(ci.high) + " ms)" : std::string(" (no CI: n < 6)");
  };
  s += " The frame as the application records it (passes free to overlap) took " + ms(o.overlapped_frame_ns.median) +
       " ms" + interval(o.overlapped_frame_ns.median_ci) + "; the serialized passes sum to " +
       ms(o.serialized_sum_ns.median) + " ms";
  if (!o.saving_ns) return s + ".\n";
  const std::string frac = o.saving_fraction ? fmt("%.1f%%", *o.saving_fraction * 100.0) : std::string("—");
  const std::string pairs = std::to_string(o.frames) + " frame pairs";
  if (!o.saving_ns_ci.valid) {
    s += ". The paired difference (serialized sum minus overlapped frame) is " + ms(*o.saving_ns) + " ms (" + frac +
         ") over " + pairs + ": too few pairs for a 95% CI, so it cannot be told from noise.\n";
  } else if (o.saving_ns_ci.low > 0.0) {
    s += ": overlapping the passes saves " + ms(*o.saving_ns) + " ms" + interval(o.saving_ns_ci) + ", " + frac +
         " of the serialized sum (paired over " + pairs + ").\n";
  } else if (o.saving_ns_ci.high < 0.0) {
    s += ": the overlapped frame is slower by " + ms(-*o.saving_ns) + " ms (95% CI " + ms(-o.saving_ns_ci.high) +
         " to " + ms(-o.saving_ns_ci.low) + " ms, paired over " + pairs + ").\n";
  } else {
    s += ": no measurable saving from overlap (paired over " + pairs + ", the 95% CI of the saving, " +
         ms(o.saving_ns_ci.low) + " to " + ms(o.saving_ns_ci.high) + " ms, includes 0).\n";
  }
  return s;
}

// A cell kept by `run --reuse-stale`: measured by another build or driver than the rest of the run.
bool stale(const CellResult& c) { return c.line.contains("stale") && c.line["stale"].is_object(); }

std::string cell_section(const CellResult& c, std::vector<ReportFile>& charts) {
  std::string s = "### " + md::escape(cell_label(c)) + "\n\n";
  if (stale(c))
    s += "> **Stale:** measured by " + md::escape(c.line["stale"].value("measured_by", std::string("?"))) +
         ", kept by `run --reuse-stale` under " + md::escape(c.line["stale"].value("reused_by", std::string("?"))) +
         "; no time of this cell is compared.\n\n";
  s += "Cell `" + c.id + "`";
  if (!c.name.empty()) s += " of `" + c.name + "`";
  s += ": " + std::to_string(c.timing.timings.measured().size()) + " measured frames after " +
       std::to_string(c.timing.summary.warmup_frames) + " warm-up.\n\n";
  s += "| pass | median (ms) | 95% CI of the median (ms) | frames | CV |\n|---|---|---|---|---|\n";
  const std::vector<PassStat> stats = pass_stats(c);
  for (const PassStat& p : stats) {
    s += "| " + p.pass + " | " + ms(p.summary.median) + " | " + ci_text(p.summary) + " | " +
         std::to_string(p.summary.count) + " | " +
         (p.summary.cv ? fmt("%.1f%%", *p.summary.cv * 100.0) : std::string("—")) + " |\n";
  }
  s += overlap_text(c.timing.summary);
  const Counters& k = c.timing.counters;
  const double frames = double(c.timing.timings.measured().size());
  if (!k.empty()) {
    s += "\n| pass | rays per frame | nodes per ray | triangles per ray | Mrays/s |\n|---|---|---|---|---|\n";
    // The driver's traversal counts no nodes or triangles: a dash, not a zero.
    const bool opaque = driver_traversal(c);
    const auto work = [&](const std::string& pass, const char* counter_name) {
      return opaque ? std::string("—") : fmt("%.2f", per_ray(k, pass, counter_name).value_or(0.0));
    };
    for (const PassStat& p : stats) {
      if (!has_pass(k, p.pass) || k.get(p.pass, counter::rays_cast) == 0) continue;
      const double rays = double(k.get(p.pass, counter::rays_cast));
      s += "| " + p.pass + " | " + md::count(rays / frames) + " | " + work(p.pass, counter::nodes_visited) + " | " +
           work(p.pass, counter::triangles_tested) + " | " +
           fmt("%.2f", p.summary.median > 0 ? rays / frames / p.summary.median * 1e3 : 0.0) + " |\n";
    }
  }
  if (c.bvh.is_object()) {
    s += "\nBVH: " + md::count(c.bvh.value("nodes", 0.0)) + " nodes, " + md::count(c.bvh.value("leaves", 0.0)) +
         " leaves, depth " + std::to_string(c.bvh.value("max_depth", 0)) + ", SAH cost " +
         fmt("%.3f", c.bvh.value("sah_cost", 0.0)) + ", built in " + fmt("%.1f", c.bvh.value("build_ms", 0.0)) + " ms";
    s += c.triangles ? " over " + md::count(double(*c.triangles)) + " triangles.\n" : ".\n";
  } else if (c.triangles) {
    s += "\nScene: " + md::count(double(*c.triangles)) + " triangles (no BVH: no rays traced).\n";
  }
  s += cache_tables(c, &charts);
  s += error_table(c);
  if (c.images.is_object() && !c.images.empty()) {
    s += "\n";
    for (const auto& [kind, path] : c.images.items()) {
      if (!path.is_string()) continue;
      const std::string alt = kind == "shadow" ? "shadow mask (white: lit)" : kind;
      s += "[![" + alt + "](" + path.get<std::string>() + ")](" + path.get<std::string>() + ") ";
    }
    s += "\n";
  }
  return s + "\n";
}

// The x position of a numeric axis value: the number, or the product of a numeric array
// (a resolution [w, h] becomes its pixel count). nullopt when the value is not numeric.
std::optional<double> numeric_value(const json& v) {
  if (v.is_number()) return v.get<double>();
  if (v.is_array() && !v.empty()) {
    double p = 1.0;
    for (const json& e : v) {
      if (!e.is_number()) return std::nullopt;
      p *= e.get<double>();
    }
    return p;
  }
  return std::nullopt;
}

std::vector<std::string> axes_of(const std::vector<CellResult>& cells) {
  std::vector<std::string> axes;
  for (const CellResult& c : cells)
    for (const auto& [k, v] : c.axes.items())
      if (std::find(axes.begin(), axes.end(), k) == axes.end()) axes.push_back(k);
  return axes;
}

// Other axes of a cell, as a key for "held equal".
std::string others_key(const CellResult& c, const std::string& axis) {
  json o = c.axes;
  o.erase(axis);
  return o.dump();
}
std::string others_text(const CellResult& c, const std::string& axis) {
  std::string s;
  for (const auto& [k, v] : c.axes.items())
    if (k != axis) s += (s.empty() ? "" : ", ") + axis_leaf(k) + "=" + axis_value_text(v);
  return s;
}

std::string slug(const std::string& s) {
  std::string out;
  for (char ch : s) out += std::isalnum(static_cast<unsigned char>(ch)) ? ch : '_';
  return out;
}

void charts_section(const std::vector<CellResult>& cells, Report& r, std::string& s) {
  s += "## Charts\n\n";
  // Bar chart: every cell a group, every pass a bar; error bars are the 95% CI of the median.
  svg::BarChart bars;
  bars.title = "Median pass time per cell (error bars: 95% CI of the median)";
  bars.y_label = "ms";
  std::vector<std::vector<PassStat>> all;
  for (const CellResult& c : cells) all.push_back(pass_stats(c));
  for (const auto& stats : all)
    for (const PassStat& p : stats)
      if (std::find(bars.series.begin(), bars.series.end(), p.pass) == bars.series.end()) bars.series.push_back(p.pass);
  for (size_t i = 0; i < cells.size(); ++i) {
    svg::BarGroup g;
    g.label = cell_label(cells[i]);  // whole: the chart makes room for it (a cut label can lose what differs)
    for (const std::string& pass : bars.series) {
      auto it = std::find_if(all[i].begin(), all[i].end(), [&](const PassStat& p) { return p.pass == pass; });
      const double med = it == all[i].end() ? 0.0 : it->summary.median / 1e6;
      g.values.push_back(med);
      g.low.push_back(it == all[i].end() ? 0.0 : it->summary.median_ci.low / 1e6);
      g.high.push_back(it == all[i].end() ? 0.0 : it->summary.median_ci.high / 1e6);
    }
    bars.groups.push_back(g);
  }
  // At most kCellsPerChart cells a chart, so that a long sweep is several charts that stay legible at a
  // page's width rather than one strip thousands of pixels wide; the charts share one y scale.
  constexpr size_t kCellsPerChart = 12;
  if (bars.groups.size() <= kCellsPerChart) {
    r.charts.push_back({"charts/pass_times.svg", svg::render(bars)});
    s += "![median pass time per cell](charts/pass_times.svg)\n\n";
  } else {
    double hi = 0;
    for (const svg::BarGroup& g : bars.groups)
      for (const std::vector<double>* v : {&g.values, &g.high})
        for (double x : *v) hi = std::max(hi, x);
    const size_t n = bars.groups.size(), parts = (n + kCellsPerChart - 1) / kCellsPerChart;
    for (size_t k = 0; k < parts; ++k) {
      svg::BarChart part = bars;
      const size_t first = k * n / parts, end = (k + 1) * n / parts;  // parts of equal size, give or take one
      part.groups.assign(bars.groups.begin() + long(first), bars.groups.begin() + long(end));
      part.y_max = hi;
      part.title = "Median pass time, cells " + std::to_string(first + 1) + "–" + std::to_string(end) + " of " +
                   std::to_string(n) + " (error bars: 95% CI)";
      const std::string path = "charts/pass_times_" + std::to_string(k + 1) + ".svg";
      r.charts.push_back({path, svg::render(part)});
      s += "![median pass time, cells " + std::to_string(first + 1) + " to " + std::to_string(end) + "](" + path +
           ")\n\n";
    }
  }
  if (std::any_of(all.begin(), all.end(), [](auto& st) {
        return std::any_of(st.begin(), st.end(), [](const PassStat& p) { return !p.summary.median_ci.valid; });
      })) {
    s += "Cells with fewer than 6 frames have no 95% CI; their error bars span the full range of the frames.\n\n";
  }

  // Line charts: time against every numeric axis, one chart per combination of the other axes.
  for (const std::string& axis : axes_of(cells)) {
    bool numeric = true;
    for (const CellResult& c : cells)
      if (c.axes.contains(axis) && !numeric_value(c.axes[axis])) numeric = false;
    if (!numeric) continue;
    std::map<std::string, std::vector<size_t>> groups;  // other axes -> cells
    std::vector<std::string> order;
    for (size_t i = 0; i < cells.size(); ++i) {
      if (!cells[i].axes.contains(axis)) continue;
      const std::string k = others_key(cells[i], axis);
      if (!groups.count(k)) order.push_back(k);
      groups[k].push_back(i);
    }
    const bool product = cells.front().axes.contains(axis) && cells.front().axes[axis].is_array();
    size_t n_chart = 0;
    for (const std::string& k : order) {
      const auto& idx = groups[k];
      if (idx.size() < 2) continue;
      if (++n_chart > 8) {
        s += "(further charts along `" + axis + "` left out: more than 8 combinations of the other axes)\n\n";
        break;
      }
      svg::LineChart lc;
      const std::string others = others_text(cells[idx[0]], axis);
      lc.title = "Median pass time vs " + axis_leaf(axis) + (others.empty() ? "" : " (" + others + ")");
      lc.x_label = axis_leaf(axis) + (product ? " (product of the values, e.g. pixels)" : "");
      lc.y_label = "ms";
      for (const std::string& pass : bars.series) {
        svg::Line line;
        line.name = pass;
        for (size_t i : idx) {
          auto it = std::find_if(all[i].begin(), all[i].end(), [&](const PassStat& p) { return p.pass == pass; });
          if (it == all[i].end()) continue;
          line.x.push_back(*numeric_value(cells[i].axes[axis]));
          line.y.push_back(it->summary.median / 1e6);
          line.low.push_back(it->summary.median_ci.low / 1e6);
          line.high.push_back(it->summary.median_ci.high / 1e6);
        }
        if (!line.x.empty()) lc.lines.push_back(line);
      }
      const std::string path = "charts/vs_" + slug(axis_leaf(axis)) + "_" + std::to_string(n_chart) + ".svg";
      r.charts.push_back({path, svg::render(lc)});
      s += "![" + lc.title + "](" + path + ")\n\n";
    }
  }

  // Miss-ratio curves of the traced passes, one chart per cell (listed under "Cache simulation").
  for (size_t i = 0; i < cells.size(); ++i) {
    svg::LineChart mc;
    mc.title = "Miss ratio vs cache size: " + cell_label(cells[i]);
    mc.x_label = "fully associative LRU cache size, log2 bytes (10 = 1 KiB, 20 = 1 MiB)";
    mc.y_label = "miss ratio";
    for (const CachePass& p : cache_passes(cells[i])) {
      if (!p.j->contains("mrc") || !(*p.j)["mrc"].is_object()) continue;
      for (const char* level : {"l1", "l2"}) {
        const json& curve = (*p.j)["mrc"].value(level, json::object());
        if (!curve.contains("points") || !curve["points"].is_array()) continue;
        svg::Line line;
        line.name = p.pass + " " + (std::string(level) == "l1" ? "L1" : "L2");
        for (const json& pt : curve["points"]) {
          if (!pt.is_array() || pt.size() != 2 || !pt[0].is_number() || !pt[1].is_number() || pt[0].get<double>() <= 0)
            continue;
          line.x.push_back(std::log2(pt[0].get<double>()));
          line.y.push_back(pt[1].get<double>());
        }
        if (!line.x.empty()) mc.lines.push_back(line);
      }
    }
    if (!mc.lines.empty()) r.charts.push_back({"charts/mrc_" + cells[i].id + ".svg", svg::render(mc)});
  }
}

// One comparison: cell b against cell a, which differ only in `axis`.
// ---- the family of timing comparisons ----------------------------------------------------------

constexpr double kAlpha = 0.05;

// Two cells that differ in one axis only, in the order the comparisons section lists them.
struct CellPair {
  const CellResult* a;
  const CellResult* b;
  std::string axis;
};

std::vector<CellPair> axis_pairs(const std::vector<CellResult>& cells, const std::string& axis) {
  std::vector<json> values;
  for (const CellResult& c : cells)
    if (c.axes.contains(axis) && std::find(values.begin(), values.end(), c.axes[axis]) == values.end())
      values.push_back(c.axes[axis]);
  std::vector<CellPair> out;
  for (size_t i = 0; i < values.size(); ++i)
    for (size_t j = i + 1; j < values.size(); ++j)
      for (const CellResult& a : cells) {
        if (!a.axes.contains(axis) || a.axes[axis] != values[i]) continue;
        for (const CellResult& b : cells)
          if (b.axes.contains(axis) && b.axes[axis] == values[j] && others_key(a, axis) == others_key(b, axis))
            out.push_back({&a, &b, axis});
      }
  return out;
}

// One pass's time in two cells: the test, its Holm adjustment over every timing comparison of the report,
// the change with its interval, the noise floor and the verdict. Interleaved cells (two or more rounds
// each) are compared by their round medians, the level where the variance between rounds is; cells of one
// round by their frames.
struct TimeComparison {
  const CellResult* a;
  const CellResult* b;
  std::string axis, pass;
  Summary sa, sb;  ///< over the frames (the tables' medians)
  double p_raw = 1.0, p_holm = 1.0;
  bool exact = false, b_slower = false;
  bool by_rounds = false;  ///< the samples tested are round medians (else frames)
  bool paired = false;     ///< round r of one cell against round r of the other (signed-rank test)
  size_t na = 0, nb = 0;   ///< samples tested a side
  double change = 0.0;     ///< b against a: Hodges-Lehmann ratio of round medians, else ratio of medians, minus 1
  std::optional<std::pair<double, double>> ci;  ///< the change's 95% interval
  /// What an A/A of this pass moves: the change between the odd and the even rounds of the same cell, the
  /// larger of the two cells'. 0 without rounds (not measured).
  double noise_floor = 0.0;
  double ma = 0.0, mb = 0.0;    ///< the medians shown: of the round medians (by rounds), else of the frames
  bool identical_work = false;  ///< both cells count the pass's work, and every counter is equal per frame
  std::string verdict;          ///< "faster", "slower", "no change" or "inconclusive"
  double ratio() const { return 1.0 + change; }
};

double per_frame(const CellResult& c, const std::string& pass, const std::string& name) {
  return double(c.timing.counters.get(pass, name)) / double(c.timing.timings.measured().size());
}


// The same work in both cells: every work counter of the pass equal per frame AND its simulated L1 and L2
// hits and misses equal. Counters alone are not enough: a change of data layout (geometry: indexed or
// soup) casts the same rays through the same nodes with other memory traffic. Without cache tables for the
// pass in both cells, nothing is claimed.
bool identical_work(const CellResult& a, const CellResult& b, const std::string& pass) {
  // The driver's traversal is not counted: equal counters say nothing of the work it did.
  if (driver_traversal(a) || driver_traversal(b)) return false;
  const Counters &ka = a.timing.counters, &kb = b.timing.counters;
  if (!has_pass(ka, pass) || !has_pass(kb, pass)) return false;
  const auto& ca = ka.passes().at(pass);
  const auto& cb = kb.passes().at(pass);
  if (ca.empty() || ca.size() != cb.size()) return false;
  for (const auto& [name, value] : ca)
    if (!cb.count(name) || per_frame(a, pass, name) != per_frame(b, pass, name)) return false;
  const std::vector<CachePass> xa = cache_passes(a), xb = cache_passes(b);
  const auto find = [&](const std::vector<CachePass>& v) {
    return std::find_if(v.begin(), v.end(), [&](const CachePass& p) { return p.pass == pass; });
  };
  const auto pa = find(xa), pb = find(xb);
  if (pa == xa.end() || pb == xb.end()) return false;
  return pa->l1_hits == pb->l1_hits && pa->l1_misses == pb->l1_misses && pa->l2_hits == pb->l2_hits &&
         pa->l2_misses == pb->l2_misses;
}

// A pass that did the same work in both cells did not change speed: whatever its times did is the
// machine's. Where even the smallest p the samples allow exceeds alpha the comparison cannot tell.
// Otherwise the test (signed-rank over paired rounds, else U), Holm-adjusted over the family, decides in
// the direction the samples moved, and only for a change larger than the noise floor: what the pass moves
// between rounds of one cell is never an effect.
std::string time_verdict(const TimeComparison& t) {
  if (t.identical_work) return "no change";
  if (stale(*t.a) || stale(*t.b)) return "inconclusive";  // another build's times
  // The bound holds for the permutation test with ties too (they only coarsen its distribution); the normal
  // approximation used with ties can go lower, but at these sizes that is the approximation, not evidence.
  if ((t.paired ? signed_rank_min_p(t.na) : mann_whitney_min_p(t.na, t.nb)) > kAlpha) return "inconclusive";
  if (std::abs(t.change) <= t.noise_floor) return "no change";
  const bool significant_up = t.p_holm <= kAlpha && t.b_slower && t.change > 0.0;
  const bool significant_down = t.p_holm <= kAlpha && !t.b_slower && t.change < 0.0;
  if (!significant_up && !significant_down) return "no change";
  // Measured by rounds, the whole interval must clear the noise floor: a significant change whose interval
  // reaches into what an A/A moves cannot be told from one.
  if (t.by_rounds && (!t.ci || (significant_up ? t.ci->first <= t.noise_floor : t.ci->second >= -t.noise_floor)))
    return "inconclusive";
  return significant_up ? "slower" : "faster";
}

const std::vector<double>* find_pass(const PassSamples& samples, const std::string& pass) {
  for (const auto& [name, v] : samples)
    if (name == pass) return &v;
  return nullptr;
}

// The change's 95% interval from the two medians' distribution-free intervals (conservative: the
// extremes of the ratio), when both are valid.
std::optional<std::pair<double, double>> median_ratio_interval(const Summary& sa, const Summary& sb) {
  const MedianCi &ca = sa.median_ci, &cb = sb.median_ci;
  if (!ca.valid || !cb.valid || ca.low <= 0 || ca.high <= 0) return std::nullopt;
  return std::pair{cb.low / ca.high - 1.0, cb.high / ca.low - 1.0};
}

// The test, change, interval and noise floor of one series of times in two cells (verdict and Holm later).
TimeComparison compare_series(const CellPair& cp, const std::string& pass, const TimeSeries& a, const TimeSeries& b) {
  TimeComparison t{cp.a, cp.b, cp.axis, pass, summarize(a.frames), summarize(b.frames)};
  const auto positive = [](const std::vector<double>& v) {
    return v.size() >= 2 && v.size() < 50 && std::all_of(v.begin(), v.end(), [](double x) { return x > 0; });
  };
  t.by_rounds = positive(a.round_medians) && positive(b.round_medians);
  // Rounds of one run pair up: round r of both cells ran in the same round, close in time, so the pair's
  // ratio cancels the state the machine was in (both cells were measured in as many rounds).
  t.paired = t.by_rounds && a.round_medians.size() == b.round_medians.size();
  const std::vector<double>& ya = t.by_rounds ? a.round_medians : a.frames;
  const std::vector<double>& yb = t.by_rounds ? b.round_medians : b.frames;
  t.na = ya.size();
  t.nb = yb.size();
  ShiftCi hl;  // of the log round medians (a shift of logarithms is the ratio's logarithm)
  if (t.paired) {
    std::vector<double> d;
    for (size_t r = 0; r < ya.size(); ++r) d.push_back(std::log(yb[r]) - std::log(ya[r]));
    const SignedRankResult w = wilcoxon_signed_rank(d);
    t.p_raw = w.p_value;
    t.exact = w.exact;
    t.b_slower = w.v > 0.25 * double(w.n) * double(w.n + 1);
    hl = hodges_lehmann_paired_ci(d);
  } else {
    const MannWhitneyResult mw = mann_whitney_u(yb, ya);
    t.p_raw = mw.p_value;
    t.exact = mw.exact;
    t.b_slower = mw.u > 0.5 * double(t.na) * double(t.nb);
    if (t.by_rounds) {
      std::vector<double> la, lb;
      for (double v : ya) la.push_back(std::log(v));
      for (double v : yb) lb.push_back(std::log(v));
      hl = hodges_lehmann_ci(lb, la);
    }
  }
  if (t.by_rounds) {
    t.change = std::exp(hl.shift) - 1.0;
    if (hl.ci.valid) t.ci = std::pair{std::exp(hl.ci.low) - 1.0, std::exp(hl.ci.high) - 1.0};
    t.noise_floor = std::max(odd_even_change(ya), odd_even_change(yb));
    t.ma = quantile(ya, 0.5);
    t.mb = quantile(yb, 0.5);
  } else {
    t.change = t.sb.median / t.sa.median - 1.0;
    t.ci = median_ratio_interval(t.sa, t.sb);
    t.ma = t.sa.median;
    t.mb = t.sb.median;
  }
  return t;
}

// The passes that trace reflections: the direct pass, or the compacted path's compaction, sort and consume.
bool reflection_work(const std::string& pass) {
  return pass == "reflections" || pass == "compact" || pass == "consume" || pass.starts_with("sort");
}
constexpr const char* kReflectionWork = "reflection work";

std::vector<TimeComparison> time_comparisons(const std::vector<CellResult>& cells) {
  std::vector<TimeComparison> out;
  for (const std::string& axis : axes_of(cells))
    for (const CellPair& cp : axis_pairs(cells, axis)) {
      const PassSamples fa = pass_samples(cp.a->timing), fb = pass_samples(cp.b->timing);
      for (const auto& [pass, frames_a] : fa) {
        if (!find_pass(fb, pass)) continue;
        const auto only = [&pass](const std::string& p) { return p == pass; };
        TimeComparison t =
            compare_series(cp, pass, summed_pass_series(cp.a->timing, only), summed_pass_series(cp.b->timing, only));
        t.identical_work = identical_work(*cp.a, *cp.b, pass);
        out.push_back(t);
      }
      // The direct and the compacted path trace reflections in different passes: their sums compare.
      const bool direct_a = find_pass(fa, "reflections") != nullptr, direct_b = find_pass(fb, "reflections") != nullptr;
      if (direct_a != direct_b && find_pass(direct_a ? fb : fa, "consume"))
        out.push_back(compare_series(cp, kReflectionWork, summed_pass_series(cp.a->timing, reflection_work),
                                     summed_pass_series(cp.b->timing, reflection_work)));
    }
  std::vector<double> raw;
  for (const TimeComparison& t : out) raw.push_back(t.p_raw);
  const std::vector<double> adj = holm_adjust(raw);
  for (size_t i = 0; i < out.size(); ++i) {
    out[i].p_holm = adj[i];
    out[i].verdict = time_verdict(out[i]);
  }
  return out;
}

std::string comparison(const CellResult& a, const CellResult& b, const std::string& axis,
                       const std::vector<TimeComparison>& family) {
  const std::string va = axis_value_text(a.axes[axis]), vb = axis_value_text(b.axes[axis]);
  const std::string leaf = axis_leaf(axis);
  const std::string others = others_text(a, axis);
  std::string head = "#### " + md::escape(va) + " → " + md::escape(vb) +
                     (others.empty() ? "" : " (" + md::escape(others) + ")") + "\n\n";

  std::string table =
      "| pass | " + md::escape(va) + " (ms) | " + md::escape(vb) +
      " (ms) | change [95% CI] | noise floor | p (Holm) | rays | nodes visited | triangles tested | verdict "
      "|\n|---|---|---|---|---|---|---|---|---|---|\n";
  std::vector<std::string> significant, same_work;
  std::string largest;
  double largest_abs = -1.0;
  for (const TimeComparison& t : family) {
    if (t.a != &a || t.b != &b || t.axis != axis) continue;
    const double ratio = t.ratio();
    auto counter_change = [&](const char* name) -> std::string {
      if (!has_pass(a.timing.counters, t.pass) || !has_pass(b.timing.counters, t.pass)) return "—";
      // Per frame, so cells with different frame counts compare.
      const double x = per_frame(a, t.pass, name), y = per_frame(b, t.pass, name);
      if (x == y) return "=";
      return x == 0 ? "new" : pct(y / x);
    };
    table += "| " + t.pass + " | " + ms(t.ma) + " | " + ms(t.mb) + " | " + pct(ratio) +
             (t.ci ? " [" + pct(1.0 + t.ci->first) + ", " + pct(1.0 + t.ci->second) + "]" : std::string()) + " | " +
             (t.by_rounds ? fmt("±%.1f%%", t.noise_floor * 100.0) : std::string("—")) + " | " + p_text(t.p_holm) +
             " | " + counter_change(counter::rays_cast) + " | " + counter_change(counter::nodes_visited) + " | " +
             counter_change(counter::triangles_tested) + " | " + t.verdict + " |\n";
    const std::string desc = t.pass + " " + fmt("%.1f%%", std::abs(ratio - 1.0) * 100.0) +
                             (ratio >= 1.0 ? " slower" : " faster") + " (" + ms(t.ma) + " → " + ms(t.mb) +
                             " ms, Holm p " + (t.p_holm < 0.001 ? "< 0.001" : "= " + p_text(t.p_holm)) + ")";
    if (t.verdict == "slower" || t.verdict == "faster") significant.push_back(desc);
    if (t.identical_work) same_work.push_back(t.pass);
    if (!t.identical_work && std::abs(ratio - 1.0) > largest_abs) {
      largest_abs = std::abs(ratio - 1.0);
      largest = desc;
    }
  }

  // Counter changes per frame, largest first.
  std::vector<std::pair<double, std::string>> counter_changes;
  const double fa = double(a.timing.timings.measured().size()), fb = double(b.timing.timings.measured().size());
  for (const auto& [pass, counters] : a.timing.counters.passes()) {
    for (const auto& [name, value] : counters) {
      const double x = double(value) / fa, y = double(b.timing.counters.get(pass, name)) / fb;
      if (x != y && x > 0) counter_changes.push_back({std::abs(y / x - 1.0), pass + " " + name + " " + pct(y / x)});
    }
  }
  std::sort(counter_changes.rbegin(), counter_changes.rend());
  // Cache tables, when both cells have them: L1 hits per pass.
  // Cache tables, when both cells have them: L1 hits per traced pass.
  std::string cache_part;
  const std::vector<CachePass> ca = cache_passes(a), cb = cache_passes(b);
  for (const CachePass& x : ca) {
    auto y = std::find_if(cb.begin(), cb.end(), [&](const CachePass& p) { return p.pass == x.pass; });
    if (y == cb.end() || x.l1_hits <= 0) continue;
    cache_part += (cache_part.empty() ? "" : ", ") + x.pass + " L1 hits " + pct(y->l1_hits / x.l1_hits) + " (" +
                  md::count(x.l1_hits) + " → " + md::count(y->l1_hits) + ")";
  }

  std::string sentence =
      "Changing " + leaf + " from " + va + " to " + vb + (others.empty() ? "" : " (with " + others + ")");
  if (!significant.empty()) {
    sentence += " made ";
    for (size_t i = 0; i < significant.size(); ++i)
      sentence += (i == 0 ? "" : i + 1 == significant.size() ? " and " : ", ") + significant[i];
  } else {
    sentence += " changed no pass time significantly (no Holm-adjusted p at or below 0.05)" +
                (largest.empty() ? "" : "; the largest change was " + largest);
  }
  if (!same_work.empty()) {
    sentence += "; " + md::list(same_work) +
                " did the same work in both cells (identical work counters and cache counts): no change";
  }
  if (!a.timing.counters.empty() || !b.timing.counters.empty()) {
    if (counter_changes.empty()) {
      sentence += "; the work counters were identical";
      if (driver_traversal(a) || driver_traversal(b)) {
        sentence += " (they do not count the driver's traversal, whose nodes and triangles are not visible)";
      }
    } else {
      sentence += "; the work per frame changed: ";
      for (size_t i = 0; i < counter_changes.size() && i < 3; ++i)
        sentence += (i ? ", " : "") + counter_changes[i].second;
      if (counter_changes.size() > 3) sentence += " (and " + std::to_string(counter_changes.size() - 3) + " more)";
    }
  }
  if (!cache_part.empty()) sentence += "; " + cache_part;
  return head + sentence + ".\n\n" + table + "\n";
}

// Compute BVH against the driver's ray tracing: cells equal but for traversal, as_order, as_layout and as_compaction,
// side by side per pass, with the rays per second, the build and the memory of each acceleration structure.
std::string traversal_section(const std::vector<CellResult>& cells) {
  if (std::none_of(cells.begin(), cells.end(), driver_traversal)) return "";
  std::map<std::string, std::vector<const CellResult*>> groups;
  std::vector<std::string> order;
  for (const CellResult& c : cells) {
    json key = c.config;
    for (const char* k : {"traversal", "as_order", "as_layout", "as_compaction"}) key.erase(k);
    const std::string k = key.dump();
    if (!groups.count(k)) order.push_back(k);
    groups[k].push_back(&c);
  }
  std::string s = "## Compute BVH against the driver's ray tracing\n\n";
  s += "Cells that differ only in who walks the rays: `compute` (hybridprof's BVH, walked by the compute "
       "shaders), `ray-query` (the driver's acceleration structure from the same compute shaders) and "
       "`pipeline` (a ray-tracing pipeline whose ray-generation shaders are the same sources). Times are medians "
       "with their 95% intervals; Mrays/s is the pass's rays per frame over its median time; the change is "
       "against the compute cell of the group. The compute BVH is built on the host (CPU wall time) and is 32 "
       "bytes a node; the driver's is built on the device (timestamps) and its size is the driver's. The "
       "driver's traversal is opaque: its node and triangle counts are not known, and a traced ray-query pass's "
       "cache tables hold the shaders' own accesses (G-buffer, shading, outputs) only.\n\n";
  for (const std::string& k : order) {
    const auto& g = groups[k];
    if (std::none_of(g.begin(), g.end(), [](const CellResult* c) { return driver_traversal(*c); })) continue;
    const CellResult* base = nullptr;
    for (const CellResult* c : g)
      if (!driver_traversal(*c)) base = c;
    s += "| traversal | pass | median (ms) | 95% CI | vs compute | Mrays/s | structure build (ms) | structure size "
         "(MiB) |\n|---|---|---|---|---|---|---|---|\n";
    for (const CellResult* c : g) {
      std::string label = traversal_of(*c);
      if (c->line.contains("accel")) {
        const json& a = c->line["accel"];
        const std::string layout = a.value("layout", std::string("flat"));
        label += " (" + (layout == "instances" ? std::string("instances") : a.value("order", std::string("?"))) +
                 (a.value("compacted", false) ? ", compacted" : "") + ")";
      }
      std::string build = "—", size = "—";
      if (c->line.contains("accel")) {
        const json& a = c->line["accel"];
        build = fmt("%.2f", a.value("build_ms", 0.0)) + (a.value("build_timed_on_device", false) ? "" : " (host)");
        size = fmt("%.2f", double(a.value("blas_bytes", uint64_t(0)) + a.value("tlas_bytes", uint64_t(0))) / 1048576.0);
      } else if (c->bvh.is_object()) {
        build = fmt("%.2f", num_or0(c->bvh, "build_ms")) + " (host)";
        size = fmt("%.2f", num_or0(c->bvh, "nodes") * 32.0 / 1048576.0);
      }
      const std::vector<PassStat> stats = pass_stats(*c);
      const std::vector<PassStat> base_stats = base ? pass_stats(*base) : std::vector<PassStat>{};
      bool first = true;
      for (const PassStat& p : stats) {
        if (p.pass != "shadows" && p.pass != "reflections" && p.pass != "consume") continue;
        std::string vs = "—";
        for (const PassStat& q : base_stats)
          if (q.pass == p.pass && c != base && q.summary.median > 0) vs = pct(p.summary.median / q.summary.median);
        std::string mrays = "—";
        if (has_pass(c->timing.counters, p.pass) && p.summary.median > 0) {
          const double rays = per_frame(*c, p.pass, counter::rays_cast);
          mrays = fmt("%.2f", rays / (p.summary.median / 1e9) / 1e6);
        }
        s += "| " + md::escape(first ? label : "") + " | " + p.pass + " | " + ms(p.summary.median) + " | " +
             ci_text(p.summary) + " | " + vs + " | " + mrays + " | " + (first ? build : "") + " | " +
             (first ? size : "") + " |\n";
        first = false;
      }
    }
    s += "\n";
  }
  return s;
}

// The cells the device could not run (OUT/unsupported.json), by name and reason: not failures, not results.
std::string unsupported_section(const json& unsupported) {
  if (!unsupported.is_array() || unsupported.empty()) return "";
  std::string s = "## Cells not run on this device\n\n";
  s += std::to_string(unsupported.size()) +
       " cell(s) of the matrix need what the device lacks; they have no results, and nothing above compares "
       "them:\n\n";
  for (const json& u : unsupported) {
    std::string axes;
    if (u.contains("axes") && u["axes"].is_object())
      for (const auto& [k, v] : u["axes"].items()) axes += (axes.empty() ? "" : ", ") + k + "=" + axis_value_text(v);
    s += "- `" + md::escape(u.value("id", std::string("?"))) + "` (" + md::escape(axes) +
         "): " + md::escape(u.value("reason", std::string("unsupported"))) + "\n";
  }
  return s + "\n";
}

void comparisons_section(const std::vector<CellResult>& cells, const std::vector<TimeComparison>& family,
                         std::string& s) {
  const std::vector<std::string> axes = axes_of(cells);
  s += "## Comparisons along each axis\n\n";
  if (axes.empty()) {
    s += "This run has no axes (a single scenario), so there is nothing to compare.\n\n";
    return;
  }
  s += "For each axis and each pair of its values, cells whose other axes are equal are compared. ";
  const size_t by_rounds =
      size_t(std::count_if(family.begin(), family.end(), [](const TimeComparison& t) { return t.by_rounds; }));
  if (by_rounds > 0) {
    s += "Cells measured in interleaved rounds are compared by their round medians (one sample per round and "
         "cell: the frames of one round are not independent of each other). Cells measured in as many rounds "
         "pair up round by round (both cells ran in each round, close in time): the change is the Hodges-Lehmann "
         "estimate of the pairs' ratio with its distribution-free 95% interval, and p a two-sided Wilcoxon "
         "signed-rank test over the pairs; otherwise the Hodges-Lehmann ratio of the two sets of round medians "
         "and a Mann-Whitney U test. The times shown are the medians of the round medians. The noise floor is "
         "an A/A measured in the same run: the change between the odd and the even rounds of the same cell (the "
         "larger of the two cells'); a change inside it is \"no change\", whatever p says. ";
  }
  if (by_rounds < family.size()) {
    s += std::string(by_rounds > 0 ? "Cells of one round"
                                   : "These cells were measured in one round each, one after "
                                     "another, so a drift of the machine between them reads "
                                     "as a change and no noise floor is measured. They") +
         " are compared by their frames: change is the ratio of the medians with the interval from the two "
         "medians' intervals, p a two-sided Mann-Whitney U test over the frames. ";
  }
  s +=
      "p is Holm-adjusted over all " + std::to_string(family.size()) +
      " pass-time comparisons of this report (tied samples use the normal approximation). Verdict: a pass whose "
      "work counters and simulated cache counts are identical in both cells is \"no change\" whatever its time "
      "did; \"inconclusive\" when a cell is stale (measured by another build, kept by `run --reuse-stale`) or the "
      "samples are too few for any p to reach 0.05 (fewer than 4 untied samples "
      "a side, or 6 pairs); otherwise \"slower\" or \"faster\" when the adjusted p is at most 0.05 in the direction the "
      "samples moved and the change is outside the noise floor (by rounds: its whole interval), \"inconclusive\" "
      "when such a change's interval reaches into the floor, else \"no change\". The same verdicts are in "
      "findings.json. Counter changes are per frame; \"=\" means identical.\n\n";
  for (const std::string& axis : axes) {
    s += "### `" + axis + "`\n\n";
    const std::vector<CellPair> pairs = axis_pairs(cells, axis);
    for (const CellPair& p : pairs) s += comparison(*p.a, *p.b, axis, family);
    if (pairs.empty()) s += "No two cells differ in this axis alone.\n\n";
    const bool have_cache =
        std::any_of(cells.begin(), cells.end(), [](const CellResult& c) { return !cache_passes(c).empty(); });
    const std::string note = study::comparison_note(axis_leaf(axis), have_cache);
    if (!note.empty()) s += note + "\n";
  }
}

// The study's questions, answered first: each of its comparisons this run's cells make, in the study's
// direction, with our verdicts for time and the reflection pass's cache counts, the study's figure in the
// same direction and whether the two agree.
struct StudyQuestion {
  const char* axis_leaf;
  const char *from, *to;  ///< axis values, in the study's direction
  const char* title;
};
constexpr StudyQuestion kQuestions[] = {
    {"geometry", "soup", "indexed", "Index buffer (EBO) against de-indexed triangles: `geometry` soup → indexed"},
    {"jitter", "per-thread", "shared",
     "One shared jitter offset against per-thread jitter: `jitter` per-thread → shared"},
    {"reflection_path", "direct", "compact",
     "Compacted (sorted) rays against the direct pass: `reflection_path` direct → compact"},
};

std::string agreement(std::optional<double> ours, std::optional<double> theirs, const std::string& why_not) {
  if (!theirs || !ours) return "not comparable: " + why_not;
  if (*ours == 0.0) return "disagrees: no change here";
  return (*ours > 0) == (*theirs > 0) ? "agrees" : "disagrees";
}

// A verdict read in the other direction.
std::string reversed(const std::string& v) { return v == "slower" ? "faster" : v == "faster" ? "slower" : v; }

std::string study_questions_section(const std::vector<CellResult>& cells, const std::vector<TimeComparison>& family) {
  std::string body;
  for (const StudyQuestion& q : kQuestions) {
    std::string axis;
    for (const std::string& a : axes_of(cells))
      if (axis_leaf(a) == q.axis_leaf) axis = a;
    if (axis.empty()) continue;
    std::string rows;
    for (const CellPair& cp : axis_pairs(cells, axis)) {
      const json va = cp.a->axes[axis], vb = cp.b->axes[axis];
      const bool forward = va == q.from && vb == q.to;
      if (!forward && !(va == q.to && vb == q.from)) continue;
      const CellResult& from = forward ? *cp.a : *cp.b;
      const CellResult& to = forward ? *cp.b : *cp.a;
      std::string context = others_text(from, axis);
      context = context.empty() ? "—" : md::escape(context);
      const bool sorting = std::string(q.axis_leaf) == "reflection_path";
      const std::string pass = sorting ? kReflectionWork : "reflections";
      // Time: our verdict in the study's direction.
      auto t = std::find_if(family.begin(), family.end(), [&](const TimeComparison& c) {
        return c.a == cp.a && c.b == cp.b && c.axis == axis && c.pass == pass;
      });
      if (t != family.end()) {
        const double change = forward ? t->change : 1.0 / (1.0 + t->change) - 1.0;
        const std::string verdict = forward ? t->verdict : reversed(t->verdict);
        std::string study_time = "no time given", agree = "not comparable: the study gives no time for this comparison";
        if (sorting) {
          study_time = "slower: \"worse than the classic one\" (sorting " + fmt("%.2f", study::kSortingMs) +
                       " ms + traversal " + fmt("%.2f", study::kSortedTraversalMs) + " ms)";
          agree = verdict == "slower"         ? "agrees"
                  : verdict == "faster"       ? "disagrees"
                  : verdict == "inconclusive" ? "not comparable: too few samples here"
                                              : "disagrees: no change measured here";
        }
        rows += "| " + context + " | " + pass + " time | " + ms(forward ? t->ma : t->mb) + " → " +
                ms(forward ? t->mb : t->ma) + " ms | " + pct(1.0 + change) + " | " + verdict + " | " + study_time +
                " | " + agree + " |\n";
      }
      // Cache counts of the reflection pass, against Table 1 in the same context.
      const auto find_cache = [](const CellResult& c) -> std::optional<CachePass> {
        for (const CachePass& p : cache_passes(c))
          if (p.pass == "reflections") return p;
        return std::nullopt;
      };
      const std::optional<CachePass> ca = find_cache(from), cb = find_cache(to);
      const auto jitter_shared = [](const CellResult& c) { return c.config.value("jitter", "per-thread") == "shared"; };
      const auto indexed = [](const CellResult& c) { return c.config.value("geometry", "indexed") == "indexed"; };
      std::optional<study::Table1Row> sa, sb;
      if (!sorting) {
        sa = study::table1(jitter_shared(from), indexed(from));
        sb = study::table1(jitter_shared(to), indexed(to));
      }
      struct Metric {
        const char* name;
        double (*count)(double hits, double misses);
        bool rate, lane;  ///< lane: L1 hits counted per lane (the study's units), where the tables have them
      };
      const Metric metrics[] = {{"L1 hits", [](double h, double) { return h; }, false, false},
                                {"L1 hit rate", [](double h, double m) { return h / (h + m); }, true, false},
                                {"L1 hits per lane", [](double h, double) { return h; }, false, true},
                                {"L1 hit rate per lane", [](double h, double m) { return h / (h + m); }, true, true},
                                {"L2 hits", [](double h, double) { return h; }, false, false},
                                {"L2 hit rate", [](double h, double m) { return h / (h + m); }, true, false}};
      for (const Metric& mt : metrics) {
        const bool l1 = std::string(mt.name).starts_with("L1");
        if (mt.lane && !(ca && cb && ca->l1_lane_hits && cb->l1_lane_hits)) continue;
        const auto hits = [&](const CachePass& c) { return mt.lane ? *c.l1_lane_hits : l1 ? c.l1_hits : c.l2_hits; };
        std::optional<double> x, y, ours, theirs;
        if (ca && cb) {
          x = mt.count(hits(*ca), l1 ? ca->l1_misses : ca->l2_misses);
          y = mt.count(hits(*cb), l1 ? cb->l1_misses : cb->l2_misses);
          ours = mt.rate ? *y - *x : (*x > 0 ? *y / *x - 1.0 : 0.0);
        }
        std::string study_text = "—";
        if (sa && sb) {
          const double sx = mt.count(l1 ? sa->l1_hit : sa->l2_hit, l1 ? sa->l1_miss : sa->l2_miss);
          const double sy = mt.count(l1 ? sb->l1_hit : sb->l2_hit, l1 ? sb->l1_miss : sb->l2_miss);
          theirs = mt.rate ? sy - sx : sy / sx - 1.0;
          study_text = mt.rate ? fmt("%.1f%%", 100 * sx) + " → " + fmt("%.1f%%", 100 * sy) + " (" +
                                     fmt("%+.1f pp", 100 * *theirs) + ", " + sa->label + " → " + sb->label + ")"
                               : md::count(sx) + " → " + md::count(sy) + " (" + pct(1.0 + *theirs) + ", " + sa->label +
                                     " → " + sb->label + ")";
        }
        const std::string why = sorting ? "the study's counts of the compacted passes come from another configuration "
                                          "than its direct pass (no Table 1 row)"
                                        : "this run's cells carry no cache tables of the reflection pass";
        const std::string ours_text = !ours ? std::string("—")
                                            : (mt.rate ? fmt("%.1f%%", 100 * *x) + " → " + fmt("%.1f%%", 100 * *y)
                                                       : md::count(*x) + " → " + md::count(*y));
        const std::string change_text = !ours     ? std::string("—")
                                        : mt.rate ? fmt("%+.1f pp", 100 * *ours)
                                                  : pct(1.0 + *ours);
        const std::string verdict = !ours ? std::string("—") : *ours > 0 ? "higher" : *ours < 0 ? "lower" : "same";
        rows += "| " + context + " | " + mt.name + " | " + ours_text + " | " + change_text + " | " + verdict + " | " +
                study_text + " | " + agreement(ours, theirs, why) + " |\n";
      }
    }
    if (rows.empty()) continue;
    body += "### " + std::string(q.title) +
            "\n\n| with | metric | ours | change | verdict | study, same direction | "
            "agreement |\n|---|---|---|---|---|---|---|\n" +
            rows + "\n";
  }
  if (body.empty()) return "";
  return "## The study's questions\n\nEach comparison the study made (Santoro 2020: Unity + PIX on a Vega 56) that "
         "this run's cells also make, read in the study's direction. Time verdicts are this report's (see "
         "\"Comparisons along each axis\"); cache counts are the simulated reflection pass's, deterministic, so "
         "their verdict is the sign of the change. \"Agrees\" means the change goes the same way as the study's; "
         "the sizes are not expected to match (another scene, our cache model). L1 hits are counted per coalesced "
         "request (the model's default) and, where the tables have them, per lane: the unit of the study's "
         "hardware counter, whose hit counts and rates only the per-lane counting reaches (docs/cache-model.md). "
         "Misses are the same in both countings.\n\n" +
         body;
}

// findings.json: the verdicts of the comparisons section, for scripts and CI bots.
json findings(const std::vector<TimeComparison>& family) {
  json list = json::array();
  for (const TimeComparison& t : family) {
    json fixed = t.a->axes;
    fixed.erase(t.axis);
    json e = {{"axis", t.axis},
              {"from", t.a->axes[t.axis]},
              {"to", t.b->axes[t.axis]},
              {"fixed", fixed},
              {"pass", t.pass},
              {"metric", "time_ms"},
              {"baseline", t.ma / 1e6},
              {"candidate", t.mb / 1e6},
              {"change", t.ratio() - 1.0},
              {"ci", nullptr},
              {"p_holm", t.p_holm},
              {"samples", t.paired      ? "paired round medians"
                          : t.by_rounds ? "round medians"
                                        : "frames"},
              {"n", {t.na, t.nb}},
              {"noise_floor", t.by_rounds ? json(t.noise_floor) : json(nullptr)},
              {"exact_test", t.exact},
              {"identical_work", t.identical_work},
              {"verdict", t.verdict}};
    if (t.ci) e["ci"] = {t.ci->first, t.ci->second};
    list.push_back(std::move(e));
  }
  return {{"alpha", kAlpha}, {"correction", "holm"}, {"comparisons", std::move(list)}};
}

}  // namespace

Report build_report(const std::vector<CellResult>& cells, const json& unsupported) {
  if (cells.empty()) throw InputError("report: no cells");
  Report r;
  std::string& s = r.markdown;
  const std::string matrix = cells.front().matrix.empty() ? cells.front().name : cells.front().matrix;
  s += "# hybridprof report: " + md::escape(matrix) + "\n\n";
  s += std::to_string(cells.size()) +
       " cell(s) from `results.jsonl`. Pass times are in milliseconds: the median "
       "over the measured frames with its distribution-free 95% confidence interval (order statistics; none "
       "below 6 frames), and the coefficient of variation (CV = standard deviation / mean) of the frames.\n\n";
  const std::vector<TimeComparison> family = time_comparisons(cells);
  s += study_questions_section(cells, family);
  s += environment_section(cells) + "\n";
  charts_section(cells, r, s);
  s += error_metrics_section(cells);
  s += tradeoff_sections(cells, r.charts);
  s += traversal_section(cells);
  s += unsupported_section(unsupported);
  s += "## Cells\n\n";
  for (const CellResult& c : cells) s += cell_section(c, r.charts);
  r.findings = findings(family).dump(1) + "\n";
  comparisons_section(cells, family, s);
  s += "## Cache simulation\n\n";
  const size_t with_cache =
      size_t(std::count_if(cells.begin(), cells.end(), [](const CellResult& c) { return !cache_passes(c).empty(); }));
  if (with_cache == 0) {
    s += "No cell carries cache-simulator tables: the scenario traced no pass. Add `\"trace\": {\"passes\": "
         "[\"reflections\"]}` to a scenario and each cell gets a `cache` object (one traced frame replayed through "
         "the preset's caches); the L1/L2 table in the study's form, the per-buffer breakdown, the miss heatmaps, "
         "the miss-ratio curves and the L1-hit changes in the comparisons then appear without any other change.\n";
  } else {
    s += std::to_string(with_cache) + " of " + std::to_string(cells.size()) +
         " cells carry cache tables; they are shown in each cell's section, and their L1-hit changes in the "
         "comparisons. Miss-ratio curves (fully associative LRU, exact by stack distance):\n\n";
    for (const ReportFile& f : r.charts)
      if (f.path.starts_with("charts/mrc_")) s += "![miss-ratio curve](" + f.path + ")\n\n";
  }
  return r;
}

// Charts of an earlier report that this one no longer draws (another matrix, fewer axes, a scene gone)
// would otherwise lie beside report.md as if current. Only the report's own kind of file goes: `.svg` files
// directly in charts/; anything else there (PNGs rendered from them, notes) is left alone.
namespace {
void remove_stale_charts(const fs::path& charts_dir, const std::vector<ReportFile>& charts) {
  std::set<std::string> current;
  for (const ReportFile& f : charts) current.insert(fs::path(f.path).filename().string());
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(charts_dir, ec)) {
    if (!e.is_regular_file() || e.path().extension() != ".svg") continue;
    if (!current.contains(e.path().filename().string())) fs::remove(e.path(), ec);
  }
}
}  // namespace

std::string write_report(const std::string& out_dir) {
  json unsupported = json::array();
  const fs::path unsupported_file = fs::path(out_dir) / "unsupported.json";
  if (fs::exists(unsupported_file)) {
    std::ifstream in(unsupported_file);
    unsupported = json::parse(in, nullptr, false);
    if (unsupported.is_discarded() || !unsupported.is_array()) {
      throw InputError(unsupported_file.string() + ": not a JSON list (hybridprof run writes it)");
    }
  }
  const Report r = build_report(load_cells(out_dir), unsupported);
  std::error_code ec;
  fs::create_directories(fs::path(out_dir) / "charts", ec);
  if (ec) throw InputError(out_dir + "/charts: cannot create: " + ec.message());
  for (const ReportFile& f : r.charts) write_file_atomically((fs::path(out_dir) / f.path).string(), f.content);
  write_file_atomically(fs::path(out_dir) / "findings.json", r.findings);
  const std::string path = (fs::path(out_dir) / "report.md").string();
  write_file_atomically(path, r.markdown);
  remove_stale_charts(fs::path(out_dir) / "charts", r.charts);
  return path;
}

}  // namespace hp
