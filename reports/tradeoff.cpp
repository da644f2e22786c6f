#include "tradeoff.hpp"

#include "error.hpp"
#include "svg_chart.hpp"
#include "timing/stats.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>

namespace hp {

using json = nlohmann::json;

namespace {

std::string fmt(const char* f, double v) { return format_number(f, v); }
std::string md_escape(const std::string& s) {
  std::string out;
  for (char c : s) out += c == '|' ? std::string("\\|") : std::string(1, c);
  return out;
}
std::string count_text(double v) {
  std::string s = fmt("%.0f", v), out;
  const size_t lead = s[0] == '-' ? 1 : 0;
  for (size_t i = 0; i < s.size(); ++i) {
    if (i > lead && (s.size() - i) % 3 == 0) out += ',';
    out += s[i];
  }
  return out;
}
// Counts with separators, other numbers to four significant digits.
std::string general(double v) {
  if (std::isfinite(v) && v == std::floor(v) && std::abs(v) < 1e15) return count_text(v);
  return fmt("%.4g", v);
}
std::string list_text(const std::vector<std::string>& items) {
  std::string s;
  for (size_t i = 0; i < items.size(); ++i) s += (i == 0 ? "" : i + 1 == items.size() ? " and " : ", ") + items[i];
  return s;
}
std::optional<double> number_at(const json& j, const char* key) {
  if (!j.is_object() || !j.contains(key) || !j[key].is_number()) return std::nullopt;
  return j[key].get<double>();
}

// A parsed metric name.
struct Metric {
  enum Kind { time, image_time, per_ray, pointer } kind = time;
  std::vector<std::string> passes;  // time, image_time: empty = every pass
  std::string pass, counter;        // per_ray
  json::json_pointer ptr;           // pointer
};

Metric parse_metric(const std::string& name, const std::string& context) {
  auto bad = [&](const std::string& why) { throw InputError(context + ": bad metric '" + name + "': " + why); };
  Metric m;
  auto pass_list = [&](const std::string& rest) {
    if (rest == "frame") return;
    size_t start = 0;
    while (true) {
      const size_t plus = rest.find('+', start);
      const std::string p = rest.substr(start, plus == std::string::npos ? std::string::npos : plus - start);
      if (p.empty()) bad("an empty pass name (expected <pass>[+<pass>...] or frame)");
      if (p == "frame") bad("'frame' already means every pass and cannot be summed with others");
      m.passes.push_back(p);
      if (plus == std::string::npos) break;
      start = plus + 1;
    }
  };
  if (name.starts_with("time:")) {
    m.kind = Metric::time;
    pass_list(name.substr(5));
  } else if (name.starts_with("image_time:")) {
    m.kind = Metric::image_time;
    pass_list(name.substr(11));
  } else if (name.starts_with("per_ray:")) {
    m.kind = Metric::per_ray;
    const std::string rest = name.substr(8);
    const size_t slash = rest.find('/');
    if (slash == std::string::npos || slash == 0 || slash + 1 == rest.size() || rest.find('/', slash + 1) != std::string::npos)
      bad("expected per_ray:<pass>/<counter>, e.g. per_ray:shadows/nodes_visited");
    m.pass = rest.substr(0, slash);
    m.counter = rest.substr(slash + 1);
  } else if (name.starts_with("/")) {
    m.kind = Metric::pointer;
    try {
      m.ptr = json::json_pointer(name);
    } catch (const json::exception& e) {
      bad(std::string("not a JSON pointer (") + e.what() + ")");
    }
  } else {
    bad("expected time:<passes>, image_time:<passes>, per_ray:<pass>/<counter> or a JSON pointer starting with '/'");
  }
  return m;
}

bool is_time_metric(const Metric& m) { return m.kind == Metric::time || m.kind == Metric::image_time; }

// Median and CI (ms) of the per-frame sum of these passes (all when empty); nullopt when the cell
// ran none of them, `why` says which is missing.
std::optional<MetricValue> time_value(const CellResult& c, const std::vector<std::string>& passes, std::string* why) {
  std::set<std::string> seen;
  std::vector<double> sums;
  for (const FrameSample& f : c.timing.timings.measured()) {
    double sum = 0;
    for (const PassSample& p : f.passes) {
      if (!passes.empty() && std::find(passes.begin(), passes.end(), p.pass) == passes.end()) continue;
      sum += double(p.duration_ns());
      seen.insert(p.pass);
    }
    sums.push_back(sum);
  }
  for (const std::string& p : passes) {
    if (!seen.count(p)) {
      if (why) *why = "no pass '" + p + "'";
      return std::nullopt;
    }
  }
  if (sums.empty() || seen.empty()) {
    if (why) *why = "no pass times";
    return std::nullopt;
  }
  const Summary s = summarize(sums);
  MetricValue v;
  v.value = s.median / 1e6;
  v.is_time = true;
  if (s.median_ci.valid) v.ci = std::make_pair(s.median_ci.low / 1e6, s.median_ci.high / 1e6);
  return v;
}

std::string value_text(const MetricValue& v, bool with_ci = true) {
  if (!v.is_time) return general(v.value);
  std::string s = fmt("%.3f", v.value);
  if (with_ci) s += v.ci ? " [" + fmt("%.3f", v.ci->first) + ", " + fmt("%.3f", v.ci->second) + "]" : " (no CI: n < 6)";
  return s;
}

// Every pass a time metric names must be one some cell ran: a typo would otherwise leave every cell
// "not available".
void check_passes_ran(const std::vector<CellResult>& cells, const Metric& m, const std::string& name, const std::string& context) {
  if (!is_time_metric(m)) return;
  for (const std::string& p : m.passes) {
    const bool ran = std::any_of(cells.begin(), cells.end(), [&](const CellResult& c) {
      for (const FrameSample& f : c.timing.timings.measured())
        for (const PassSample& s : f.passes)
          if (s.pass == p) return true;
      return false;
    });
    if (!ran) throw InputError(context + ": bad metric '" + name + "': no cell ran a pass named '" + p + "'");
  }
}

// The axes whose values differ among these cells, as "key=value, ..." (the cell's label when none differ).
std::string varying_label(const CellResult& c, const std::vector<const CellResult*>& among,
                          const std::vector<std::string>& skip_leaves = {}) {
  std::string s;
  for (const auto& [k, v] : c.axes.items()) {
    if (std::find(skip_leaves.begin(), skip_leaves.end(), axis_leaf(k)) != skip_leaves.end()) continue;
    const bool varies = std::any_of(among.begin(), among.end(), [&](const CellResult* o) {
      return !o->axes.contains(k) || o->axes[k] != v;
    });
    if (varies) s += (s.empty() ? "" : ", ") + axis_leaf(k) + "=" + axis_value_text(v);
  }
  if (!s.empty()) return s;
  if (skip_leaves.empty()) return cell_label(c);
  for (const auto& [k, v] : c.axes.items())
    if (std::find(skip_leaves.begin(), skip_leaves.end(), axis_leaf(k)) == skip_leaves.end())
      s += (s.empty() ? "" : ", ") + axis_leaf(k) + "=" + axis_value_text(v);
  return s.empty() ? (c.name.empty() ? c.id : c.name) : s;
}

std::string string_field(const json& o, const char* key, const std::string& fallback, const std::string& context) {
  if (!o.contains(key)) return fallback;
  if (!o[key].is_string()) throw InputError(context + ": '" + key + "' is not a string");
  return o[key].get<std::string>();
}
bool bool_field(const json& o, const char* key, const std::string& context) {
  if (!o.contains(key)) return false;
  if (!o[key].is_boolean()) throw InputError(context + ": '" + key + "' is not true or false");
  return o[key].get<bool>();
}

// ---- trade-offs ------------------------------------------------------------------------------

std::string tradeoff_section(const std::vector<CellResult>& cells, const json& spec, size_t n, std::vector<ReportFile>& charts) {
  std::string context = "report spec: tradeoffs[" + std::to_string(n - 1) + "]";
  if (!spec.is_object()) throw InputError(context + ": not an object");
  const std::string title = string_field(spec, "title", "Trade-off " + std::to_string(n), context);
  context += " \"" + title + "\"";
  for (const char* k : {"x", "y"})
    if (!spec.contains(k) || !spec[k].is_string()) throw InputError(context + ": '" + k + "' (a metric name) missing or not a string");
  const std::string xn = spec["x"].get<std::string>(), yn = spec["y"].get<std::string>();
  const std::string x_label = string_field(spec, "x_label", xn, context), y_label = string_field(spec, "y_label", yn, context);
  const bool log_x = bool_field(spec, "log_x", context), log_y = bool_field(spec, "log_y", context);
  std::vector<std::string> columns;
  if (spec.contains("columns")) {
    if (!spec["columns"].is_array()) throw InputError(context + ": 'columns' is not a list of metric names");
    for (const json& c : spec["columns"]) {
      if (!c.is_string()) throw InputError(context + ": 'columns' is not a list of metric names");
      columns.push_back(c.get<std::string>());
    }
  }
  for (const std::string& name : [&] {
         std::vector<std::string> all = {xn, yn};
         all.insert(all.end(), columns.begin(), columns.end());
         return all;
       }()) {
    check_passes_ran(cells, parse_metric(name, context), name, context);
  }

  struct Row {
    const CellResult* cell;
    MetricValue x, y;
    std::vector<std::optional<MetricValue>> extra;
    bool front = false;
  };
  std::vector<Row> rows;
  std::vector<std::string> skipped;
  for (const CellResult& c : cells) {
    std::string why_x, why_y;
    const auto x = resolve_metric(c, xn, context, &why_x);
    const auto y = resolve_metric(c, yn, context, &why_y);
    if (!x || !y) {
      skipped.push_back(cell_label(c) + " (" + (!x ? "`" + xn + "`: " + why_x : "`" + yn + "`: " + why_y) + ")");
      continue;
    }
    Row r{&c, *x, *y, {}};
    for (const std::string& col : columns) r.extra.push_back(resolve_metric(c, col, context));
    rows.push_back(r);
  }
  std::string s = "### " + md_escape(title) + "\n\n";
  s += "x: `" + xn + "` (" + md_escape(x_label) + "), y: `" + yn + "` (" + md_escape(y_label) + "); both lower is better.\n\n";
  if (rows.empty()) {
    s += "No cell has both values, so there is nothing to compare.";
    if (!skipped.empty()) s += " Not available: " + md_escape(list_text(skipped)) + ".";
    return s + "\n\n";
  }
  std::sort(rows.begin(), rows.end(), [](const Row& a, const Row& b) { return a.x.value != b.x.value ? a.x.value < b.x.value : a.y.value < b.y.value; });
  std::vector<std::pair<double, double>> pts;
  for (const Row& r : rows) pts.push_back({r.x.value, r.y.value});
  const std::vector<bool> front = pareto_front(pts);
  for (size_t i = 0; i < rows.size(); ++i) rows[i].front = front[i];

  std::vector<const CellResult*> among;
  for (const Row& r : rows) among.push_back(r.cell);

  // The chart, with the log axes asked for where every value allows one.
  std::vector<std::string> notes;
  svg::ScatterChart chart;
  chart.title = title;
  chart.x_label = x_label + (log_x ? " (log)" : "");
  chart.y_label = y_label + (log_y ? " (log)" : "");
  chart.log_x = log_x && std::all_of(rows.begin(), rows.end(), [](const Row& r) { return r.x.value > 0; });
  chart.log_y = log_y && std::all_of(rows.begin(), rows.end(), [](const Row& r) { return r.y.value > 0; });
  if (log_x && !chart.log_x) {
    chart.x_label = x_label;
    notes.push_back("The x axis is linear: a value is <= 0, which a log axis cannot show.");
  }
  if (log_y && !chart.log_y) {
    chart.y_label = y_label;
    notes.push_back("The y axis is linear: a value is <= 0, which a log axis cannot show.");
  }
  for (const Row& r : rows) {
    svg::ScatterPoint p;
    p.x = r.x.value;
    p.y = r.y.value;
    // Only the front is labelled (every point has its tooltip): labels on every point of a 24-cell sweep
    // overlap into an unreadable band.
    if (r.front) p.label = varying_label(*r.cell, among);
    p.tooltip = cell_label(*r.cell) + ": " + x_label + " " + value_text(r.x) + ", " + y_label + " " + value_text(r.y) +
                (r.front ? " (on the Pareto front)" : "");
    p.front = r.front;
    chart.points.push_back(p);
  }
  const std::string path = "charts/tradeoff_" + std::to_string(n) + ".svg";
  charts.push_back({path, svg::render(chart)});
  s += "![" + md_escape(title) + "](" + path + ")\n\n";

  // One sentence on the front.
  std::vector<std::string> on;
  for (const Row& r : rows)
    if (r.front) on.push_back(varying_label(*r.cell, among) + " (" + value_text(r.x, false) + ", " + value_text(r.y, false) + ")");
  const size_t n_front = on.size();
  if (rows.size() == 1) {
    s += "Only one cell has both values; it is trivially on the Pareto front.\n\n";
  } else if (n_front == rows.size()) {
    s += "Every cell is on the Pareto front (no cell is beaten on both " + x_label + " and " + y_label +
         " by another); in x order: " + list_text(on) + ".\n\n";
  } else {
    s += std::to_string(n_front) + " of " + std::to_string(rows.size()) +
         " cells are on the Pareto front (no other cell is at least as good in both " + x_label + " and " + y_label +
         " and better in one): " + list_text(on) + "; the other " + std::to_string(rows.size() - n_front) +
         " are dominated.\n\n";
  }

  s += "| cell | " + md_escape(x_label) + (rows.front().x.is_time ? " (ms, 95% CI)" : "") + " | " + md_escape(y_label) +
       (rows.front().y.is_time ? " (ms, 95% CI)" : "") + " |";
  for (const std::string& col : columns) s += " `" + md_escape(col) + "` |";
  s += " Pareto |\n|---|---|---|";
  for (size_t i = 0; i < columns.size(); ++i) s += "---|";
  s += "---|\n";
  for (const Row& r : rows) {
    s += "| " + md_escape(cell_label(*r.cell)) + " | " + value_text(r.x) + " | " + value_text(r.y) + " |";
    for (const auto& e : r.extra) {
      s += ' ';
      s += e ? value_text(*e) : std::string("—");
      s += " |";
    }
    s += std::string(" ") + (r.front ? "**yes**" : "no") + " |\n";
  }
  s += "\n";
  if (!skipped.empty()) notes.push_back("Not available, left out: " + list_text(skipped) + ".");
  if (std::any_of(rows.begin(), rows.end(), [](const Row& r) {
        return std::any_of(r.extra.begin(), r.extra.end(), [](const auto& e) { return !e.has_value(); });
      }))
    notes.push_back("— in a column: not available for that cell.");
  for (const std::string& note : notes) s += "*Note:* " + md_escape(note) + "\n\n";
  return s;
}

// ---- cache sampling --------------------------------------------------------------------------

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

std::string cache_sampling_section(const std::vector<CellResult>& cells, std::vector<ReportFile>& charts) {
  std::string s = "### Cache simulation on sampled traces\n\n";
  // The burst length (trace.sample_block) does not matter for a full trace (k = 1): any full cell partners
  // every burst length, and each burst length is a group of its own.
  const std::vector<std::string> key_ignore = {"/trace/sample_every", "/trace/sample_block", "/trace/scale_model"};
  std::vector<const CellResult*> traced;
  for (const CellResult& c : cells)
    if (c.cache.is_object()) traced.push_back(&c);
  std::map<std::string, const CellResult*> full;
  for (const CellResult* c : traced)
    if (sample_every(*c).value_or(1.0) == 1.0 && !full.count(match_key_ignoring(*c, key_ignore))) full[match_key_ignoring(*c, key_ignore)] = c;
  // Groups: a full-trace cell and its sampled partners, in the order the full cells appear.
  struct Group {
    const CellResult* full;
    double block;
    std::string key;  // the sampled cells' configuration without k: one group per burst length and model
    std::vector<std::pair<double, const CellResult*>> sampled;
  };
  std::vector<Group> groups;
  std::vector<std::string> orphans;
  for (const CellResult* c : traced) {
    const double k = sample_every(*c).value_or(1.0);
    if (k <= 1.0) continue;
    const auto it = full.find(match_key_ignoring(*c, key_ignore));
    if (it == full.end()) {
      orphans.push_back(cell_label(*c) + " (sample_every " + general(k) + ")");
      continue;
    }
    const double block = number_at(c->config["trace"], "sample_block").value_or(1.0);
    const std::string key = match_key_ignoring(*c, {"/trace/sample_every"});
    auto g = std::find_if(groups.begin(), groups.end(), [&](const Group& x) { return x.full == it->second && x.key == key; });
    if (g == groups.end()) {
      groups.push_back({it->second, block, key, {}});
      g = groups.end() - 1;
    }
    g->sampled.push_back({k, c});
  }
  if (groups.empty() && orphans.empty()) {
    return s + "No traced cell samples its trace (`trace.sample_every` > 1), so there is nothing to compare with the full trace.\n\n";
  }
  s += "Each traced cell with `trace.sample_every` k > 1 (the memory accesses of every k-th burst of `trace.sample_block` "
       "consecutive workgroups, in dispatch order, replayed through the caches) "
       "against the cell with the same configuration traced in full (k = 1). |error| is the absolute difference of the hit "
       "rates in percentage points; the per-buffer column is the largest such difference over the pass's buffers' L1 hit "
       "rates. Simulation time is the cache simulator's wall time for the cell (all traced passes); speed-up = full / sampled.\n\n";
  std::vector<const CellResult*> all_group_cells;
  for (const Group& g : groups) {
    all_group_cells.push_back(g.full);
    for (const auto& [k, c] : g.sampled) all_group_cells.push_back(c);
  }
  for (Group& g : groups) std::stable_sort(g.sampled.begin(), g.sampled.end(), [](auto& a, auto& b) { return a.first < b.first; });
  std::vector<std::string> pass_order;
  for (const Group& g : groups)
    for (const auto& [k, c] : g.sampled)
      for (const auto& [pass, r] : cache_rates(*c))
        if (std::find(pass_order.begin(), pass_order.end(), pass) == pass_order.end()) pass_order.push_back(pass);

  auto pp = [](const std::optional<double>& a, const std::optional<double>& b) -> std::optional<double> {
    if (!a || !b) return std::nullopt;
    return std::abs(*a - *b) * 100.0;
  };
  auto pct = [](const std::optional<double>& r) { return r ? fmt("%.2f%%", *r * 100.0) : std::string("—"); };
  auto ppt = [](const std::optional<double>& e) { return e ? fmt("%.3f", *e) : std::string("—"); };
  svg::LineChart chart;
  chart.title = "Hit-rate error of sampled cache traces against the full trace";
  chart.x_label = "sample_every k (log)";
  chart.y_label = "|hit rate error| (percentage points, log)";
  chart.log_x = chart.log_y = true;
  size_t zero_points = 0;
  for (const std::string& pass : pass_order) {
    s += "#### " + md_escape(pass) + "\n\n| cell | k | L1 hit rate | L1 \\|error\\| (pp) | L2 hit rate | L2 \\|error\\| (pp) | "
         "max per-buffer L1 \\|error\\| (pp) | simulation (s) | speed-up |\n|---|---|---|---|---|---|---|---|---|\n";
    for (const Group& g : groups) {
      const auto fr = cache_rates(*g.full);
      const auto fp = fr.find(pass);
      if (fp == fr.end()) continue;
      std::string group_label = g.sampled.empty() ? std::string()
                                : varying_label(*g.sampled.front().second, all_group_cells, {"sample_every", "sample_block"});
      group_label = (group_label.empty() || group_label == g.full->name ? "" : group_label + ", ") + "bursts of " +
                    general(g.block) + (g.block == 1.0 ? " workgroup" : " workgroups");
      const auto full_sim = number_at(g.full->cache, "simulation_s");
      s += "| " + md_escape(group_label) + " | 1 | " + pct(fp->second.l1) + " | — | " + pct(fp->second.l2) + " | — | — | " +
           (full_sim ? fmt("%.2f", *full_sim) : "—") + " | 1× |\n";
      svg::Line l1{pass + " L1" + (groups.size() > 1 ? " (" + group_label + ")" : ""), {}, {}, {}, {}};
      svg::Line l2{pass + " L2" + (groups.size() > 1 ? " (" + group_label + ")" : ""), {}, {}, {}, {}};
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
        s += "| " + md_escape(group_label) + " | " + general(k) + " | " + pct(sp->second.l1) + " | " + ppt(e1) + " | " +
             pct(sp->second.l2) + " | " + ppt(e2) + " | " + ppt(emax) + " | " + (sim ? fmt("%.2f", *sim) : "—") + " | " +
             (sim && full_sim && *sim > 0 ? fmt("%.1f", *full_sim / *sim) + "×" : "—") + " |\n";
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
  if (!chart.lines.empty()) {
    charts.push_back({"charts/cache_sampling.svg", svg::render(chart)});
    s += "![hit-rate error against sample_every](charts/cache_sampling.svg)\n\n";
    if (zero_points > 0)
      s += "(" + std::to_string(zero_points) + " exact point(s), |error| = 0, are not drawn on the log axis.)\n\n";
  } else if (!groups.empty()) {
    s += "Every sampled hit rate equals the full trace's (|error| = 0), so there is no log-scale chart.\n\n";
  }
  // Speed against error: each cell's simulator time against its mean |hit-rate error| (L1 and L2 over every
  // traced pass; the full trace at 0), with the Pareto front.
  struct Summary {
    std::string label;
    double sim, err;
  };
  std::vector<Summary> sums;
  for (const Group& g : groups) {
    const auto full_sim = number_at(g.full->cache, "simulation_s");
    if (full_sim && std::none_of(sums.begin(), sums.end(), [&](const Summary& x) { return x.err == 0.0 && x.sim == *full_sim; })) {
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
        const bool varies = std::any_of(all_group_cells.begin(), all_group_cells.end(), [&](const CellResult* o) {
          return !o->axes.contains(axis) || o->axes[axis] != v;
        });
        if (varies) other += ", " + leaf + "=" + axis_value_text(v);
      }
      sums.push_back({"k=" + general(k) + ", bursts of " + general(g.block) + other, *sim, total / n});
    }
  }
  if (sums.size() > 1) {
    std::vector<std::pair<double, double>> pts;
    for (const Summary& x : sums) pts.emplace_back(x.sim, x.err);
    const std::vector<bool> front = pareto_front(pts);
    std::vector<size_t> order(sums.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return sums[a].sim < sums[b].sim; });
    svg::ScatterChart sc;
    sc.title = "Cache simulation: simulator time against the error of the sampled hit rates";
    sc.x_label = "simulator wall time, s";
    sc.y_label = "mean |hit-rate error| over passes and levels, pp";
    s += "Time against error: the simulator's wall time against the mean |hit-rate error| (L1 and L2 of every traced pass, "
         "percentage points); the Pareto front (both lower is better) is marked.\n\n"
         "| sampling | simulation (s) | mean \\|error\\| (pp) | Pareto |\n|---|---|---|---|\n";
    for (size_t i : order) {
      s += "| " + md_escape(sums[i].label) + " | " + fmt("%.3f", sums[i].sim) + " | " + fmt("%.3f", sums[i].err) + " | " +
           (front[i] ? "**yes**" : "no") + " |\n";
      sc.points.push_back({sums[i].sim, sums[i].err, sums[i].label, "", bool(front[i])});
    }
    charts.push_back({"charts/cache_sampling_tradeoff.svg", svg::render(sc)});
    s += "\n![simulator time against hit-rate error](charts/cache_sampling_tradeoff.svg)\n\n";
  }
  if (!orphans.empty()) {
    s += "Without a full-trace partner (no cell with the same configuration and `trace.sample_every` 1), so not compared: " +
         md_escape(list_text(orphans)) + ".\n\n";
  }
  return s;
}

// ---- depth error -----------------------------------------------------------------------------

std::string depth_error_section(const std::vector<CellResult>& cells, std::vector<ReportFile>& charts) {
  std::string s = "### World-position reconstruction error by distance\n\n";
  std::vector<const CellResult*> with;
  std::vector<std::string> without;
  for (const CellResult& c : cells) {
    if (c.error.is_object() && c.error.contains("depth") && c.error["depth"].is_object()) with.push_back(&c);
    else without.push_back(cell_label(c));
  }
  if (with.empty()) return s + "No cell carries depth-error numbers (`error.depth`).\n\n";
  s += "|reconstructed − true world position| / true distance, from the depth buffer of each cell's depth mode; mean and "
       "max over the pixels with geometry, and the mean per distance bin (x: the bin's centre distance).\n\n";
  svg::LineChart chart;
  chart.title = "Mean relative position error by distance";
  chart.x_label = "distance from the camera (bin centre, log)";
  chart.y_label = "mean relative error (log)";
  chart.log_x = chart.log_y = true;
  s += "| cell | pixels | mean relative error | max relative error | bins |\n|---|---|---|---|---|\n";
  size_t dropped = 0;
  for (const CellResult* c : with) {
    const json& d = c->error["depth"];
    const auto px = number_at(d, "pixels"), mean = number_at(d, "mean_rel"), mx = number_at(d, "max_rel");
    const size_t nbins = d.contains("bins") && d["bins"].is_array() ? d["bins"].size() : 0;
    s += "| " + md_escape(cell_label(*c)) + " | " + (px ? count_text(*px) : "—") + " | " + (mean ? fmt("%.3g", *mean) : "—") +
         " | " + (mx ? fmt("%.3g", *mx) : "—") + " | " + std::to_string(nbins) + " |\n";
    svg::Line line{varying_label(*c, with), {}, {}, {}, {}};
    if (nbins) {
      for (const json& b : d["bins"]) {
        const auto nr = number_at(b, "near"), fr = number_at(b, "far"), m = number_at(b, "mean_rel"), n = number_at(b, "pixels");
        if (!nr || !fr || !m || (n && *n <= 0)) continue;
        const double x = (*nr + *fr) / 2;
        if (!(x > 0) || !(*m > 0)) {
          ++dropped;
          continue;
        }
        line.x.push_back(x);
        line.y.push_back(*m);
      }
    }
    if (!line.x.empty()) chart.lines.push_back(line);
  }
  s += "\n";
  if (!chart.lines.empty()) {
    charts.push_back({"charts/depth_error.svg", svg::render(chart)});
    s += "![mean relative position error by distance](charts/depth_error.svg)\n\n";
  }
  if (dropped) s += "(" + std::to_string(dropped) + " bin(s) with zero error are not drawn on the log axes.)\n\n";
  if (!without.empty()) s += "Without depth-error numbers: " + md_escape(list_text(without)) + ".\n\n";
  return s;
}

std::string distinct_numbers(const std::vector<CellResult>& cells, const char* key) {
  std::vector<std::string> values;
  for (const CellResult& c : cells) {
    if (!c.error.is_object() || !c.error.contains("image")) continue;
    if (const auto v = number_at(c.error["image"], key)) {
      const std::string t = fmt("%g", *v);
      if (std::find(values.begin(), values.end(), t) == values.end()) values.push_back(t);
    }
  }
  if (values.empty()) return "";
  std::string s;
  for (const std::string& v : values) s += (s.empty() ? "" : " / ") + v;
  return s;
}

}  // namespace

std::vector<bool> pareto_front(const std::vector<std::pair<double, double>>& pts) {
  std::vector<bool> front(pts.size(), false);
  for (size_t i = 0; i < pts.size(); ++i) {
    const auto [xi, yi] = pts[i];
    if (std::isnan(xi) || std::isnan(yi)) continue;
    bool dominated = false;
    for (size_t j = 0; j < pts.size() && !dominated; ++j) {
      const auto [xj, yj] = pts[j];
      if (j == i || std::isnan(xj) || std::isnan(yj)) continue;
      dominated = xj <= xi && yj <= yi && (xj < xi || yj < yi);
    }
    front[i] = !dominated;
  }
  return front;
}

void check_metric(const std::string& name, const std::string& context) { (void)parse_metric(name, context); }

std::optional<double> per_ray(const Counters& counters, const std::string& pass, const std::string& counter) {
  const auto p = counters.passes().find(pass);
  if (p == counters.passes().end() || !p->second.count(counter)) return std::nullopt;
  const std::uint64_t rays = counters.get(pass, counter::rays_cast);
  if (rays == 0) return std::nullopt;
  return double(counters.get(pass, counter)) / double(rays);
}

std::optional<MetricValue> resolve_metric(const CellResult& c, const std::string& name, const std::string& context, std::string* why) {
  const Metric m = parse_metric(name, context);
  auto none = [&](const std::string& w) -> std::optional<MetricValue> {
    if (why) *why = w;
    return std::nullopt;
  };
  switch (m.kind) {
    case Metric::time:
      return time_value(c, m.passes, why);
    case Metric::image_time: {
      const auto frames = number_at(c.error, "frames");
      if (!frames) return none("no error.frames (the cell computed no error metrics)");
      auto t = time_value(c, m.passes, why);
      if (!t) return t;
      t->value *= *frames;
      if (t->ci) t->ci = std::make_pair(t->ci->first * *frames, t->ci->second * *frames);
      return t;
    }
    case Metric::per_ray: {
      const auto v = per_ray(c.timing.counters, m.pass, m.counter);
      if (!v) return none("no " + m.counter + " or no rays_cast counted for pass '" + m.pass + "'");
      return MetricValue{*v, std::nullopt, false};
    }
    case Metric::pointer: {
      const json* v = nullptr;
      try {
        if (c.line.contains(m.ptr)) v = &c.line.at(m.ptr);
      } catch (const json::exception&) {
        v = nullptr;  // e.g. a non-numeric index into an array: not in this line
      }
      if (!v || v->is_null()) return none("missing or null");
      if (!v->is_number()) return none(std::string("a ") + v->type_name() + ", not a number");
      return MetricValue{v->get<double>(), std::nullopt, false};
    }
  }
  return std::nullopt;
}

json report_spec(const std::vector<CellResult>& cells) {
  for (const CellResult& c : cells)
    if (c.report.is_object()) return c.report;
  return nullptr;
}

std::string error_metrics_section(const std::vector<CellResult>& cells) {
  if (std::none_of(cells.begin(), cells.end(), [](const CellResult& c) { return c.error.is_object(); })) return "";
  const std::string eps = distinct_numbers(cells, "relmse_eps"), peak = distinct_numbers(cells, "psnr_peak"),
                    threshold = distinct_numbers(cells, "threshold");
  std::string s = "## Error metrics\n\n";
  s += "Each cell's image (t), accumulated over `error.frames` frames, is compared with a converged reference render (r) of "
       "the same configuration, per pixel and RGB channel on linear values:\n\n";
  s += "- **MSE** = mean over pixels and channels of (t − r)².\n";
  s += "- **relMSE** = mean of (t − r)² / (r² + ε), ε = " + (eps.empty() ? std::string("as recorded") : eps) + ".\n";
  s += "- **PSNR** = 10 · log10(peak² / MSE) dB on linear values, peak = " + (peak.empty() ? std::string("as recorded") : peak) +
       " (∞ when the images are identical). This is not OpenImageIO's PSNR, which uses max(1, peak) as the peak.\n";
  s += "- **max |t − r|**: the largest channel difference of any pixel.\n";
  s += "- **over threshold**: pixels whose largest channel error exceeds " +
       (threshold.empty() ? std::string("the threshold") : threshold) + "; **non-finite**: pixels with a NaN or infinite channel.\n";
  s += "- **FLIP** (when computed): mean LDR-FLIP over the pixels (Andersson et al. 2020, \"FLIP: A Difference Evaluator for "
       "Alternating Images\").\n";
  s += "- **Shadows**, over pixels whose primary visibility agrees with the reference: **acne** = shadowed in the frame but lit "
       "in the reference, **leaks** = lit in the frame but shadowed in the reference; **coverage mismatches** (primary "
       "visibility differs) are counted apart and left out of both.\n";
  s += "- **Depth error** = |reconstructed − true world position| / true distance, per pixel with geometry.\n\n";
  return s;
}

std::string error_table(const CellResult& c) {
  if (!c.error.is_object()) return "";
  const json& e = c.error;
  std::string s = "\nError against the reference:\n\n| error metric | value |\n|---|---|\n";
  if (e.contains("reference") && e["reference"].is_object()) {
    const json& r = e["reference"];
    std::string t = r.contains("id") && r["id"].is_string() ? "`" + r["id"].get<std::string>() + "`" : std::string("?");
    if (const auto n = number_at(r, "samples")) t += ", " + count_text(*n) + " samples per pixel";
    if (const auto sec = number_at(r, "render_s")) t += ", rendered in " + fmt("%.1f", *sec) + " s";
    if (r.contains("cached") && r["cached"].is_boolean()) t += r["cached"].get<bool>() ? " (cached)" : " (rendered for this run)";
    s += "| reference | " + t + " |\n";
  }
  if (const auto f = number_at(e, "frames")) s += "| frames accumulated | " + count_text(*f) + " |\n";
  if (e.contains("image") && e["image"].is_object()) {
    const json& im = e["image"];
    auto row = [&](const std::string& label, const char* key, const char* f) {
      if (const auto v = number_at(im, key)) s += "| " + label + " | " + fmt(f, *v) + " |\n";
    };
    row("MSE", "mse", "%.4g");
    const auto eps = number_at(im, "relmse_eps");
    row("relMSE" + (eps ? " (ε = " + fmt("%g", *eps) + ")" : std::string()), "relmse", "%.4g");
    if (im.contains("psnr_db")) {
      const auto peak = number_at(im, "psnr_peak");
      s += "| PSNR" + (peak ? " (peak " + fmt("%g", *peak) + ")" : std::string()) + " | " +
           (im["psnr_db"].is_null() ? std::string("∞") : im["psnr_db"].is_number() ? fmt("%.2f", im["psnr_db"].get<double>()) + " dB" : "—") +
           " |\n";
    }
    row("max \\|t − r\\|", "max_abs", "%.4g");
    if (const auto o = number_at(im, "over_threshold")) {
      const auto th = number_at(im, "threshold");
      const auto px = number_at(im, "pixels");
      s += "| pixels over " + (th ? fmt("%g", *th) : std::string("the threshold")) + " | " + count_text(*o) +
           (px && *px > 0 ? " (" + fmt("%.3g", 100.0 * *o / *px) + "% of " + count_text(*px) + ")" : std::string()) + " |\n";
    }
    if (const auto nf = number_at(im, "non_finite")) s += "| non-finite pixels | " + count_text(*nf) + " |\n";
    if (const auto fl = number_at(im, "flip_mean"); fl && *fl >= 0) s += "| FLIP (mean) | " + fmt("%.4f", *fl) + " |\n";
  }
  if (e.contains("shadow") && e["shadow"].is_object()) {
    const json& sh = e["shadow"];
    auto v = [&](const char* k) { const auto x = number_at(sh, k); return x ? count_text(*x) : std::string("—"); };
    s += "| shadow acne / leaks | " + v("acne") + " / " + v("leaks") + " of " + v("compared") + " compared pixels |\n";
    s += "| shadow coverage mismatches | " + v("coverage_mismatch") + " |\n";
  }
  if (e.contains("depth") && e["depth"].is_object()) {
    const json& d = e["depth"];
    const auto mean = number_at(d, "mean_rel"), mx = number_at(d, "max_rel");
    s += "| relative position error (mean / max) | " + (mean ? fmt("%.3g", *mean) : "—") + " / " + (mx ? fmt("%.3g", *mx) : "—") + " |\n";
  }
  return s;
}

std::string tradeoff_sections(const std::vector<CellResult>& cells, std::vector<ReportFile>& charts) {
  const json spec = report_spec(cells);
  if (spec.is_null()) return "";
  const std::string context = "report spec";
  std::string s;
  if (spec.contains("tradeoffs")) {
    if (!spec["tradeoffs"].is_array()) throw InputError(context + ": 'tradeoffs' is not a list");
    size_t n = 0;
    for (const json& t : spec["tradeoffs"]) s += tradeoff_section(cells, t, ++n, charts);
  }
  if (bool_field(spec, "cache_sampling", context)) s += cache_sampling_section(cells, charts);
  if (bool_field(spec, "depth_error", context)) s += depth_error_section(cells, charts);
  if (s.empty()) return "";
  return "## Speed against error\n\nThe sections the matrix's `report` object asks for.\n\n" + s;
}

}  // namespace hp
