#include "cache_sampling.hpp"

#include "markdown.hpp"
#include "svg_chart.hpp"
#include "tradeoff.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

namespace hp {

using json = nlohmann::json;

namespace {

std::string fmt(const char* f, double v) { return format_number(f, v); }

std::optional<double> sample_every(const CellResult& c) {
  if (!c.config.is_object() || !c.config.contains("trace") || !c.config["trace"].is_object()) return std::nullopt;
  return number_at(c.config["trace"], "sample_every");
}

struct LevelRates {
  std::optional<double> l1, l2;
  std::map<std::string, double> buffer_l1;
};
std::optional<double> hit_rate(const json& level) {
  const auto h = number_at(level, "hits"), m = number_at(level, "misses");
  if (h && m && *h + *m > 0) return *h / (*h + *m);
  return number_at(level, "hit_rate");
}
std::map<std::string, LevelRates> cache_rates(const CellResult& c) {
  std::map<std::string, LevelRates> out;
  if (!c.cache.is_object() || !c.cache.contains("passes") || !c.cache["passes"].is_array()) return out;
  for (const json& p : c.cache["passes"]) {
    if (!p.is_object() || !p.contains("pass") || !p["pass"].is_string()) continue;
    LevelRates r;
    if (p.contains("l1")) r.l1 = hit_rate(p["l1"]);
    if (p.contains("l2")) r.l2 = hit_rate(p["l2"]);
    if (p.contains("buffers") && p["buffers"].is_object()) {
      for (const auto& [name, b] : p["buffers"].items()) {
        const auto req = number_at(b, "l1_requests"), miss = number_at(b, "l1_misses");
        if (req && miss && *req > 0) r.buffer_l1[name] = (*req - *miss) / *req;
      }
    }
    out[p["pass"].get<std::string>()] = r;
  }
  return out;
}

// A full-trace cell and its sampled partners (one group per burst length and model).
struct Group {
  const CellResult* full;
  double block;
  std::string key;  // the sampled cells' configuration without k
  std::vector<std::pair<double, const CellResult*>> sampled;
};

struct Groups {
  std::vector<Group> groups;
  std::vector<std::string> orphans;      ///< sampled cells without a full-trace partner
  std::vector<const CellResult*> cells;  ///< every cell of every group
  std::vector<std::string> pass_order;   ///< the traced passes, in the order they first appear
};

// The burst length (trace.sample_block) does not matter for a full trace (k = 1): any full cell partners
// every burst length, and each burst length is a group of its own.
Groups group_cells(const std::vector<CellResult>& cells) {
  const std::vector<std::string> key_ignore = {"/trace/sample_every", "/trace/sample_block", "/trace/scale_model"};
  std::vector<const CellResult*> traced;
  for (const CellResult& c : cells)
    if (c.cache.is_object()) traced.push_back(&c);
  std::map<std::string, const CellResult*> full;
  for (const CellResult* c : traced)
    if (sample_every(*c).value_or(1.0) == 1.0 && !full.count(match_key_ignoring(*c, key_ignore)))
      full[match_key_ignoring(*c, key_ignore)] = c;
  Groups out;
  std::vector<Group>& groups = out.groups;
  for (const CellResult* c : traced) {
    const double k = sample_every(*c).value_or(1.0);
    if (k <= 1.0) continue;
    const auto it = full.find(match_key_ignoring(*c, key_ignore));
    if (it == full.end()) {
      out.orphans.push_back(cell_label(*c) + " (sample_every " + md::general(k) + ")");
      continue;
    }
    const double block = number_at(c->config["trace"], "sample_block").value_or(1.0);
    const std::string key = match_key_ignoring(*c, {"/trace/sample_every"});
    auto g = std::find_if(groups.begin(), groups.end(),
                          [&](const Group& x) { return x.full == it->second && x.key == key; });
    if (g == groups.end()) {
      groups.push_back({it->second, block, key, {}});
      g = groups.end() - 1;
    }
    g->sampled.push_back({k, c});
  }
  for (const Group& g : groups) {
    out.cells.push_back(g.full);
    for (const auto& [k, c] : g.sampled) out.cells.push_back(c);
  }
  for (Group& g : groups)
    std::stable_sort(g.sampled.begin(), g.sampled.end(), [](auto& a, auto& b) { return a.first < b.first; });
  for (const Group& g : groups)
    for (const auto& [k, c] : g.sampled)
      for (const auto& [pass, r] : cache_rates(*c))
        if (std::find(out.pass_order.begin(), out.pass_order.end(), pass) == out.pass_order.end())
          out.pass_order.push_back(pass);
  return out;
}

// |a - b| in percentage points.
std::optional<double> pp(const std::optional<double>& a, const std::optional<double>& b) {
  if (!a || !b) return std::nullopt;
  return std::abs(*a - *b) * 100.0;
}

std::string group_label(const Group& g, const Groups& all) {
  std::string label = g.sampled.empty()
                          ? std::string()
                          : varying_label(*g.sampled.front().second, all.cells, {"sample_every", "sample_block"});
  return (label.empty() || label == g.full->name ? "" : label + ", ") + "bursts of " + md::general(g.block) +
         (g.block == 1.0 ? " workgroup" : " workgroups");
}

// One table per traced pass: each group's full trace, then its sampled cells with their errors; the
// errors also go to `chart` (exact zeros, which a log axis cannot show, are counted in `zero_points`).
std::string pass_tables(const Groups& all, svg::LineChart& chart, size_t& zero_points) {
  auto pct = [](const std::optional<double>& r) { return r ? fmt("%.2f%%", *r * 100.0) : std::string("—"); };
  auto ppt = [](const std::optional<double>& e) { return e ? fmt("%.3f", *e) : std::string("—"); };
  std::string s;
  for (const std::string& pass : all.pass_order) {
    s += "#### " + md::escape(pass) +
         "\n\n| cell | k | L1 hit rate | L1 \\|error\\| (pp) | L2 hit rate | L2 \\|error\\| (pp) | "
         "max per-buffer L1 \\|error\\| (pp) | simulation (s) | speed-up |\n|---|---|---|---|---|---|---|---|---|\n";
    for (const Group& g : all.groups) {
      const auto fr = cache_rates(*g.full);
      const auto fp = fr.find(pass);
      if (fp == fr.end()) continue;
      const std::string label = group_label(g, all);
      const auto full_sim = number_at(g.full->cache, "simulation_s");
      s += "| " + md::escape(label) + " | 1 | " + pct(fp->second.l1) + " | — | " + pct(fp->second.l2) + " | — | — | " +
           (full_sim ? fmt("%.2f", *full_sim) : "—") + " | 1× |\n";
      svg::Line l1{pass + " L1" + (all.groups.size() > 1 ? " (" + label + ")" : ""), {}, {}, {}, {}};
      svg::Line l2{pass + " L2" + (all.groups.size() > 1 ? " (" + label + ")" : ""), {}, {}, {}, {}};
      for (const auto& [k, c] : g.sampled) {
        const auto sr = cache_rates(*c);
        const auto sp = sr.find(pass);
        if (sp == sr.end()) continue;
        const auto e1 = pp(sp->second.l1, fp->second.l1), e2 = pp(sp->second.l2, fp->second.l2);
        std::optional<double> emax;
        for (const auto& [buf, rate] : sp->second.buffer_l1) {
          const auto f = fp->second.buffer_l1.find(buf);
          if (f == fp->second.buffer_l1.end()) continue;
          emax = std::max(emax.value_or(0.0), std::abs(rate - f->second) * 100.0);
        }
        const auto sim = number_at(c->cache, "simulation_s");
        s += "| " + md::escape(label) + " | " + md::general(k) + " | " + pct(sp->second.l1) + " | " + ppt(e1) + " | " +
             pct(sp->second.l2) + " | " + ppt(e2) + " | " + ppt(emax) + " | " + (sim ? fmt("%.2f", *sim) : "—") +
             " | " + (sim && full_sim && *sim > 0 ? fmt("%.1f", *full_sim / *sim) + "×" : "—") + " |\n";
        for (auto [line, e] : {std::pair{&l1, e1}, std::pair{&l2, e2}}) {
          if (!e) continue;
          if (*e <= 0) {
            ++zero_points;
            continue;
          }
          line->x.push_back(k);
          line->y.push_back(*e);
        }
      }
      for (svg::Line* l : {&l1, &l2})
        if (!l->x.empty()) chart.lines.push_back(*l);
    }
    s += "\n";
  }
  return s;
}

// Speed against error: each cell's simulator time against its mean |hit-rate error| (L1 and L2 over every
// traced pass; the full trace at 0), with the Pareto front.
std::string time_against_error(const Groups& all, std::vector<ReportFile>& charts) {
  struct Summary {
    std::string label;
    double sim, err;
  };
  std::vector<Summary> sums;
  for (const Group& g : all.groups) {
    const auto full_sim = number_at(g.full->cache, "simulation_s");
    if (full_sim &&
        std::none_of(sums.begin(), sums.end(), [&](const Summary& x) { return x.err == 0.0 && x.sim == *full_sim; })) {
      sums.push_back({"full trace", *full_sim, 0.0});
    }
    const auto fr = cache_rates(*g.full);
    for (const auto& [k, c] : g.sampled) {
      const auto sim = number_at(c->cache, "simulation_s");
      if (!sim) continue;
      double total = 0.0;
      int n = 0;
      for (const auto& [pass, r] : cache_rates(*c)) {
        const auto f = fr.find(pass);
        if (f == fr.end()) continue;
        for (const auto& e : {pp(r.l1, f->second.l1), pp(r.l2, f->second.l2)}) {
          if (e) total += *e, ++n;
        }
      }
      if (n == 0) continue;
      // The other axes that differ between the compared cells (e.g. scale_model), if any.
      std::string other;
      for (const auto& [axis, v] : c->axes.items()) {
        const std::string leaf = axis_leaf(axis);
        if (leaf == "sample_every" || leaf == "sample_block") continue;
        const bool varies = std::any_of(all.cells.begin(), all.cells.end(), [&](const CellResult* o) {
          return !o->axes.contains(axis) || o->axes[axis] != v;
        });
        if (varies) other += ", " + leaf + "=" + axis_value_text(v);
      }
      sums.push_back({"k=" + md::general(k) + ", bursts of " + md::general(g.block) + other, *sim, total / n});
    }
  }
  if (sums.size() <= 1) return "";
  std::vector<std::pair<double, double>> pts;
  for (const Summary& x : sums) pts.emplace_back(x.sim, x.err);
  const std::vector<bool> front = pareto_front(pts);
  std::vector<size_t> order(sums.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return sums[a].sim < sums[b].sim; });
  svg::ScatterChart sc;
  sc.title = "Cache simulation: simulator time against the error of the sampled hit rates";
  // Sampling rates spread the simulator's time over decades: a log time axis keeps the fast cells apart.
  sc.log_x = std::all_of(sums.begin(), sums.end(), [](const Summary& x) { return x.sim > 0; });
  sc.x_label = sc.log_x ? "simulator wall time, s (log)" : "simulator wall time, s";
  sc.y_label = "mean |hit-rate error| over passes and levels, pp";
  std::string s =
      "Time against error: the simulator's wall time against the mean |hit-rate error| (L1 and L2 of every traced pass, "
      "percentage points); the Pareto front (both lower is better) is marked.\n\n"
      "| # | sampling | simulation (s) | mean \\|error\\| (pp) | Pareto |\n|---|---|---|---|---|\n";
  // The chart labels each point by its row number: whole names beside the points overlap.
  int number = 0;
  for (size_t i : order) {
    const std::string tag = std::to_string(++number);
    s += "| " + tag + " | " + md::escape(sums[i].label) + " | " + fmt("%.3f", sums[i].sim) + " | " +
         fmt("%.3f", sums[i].err) + " | " + (front[i] ? "**yes**" : "no") + " |\n";
    sc.points.push_back(
        {sums[i].sim, sums[i].err, tag,
         tag + ": " + sums[i].label + ", " + fmt("%.3f", sums[i].sim) + " s, " + fmt("%.3f", sums[i].err) + " pp",
         bool(front[i])});
  }
  charts.push_back({"charts/cache_sampling_tradeoff.svg", svg::render(sc)});
  s += "\n![simulator time against hit-rate error](charts/cache_sampling_tradeoff.svg)\n\n";
  return s;
}

}  // namespace

std::string cache_sampling_section(const std::vector<CellResult>& cells, std::vector<ReportFile>& charts) {
  std::string s = "### Cache simulation on sampled traces\n\n";
  const Groups all = group_cells(cells);
  if (all.groups.empty() && all.orphans.empty()) {
    return s +
           "No traced cell samples its trace (`trace.sample_every` > 1), so there is nothing to compare with the full trace.\n\n";
  }
  s +=
      "Each traced cell with `trace.sample_every` k > 1 (the memory accesses of every k-th burst of `trace.sample_block` "
      "consecutive workgroups, in dispatch order, replayed through the caches) "
      "against the cell with the same configuration traced in full (k = 1). |error| is the absolute difference of the hit "
      "rates in percentage points; the per-buffer column is the largest such difference over the pass's buffers' L1 hit "
      "rates. Simulation time is the cache simulator's wall time for the cell (all traced passes); speed-up = full / sampled.\n\n";
  svg::LineChart chart;
  chart.title = "Hit-rate error of sampled cache traces against the full trace";
  chart.x_label = "sample_every k (log)";
  chart.y_label = "|hit rate error| (percentage points, log)";
  chart.log_x = chart.log_y = true;
  size_t zero_points = 0;
  s += pass_tables(all, chart, zero_points);
  if (!chart.lines.empty()) {
    charts.push_back({"charts/cache_sampling.svg", svg::render(chart)});
    s += "![hit-rate error against sample_every](charts/cache_sampling.svg)\n\n";
    if (zero_points > 0)
      s += "(" + std::to_string(zero_points) + " exact point(s), |error| = 0, are not drawn on the log axis.)\n\n";
  } else if (!all.groups.empty()) {
    s += "Every sampled hit rate equals the full trace's (|error| = 0), so there is no log-scale chart.\n\n";
  }
  s += time_against_error(all, charts);
  if (!all.orphans.empty()) {
    s +=
        "Without a full-trace partner (no cell with the same configuration and `trace.sample_every` 1), so not compared: " +
        md::escape(md::list(all.orphans)) + ".\n\n";
  }
  return s;
}

}  // namespace hp
