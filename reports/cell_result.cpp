#include "cell_result.hpp"
#include "cell_record.hpp"

#include <cstdio>

#include "error.hpp"
#include "input_file.hpp"
#include "json_depth.hpp"
#include "timing/jsonl.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>

namespace hp {

using json = nlohmann::json;
namespace fs = std::filesystem;

CellResult parse_cell(const json& line, const std::string& where) {
  CellRecord r = parse_cell_record(line, where);
  if (r.result.timings.measured().empty()) throw InputError(where + ": result: no measured frames");
  CellResult c(std::move(r.result));
  c.where = where;
  c.id = std::move(r.id);
  c.matrix = std::move(r.matrix);
  c.name = std::move(r.name);
  c.axes = std::move(r.axes);
  c.config = std::move(r.config);
  c.triangles = r.triangles;
  if (r.bvh) c.bvh = *r.bvh;
  c.images = r.images;
  c.cache = std::move(r.cache);
  c.report = std::move(r.report);
  c.error = std::move(r.error);
  // The line as it was read (not re-serialized), so JSON-pointer metrics see every key it holds.
  c.line = line;
  c.line.erase("result");
  return c;
}

std::vector<CellResult> load_cells(const std::string& out_dir) {
  const fs::path file = fs::path(out_dir) / "results.jsonl";
  if (!fs::exists(file)) throw InputError(file.string() + ": no such file (run `hybridprof run` first)");
  std::vector<CellResult> cells;
  // Read line by line rather than through read_results so each cell can name its own line.
  const std::string content = read_input_file(file, "results file");
  for_each_jsonl_line(content, file.string(), "result",
                      [&](const json& j, const std::string& where) { cells.push_back(parse_cell(j, where)); });
  if (cells.empty()) throw InputError(file.string() + ": no finished cell");
  return cells;
}

PassSamples pass_samples(const TimingResult& timing) {
  PassSamples out;
  for (const FrameSample& f : timing.timings.measured()) {
    std::vector<std::pair<std::string, double>> frame;  // this frame's sum per pass, in order
    for (const PassSample& p : f.passes) {
      auto it = std::find_if(frame.begin(), frame.end(), [&](auto& e) { return e.first == p.pass; });
      if (it == frame.end())
        frame.emplace_back(p.pass, double(p.duration_ns()));
      else
        it->second += double(p.duration_ns());
    }
    for (const auto& [pass, ns] : frame) {
      auto it = std::find_if(out.begin(), out.end(), [&](auto& e) { return e.first == pass; });
      if (it == out.end())
        out.push_back({pass, {ns}});
      else
        it->second.push_back(ns);
    }
  }
  return out;
}

TimeSeries summed_pass_series(const TimingResult& timing, const std::function<bool(const std::string&)>& in) {
  TimeSeries out;
  std::map<std::uint32_t, std::vector<double>> by_round;
  for (const FrameSample& f : timing.timings.measured()) {
    double sum = 0.0;
    bool any = false;
    for (const PassSample& p : f.passes)
      if (in(p.pass)) {
        sum += double(p.duration_ns());
        any = true;
      }
    if (!any) continue;
    out.frames.push_back(sum);
    by_round[f.round].push_back(sum);
  }
  for (const auto& [round, v] : by_round) out.round_medians.push_back(quantile(v, 0.5));
  return out;
}

std::optional<std::pair<double, double>> recorded_load(const CellResult& c) {
  double lo = 1e300, hi = -1e300;
  const auto take = [&](const json& load) {
    for (const char* k : {"start", "end"}) {
      const json x = load.is_object() ? load.value(k, json()) : json();
      if (!x.is_number()) continue;
      lo = std::min(lo, x.get<double>());
      hi = std::max(hi, x.get<double>());
    }
  };
  take(c.line.value("load_1min", json()));
  for (const json& v : c.line.value("rounds", json::object()).value("visits", json::array()))
    take(v.value("load_1min", json()));
  if (hi < lo) return std::nullopt;
  return std::pair{lo, hi};
}

namespace {
void flatten_numbers(const json& j, const std::string& prefix, std::map<std::string, double>& out) {
  if (j.is_number()) {
    out[prefix] = j.get<double>();
  } else if (j.is_object()) {
    for (const auto& [k, v] : j.items()) flatten_numbers(v, prefix + "/" + k, out);
  }
}
}  // namespace

std::map<std::string, double> deterministic_metrics(const CellResult& c) {
  std::map<std::string, double> m;
  for (const auto& [pass, counters] : c.timing.counters.passes()) {
    for (const auto& [name, value] : counters) m[pass + "/" + name] = double(value);
  }
  // Pipeline statistics of the one untimed frame that counted them (not a sum over frames).
  for (const auto& [pass, counters] : c.timing.timings.frame_invocations().passes()) {
    for (const auto& [name, value] : counters) m[pass + "/" + name + "_per_frame"] = double(value);
  }
  if (c.bvh.is_object()) {
    for (const char* k : {"nodes", "leaves", "max_depth", "sah_cost"}) {
      if (c.bvh.contains(k) && c.bvh[k].is_number()) m[std::string("bvh.") + k] = c.bvh[k].get<double>();
    }
  }
  if (c.triangles) m["scene.triangles"] = double(*c.triangles);
  if (c.cache.is_object() && c.cache.contains("passes") && c.cache["passes"].is_array()) {
    for (const json& p : c.cache["passes"]) {
      if (!p.is_object() || !p.contains("pass") || !p["pass"].is_string()) continue;
      json counts = p;
      counts.erase("pass");
      counts.erase("mrc");
      flatten_numbers(counts, "cache/" + p["pass"].get<std::string>(), m);
    }
  }
  return m;
}

std::string match_key(const CellResult& c) {
  json k = c.config;
  if (k.is_object()) k.erase("inject");
  return c.matrix + "|" + c.name + "|" + k.dump();
}

std::string match_key_ignoring(const CellResult& c, const std::vector<std::string>& pointers) {
  json k = c.config;
  if (k.is_object()) {
    k.erase("inject");
    for (const std::string& p : pointers) {
      const json::json_pointer ptr(p);
      if (!k.contains(ptr)) continue;
      json& parent = k[ptr.parent_pointer()];
      if (parent.is_object()) parent.erase(ptr.back());
    }
  }
  return c.matrix + "|" + c.name + "|" + k.dump();
}

std::string axis_value_text(const json& v) {
  if (v.is_string()) return v.get<std::string>();
  if (v.is_array() && !v.empty() && std::all_of(v.begin(), v.end(), [](const json& e) { return e.is_number(); })) {
    std::string s;
    for (const json& e : v) {
      if (!s.empty()) s += 'x';
      s += e.dump();
    }
    return s;
  }
  return v.dump();
}

std::string cell_label(const CellResult& c) {
  std::string s;
  for (const auto& [k, v] : c.axes.items()) s += (s.empty() ? "" : ", ") + axis_leaf(k) + "=" + axis_value_text(v);
  if (!s.empty()) return s;
  return c.name.empty() ? c.id : c.name;
}

std::string axis_leaf(const std::string& axis) {
  const size_t dot = axis.rfind('.');
  return dot == std::string::npos ? axis : axis.substr(dot + 1);
}

std::string format_number(const char* format, double value) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, value);
  return buf;
}

}  // namespace hp
