#include "tradeoff.hpp"

#include "cache_sampling.hpp"
#include "error.hpp"
#include "markdown.hpp"
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
    if (slash == std::string::npos || slash == 0 || slash + 1 == rest.size() ||
        rest.find('/', slash + 1) != std::string::npos)
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
  if (!v.is_time) return md::general(v.value);
  std::string s = fmt("%.3f", v.value);
  if (with_ci) s += v.ci ? " [" + fmt("%.3f", v.ci->first) + ", " + fmt("%.3f", v.ci->second) + "]" : " (no CI: n < 6)";
  return s;
}

// Every pass a time metric names must be one some cell ran: a typo would otherwise leave every cell
// "not available".
void check_passes_ran(const std::vector<CellResult>& cells, const Metric& m, const std::string& name,
                      const std::string& context) {
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

// A "tradeoffs" entry of the report spec, validated: its metrics exist and their passes ran.
struct TradeoffSpec {
  std::string context, title, xn, yn, x_label, y_label;
  std::optional<bool> log_x, log_y;  ///< as the spec says; unset: log where the values span two decades
  std::vector<std::string> columns;
};

TradeoffSpec parse_tradeoff(const std::vector<CellResult>& cells, const json& spec, size_t n) {
  TradeoffSpec t;
  t.context = "report spec: tradeoffs[" + std::to_string(n - 1) + "]";
  const std::string& context = t.context;
  if (!spec.is_object()) throw InputError(context + ": not an object");
  t.title = string_field(spec, "title", "Trade-off " + std::to_string(n), context);
  t.context += " \"" + t.title + "\"";
  for (const char* k : {"x", "y"})
    if (!spec.contains(k) || !spec[k].is_string())
      throw InputError(context + ": '" + k + "' (a metric name) missing or not a string");
  t.xn = spec["x"].get<std::string>();
  t.yn = spec["y"].get<std::string>();
  t.x_label = string_field(spec, "x_label", t.xn, context);
  t.y_label = string_field(spec, "y_label", t.yn, context);
  if (spec.contains("log_x")) t.log_x = bool_field(spec, "log_x", context);
  if (spec.contains("log_y")) t.log_y = bool_field(spec, "log_y", context);
  if (spec.contains("columns")) {
    if (!spec["columns"].is_array()) throw InputError(context + ": 'columns' is not a list of metric names");
    for (const json& c : spec["columns"]) {
      if (!c.is_string()) throw InputError(context + ": 'columns' is not a list of metric names");
      t.columns.push_back(c.get<std::string>());
    }
  }
  std::vector<std::string> all = {t.xn, t.yn};
  all.insert(all.end(), t.columns.begin(), t.columns.end());
  for (const std::string& name : all) check_passes_ran(cells, parse_metric(name, context), name, context);
  return t;
}

struct TradeoffRow {
  const CellResult* cell;
  MetricValue x, y;
  std::vector<std::optional<MetricValue>> extra;
  bool front = false;
  int front_number = 0;  ///< 1, 2, ... along the front in x order: the chart's label, the table's and the text's
};

// Whether an axis is drawn log10: as the spec asks where every value allows it, else (unset) where every
// value is positive and the largest is at least 100 times the smallest, so that a front from 170 to 140,000
// is not a flat line at the bottom. `asked` is set to whether the spec asked for a log axis it cannot have.
bool log_axis(const std::optional<bool>& spec, const std::vector<double>& values, bool& asked) {
  const bool positive = std::all_of(values.begin(), values.end(), [](double v) { return v > 0; });
  asked = spec.value_or(false) && !positive;
  if (spec) return *spec && positive;
  if (!positive || values.empty()) return false;
  const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
  return *hi >= 100.0 * *lo;
}

std::string front_tag(const TradeoffRow& r) { return "(" + std::to_string(r.front_number) + ")"; }

// The scatter chart, with the log axes asked for where every value allows one (a note says where not).
svg::ScatterChart tradeoff_chart(const TradeoffSpec& t, const std::vector<TradeoffRow>& rows,
                                 std::vector<std::string>& notes) {
  svg::ScatterChart chart;
  chart.title = t.title;
  std::vector<double> xs, ys;
  for (const TradeoffRow& r : rows) {
    xs.push_back(r.x.value);
    ys.push_back(r.y.value);
  }
  bool x_refused = false, y_refused = false;
  chart.log_x = log_axis(t.log_x, xs, x_refused);
  chart.log_y = log_axis(t.log_y, ys, y_refused);
  chart.x_label = t.x_label + (chart.log_x ? " (log)" : "");
  chart.y_label = t.y_label + (chart.log_y ? " (log)" : "");
  if (x_refused) notes.push_back("The x axis is linear: a value is <= 0, which a log axis cannot show.");
  if (y_refused) notes.push_back("The y axis is linear: a value is <= 0, which a log axis cannot show.");
  for (const TradeoffRow& r : rows) {
    svg::ScatterPoint p;
    p.x = r.x.value;
    p.y = r.y.value;
    // Only the front is labelled, by its number in the table and the text (every point has its tooltip):
    // whole cell names beside every front point overlap and run off the chart.
    if (r.front) p.label = std::to_string(r.front_number);
    p.tooltip = cell_label(*r.cell) + ": " + t.x_label + " " + value_text(r.x) + ", " + t.y_label + " " +
                value_text(r.y) + (r.front ? " (on the Pareto front)" : "");
    p.front = r.front;
    chart.points.push_back(p);
  }
  return chart;
}

// One sentence on the Pareto front.
std::string front_sentence(const TradeoffSpec& t, const std::vector<TradeoffRow>& rows,
                           const std::vector<const CellResult*>& among) {
  std::vector<std::string> on;
  for (const TradeoffRow& r : rows)
    if (r.front)
      on.push_back(front_tag(r) + " " + varying_label(*r.cell, among) + " (" + value_text(r.x, false) + ", " +
                   value_text(r.y, false) + ")");
  const size_t n_front = on.size();
  if (rows.size() == 1) return "Only one cell has both values; it is trivially on the Pareto front.\n\n";
  if (n_front == rows.size()) {
    return "Every cell is on the Pareto front (no cell is beaten on both " + t.x_label + " and " + t.y_label +
           " by another); in x order: " + md::list(on) + ".\n\n";
  }
  return std::to_string(n_front) + " of " + std::to_string(rows.size()) +
         " cells are on the Pareto front (no other cell is at least as good in both " + t.x_label + " and " +
         t.y_label + " and better in one): " + md::list(on) + "; the other " + std::to_string(rows.size() - n_front) +
         " are dominated.\n\n";
}

std::string tradeoff_table(const TradeoffSpec& t, const std::vector<TradeoffRow>& rows) {
  std::string s = "| cell | " + md::escape(t.x_label) + (rows.front().x.is_time ? " (ms, 95% CI)" : "") + " | " +
                  md::escape(t.y_label) + (rows.front().y.is_time ? " (ms, 95% CI)" : "") + " |";
  for (const std::string& col : t.columns) s += " `" + md::escape(col) + "` |";
  s += " Pareto |\n|---|---|---|";
  for (size_t i = 0; i < t.columns.size(); ++i) s += "---|";
  s += "---|\n";
  for (const TradeoffRow& r : rows) {
    s += "| " + md::escape(cell_label(*r.cell)) + " | " + value_text(r.x) + " | " + value_text(r.y) + " |";
    for (const auto& e : r.extra) {
      s += ' ';
      s += e ? value_text(*e) : std::string("—");
      s += " |";
    }
    s += " " + (r.front ? "**yes** " + front_tag(r) : std::string("no")) + " |\n";
  }
  return s + "\n";
}

// The cells' scene as a front compares it: the scene file and the world transform of its config.
std::string scene_key(const CellResult& c) {
  return json{{"scene", c.config.value("scene", json())}, {"transform", c.config.value("transform", json())}}.dump();
}
std::string scene_text(const CellResult& c) {
  std::string s = "scene " + c.config.value("scene", std::string("?"));
  const json tr = c.config.value("transform", json());
  if (tr.is_object())
    for (const auto& [k, v] : tr.items()) s += ", transform." + k + " " + v.dump();
  return s;
}

// One scene's rows: the front, the chart at `path`, the sentence, the table and their notes.
std::string front_part(const TradeoffSpec& t, std::vector<TradeoffRow>& rows, const std::string& path,
                       std::vector<ReportFile>& charts) {
  std::sort(rows.begin(), rows.end(), [](const TradeoffRow& a, const TradeoffRow& b) {
    return a.x.value != b.x.value ? a.x.value < b.x.value : a.y.value < b.y.value;
  });
  std::vector<std::pair<double, double>> pts;
  for (const TradeoffRow& r : rows) pts.push_back({r.x.value, r.y.value});
  const std::vector<bool> front = pareto_front(pts);
  int number = 0;
  for (size_t i = 0; i < rows.size(); ++i) {
    rows[i].front = front[i];
    rows[i].front_number = front[i] ? ++number : 0;
  }
  std::vector<const CellResult*> among;
  for (const TradeoffRow& r : rows) among.push_back(r.cell);
  std::vector<std::string> notes;
  charts.push_back({path, svg::render(tradeoff_chart(t, rows, notes))});
  std::string s = "![" + md::escape(t.title) + "](" + path + ")\n\n";
  s += front_sentence(t, rows, among);
  s += tradeoff_table(t, rows);
  if (std::any_of(rows.begin(), rows.end(), [](const TradeoffRow& r) {
        return std::any_of(r.extra.begin(), r.extra.end(), [](const auto& e) { return !e.has_value(); });
      }))
    notes.push_back("— in a column: not available for that cell.");
  for (const std::string& note : notes) s += "*Note:* " + md::escape(note) + "\n\n";
  return s;
}

std::string tradeoff_section(const std::vector<CellResult>& cells, const json& spec, size_t n,
                             std::vector<ReportFile>& charts) {
  const TradeoffSpec t = parse_tradeoff(cells, spec, n);
  std::vector<TradeoffRow> rows;
  std::vector<std::string> skipped;
  for (const CellResult& c : cells) {
    std::string why_x, why_y;
    const auto x = resolve_metric(c, t.xn, t.context, &why_x);
    const auto y = resolve_metric(c, t.yn, t.context, &why_y);
    if (!x || !y) {
      skipped.push_back(cell_label(c) + " (" + (!x ? "`" + t.xn + "`: " + why_x : "`" + t.yn + "`: " + why_y) + ")");
      continue;
    }
    TradeoffRow r{&c, *x, *y, {}};
    for (const std::string& col : t.columns) r.extra.push_back(resolve_metric(c, col, t.context));
    rows.push_back(r);
  }
  std::string s = "### " + md::escape(t.title) + "\n\n";
  s += "x: `" + t.xn + "` (" + md::escape(t.x_label) + "), y: `" + t.yn + "` (" + md::escape(t.y_label) +
       "); both lower is better.\n\n";
  if (rows.empty()) {
    s += "No cell has both values, so there is nothing to compare.";
    if (!skipped.empty()) s += " Not available: " + md::escape(md::list(skipped)) + ".";
    return s + "\n\n";
  }
  // A Pareto front compares ways of rendering one scene: cells of different scenes (another scene file, or
  // the same one moved or scaled by `transform`) get a front, a chart and a table each.
  std::map<std::string, std::vector<TradeoffRow>> by_scene;
  std::vector<std::string> scene_order;
  for (const TradeoffRow& r : rows) {
    const std::string key = scene_key(*r.cell);
    if (!by_scene.count(key)) scene_order.push_back(key);
    by_scene[key].push_back(r);
  }
  if (by_scene.size() > 1)
    s += "The cells render " + std::to_string(by_scene.size()) +
         " different scenes (scene or transform); each has its own Pareto front.\n\n";
  for (size_t g = 0; g < scene_order.size(); ++g) {
    std::vector<TradeoffRow>& group = by_scene[scene_order[g]];
    if (by_scene.size() > 1) s += "#### " + md::escape(scene_text(*group.front().cell)) + "\n\n";
    const std::string suffix = by_scene.size() > 1 ? "_" + std::to_string(g + 1) : "";
    s += front_part(t, group, "charts/tradeoff_" + std::to_string(n) + suffix + ".svg", charts);
  }
  if (!skipped.empty()) s += "*Note:* " + md::escape("Not available, left out: " + md::list(skipped) + ".") + "\n\n";
  return s;
}

// ---- depth error -----------------------------------------------------------------------------

std::string depth_error_section(const std::vector<CellResult>& cells, std::vector<ReportFile>& charts) {
  std::string s = "### World-position reconstruction error by distance\n\n";
  std::vector<const CellResult*> with;
  std::vector<std::string> without;
  for (const CellResult& c : cells) {
    if (c.error.is_object() && c.error.contains("depth") && c.error["depth"].is_object())
      with.push_back(&c);
    else
      without.push_back(cell_label(c));
  }
  if (with.empty()) return s + "No cell carries depth-error numbers (`error.depth`).\n\n";
  s +=
      "|reconstructed − true world position| / true distance, from the depth buffer of each cell's depth mode; mean and "
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
    s += "| " + md::escape(cell_label(*c)) + " | " + (px ? md::count(*px) : "—") + " | " +
         (mean ? fmt("%.3g", *mean) : "—") + " | " + (mx ? fmt("%.3g", *mx) : "—") + " | " + std::to_string(nbins) +
         " |\n";
    svg::Line line{varying_label(*c, with), {}, {}, {}, {}};
    if (nbins) {
      for (const json& b : d["bins"]) {
        const auto nr = number_at(b, "near"), fr = number_at(b, "far"), m = number_at(b, "mean_rel"),
                   n = number_at(b, "pixels");
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
  if (!without.empty()) s += "Without depth-error numbers: " + md::escape(md::list(without)) + ".\n\n";
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

std::optional<double> number_at(const json& j, const char* key) {
  if (!j.is_object() || !j.contains(key) || !j[key].is_number()) return std::nullopt;
  return j[key].get<double>();
}

std::string varying_label(const CellResult& c, const std::vector<const CellResult*>& among,
                          const std::vector<std::string>& skip_leaves) {
  std::string s;
  for (const auto& [k, v] : c.axes.items()) {
    if (std::find(skip_leaves.begin(), skip_leaves.end(), axis_leaf(k)) != skip_leaves.end()) continue;
    const bool varies = std::any_of(among.begin(), among.end(),
                                    [&](const CellResult* o) { return !o->axes.contains(k) || o->axes[k] != v; });
    if (varies) s += (s.empty() ? "" : ", ") + axis_leaf(k) + "=" + axis_value_text(v);
  }
  if (!s.empty()) return s;
  if (skip_leaves.empty()) return cell_label(c);
  for (const auto& [k, v] : c.axes.items())
    if (std::find(skip_leaves.begin(), skip_leaves.end(), axis_leaf(k)) == skip_leaves.end())
      s += (s.empty() ? "" : ", ") + axis_leaf(k) + "=" + axis_value_text(v);
  return s.empty() ? (c.name.empty() ? c.id : c.name) : s;
}

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

std::optional<MetricValue> resolve_metric(const CellResult& c, const std::string& name, const std::string& context,
                                          std::string* why) {
  const Metric m = parse_metric(name, context);
  auto none = [&](const std::string& w) -> std::optional<MetricValue> {
    if (why) *why = w;
    return std::nullopt;
  };
  switch (m.kind) {
    case Metric::time: return time_value(c, m.passes, why);
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
  s +=
      "Each cell's image (t), accumulated over `error.frames` frames, is compared with a converged reference render (r) of "
      "the same configuration, per pixel and RGB channel on linear values:\n\n";
  s += "- **MSE** = mean over pixels and channels of (t − r)².\n";
  s += "- **relMSE** = mean of (t − r)² / (r² + ε), ε = " + (eps.empty() ? std::string("as recorded") : eps) + ".\n";
  s += "- **PSNR** = 10 · log10(peak² / MSE) dB on linear values, peak = " +
       (peak.empty() ? std::string("as recorded") : peak) +
       " (∞ when the images are identical). This is not OpenImageIO's PSNR, which uses max(1, peak) as the peak.\n";
  s += "- **max |t − r|**: the largest channel difference of any pixel.\n";
  s += "- **over threshold**: pixels whose largest channel error exceeds " +
       (threshold.empty() ? std::string("the threshold") : threshold) +
       "; **non-finite**: pixels with a NaN or infinite channel.\n";
  s +=
      "- **FLIP** (when computed): mean LDR-FLIP over the pixels (Andersson et al. 2020, \"FLIP: A Difference Evaluator for "
      "Alternating Images\").\n";
  s +=
      "- **Shadows**, over pixels whose primary visibility agrees with the reference: **acne** = shadowed in the frame but lit "
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
    if (const auto n = number_at(r, "samples")) t += ", " + md::count(*n) + " samples per pixel";
    if (const auto sec = number_at(r, "render_s")) t += ", rendered in " + fmt("%.1f", *sec) + " s";
    if (r.contains("cached") && r["cached"].is_boolean())
      t += r["cached"].get<bool>() ? " (cached)" : " (rendered for this run)";
    s += "| reference | " + t + " |\n";
  }
  if (const auto f = number_at(e, "frames")) s += "| frames accumulated | " + md::count(*f) + " |\n";
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
           (im["psnr_db"].is_null()     ? std::string("∞")
            : im["psnr_db"].is_number() ? fmt("%.2f", im["psnr_db"].get<double>()) + " dB"
                                        : "—") +
           " |\n";
    }
    row("max \\|t − r\\|", "max_abs", "%.4g");
    if (const auto o = number_at(im, "over_threshold")) {
      const auto th = number_at(im, "threshold");
      const auto px = number_at(im, "pixels");
      s += "| pixels over " + (th ? fmt("%g", *th) : std::string("the threshold")) + " | " + md::count(*o) +
           (px && *px > 0 ? " (" + fmt("%.3g", 100.0 * *o / *px) + "% of " + md::count(*px) + ")" : std::string()) +
           " |\n";
    }
    if (const auto nf = number_at(im, "non_finite")) s += "| non-finite pixels | " + md::count(*nf) + " |\n";
    if (const auto fl = number_at(im, "flip_mean"); fl && *fl >= 0) s += "| FLIP (mean) | " + fmt("%.4f", *fl) + " |\n";
  }
  if (e.contains("shadow") && e["shadow"].is_object()) {
    const json& sh = e["shadow"];
    auto v = [&](const char* k) {
      const auto x = number_at(sh, k);
      return x ? md::count(*x) : std::string("—");
    };
    s += "| shadow acne / leaks | " + v("acne") + " / " + v("leaks") + " of " + v("compared") + " compared pixels |\n";
    s += "| shadow coverage mismatches | " + v("coverage_mismatch") + " |\n";
  }
  if (e.contains("depth") && e["depth"].is_object()) {
    const json& d = e["depth"];
    const auto mean = number_at(d, "mean_rel"), mx = number_at(d, "max_rel");
    s += "| relative position error (mean / max) | " + (mean ? fmt("%.3g", *mean) : "—") + " / " +
         (mx ? fmt("%.3g", *mx) : "—") + " |\n";
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
