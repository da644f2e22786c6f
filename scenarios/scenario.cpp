#include "scenario.hpp"
#include "scenario_keys.hpp"

#include "error.hpp"
#include "input_file.hpp"
#include "json_depth.hpp"
#include "stable_id.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <set>
#include <sstream>

namespace hp {

namespace {

using json = nlohmann::json;

std::string join(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }

[[noreturn]] void fail(const std::string& file, const std::string& path, const std::string& why) {
  throw InputError(file + ": " + (path.empty() ? std::string("(top level)") : path) + ": " + why);
}

void only_keys(const json& j, const std::set<std::string>& allowed, const std::string& file, const std::string& path) {
  if (!j.is_object()) fail(file, path, std::string("expected an object, got ") + j.type_name());
  for (const auto& [k, v] : j.items()) {
    if (!allowed.count(k)) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      fail(file, join(path, k), "unknown key (allowed here: " + list + ")");
    }
  }
}

// The value of one key, checked against its table row (the messages are those the scenario tests pin).
json read_value(const ScenarioKey& k, const json& v, const std::string& file, const std::string& where) {
  const auto wrong = [&](const char* expected) { fail(file, where, std::string(expected) + ", got " + v.type_name()); };
  switch (k.type) {
    case KeyType::boolean:
      if (!v.is_boolean()) wrong("expected true or false");
      return v;
    case KeyType::number: {
      if (!v.is_number()) wrong("expected a number");
      const double x = v.get<double>();
      if (!std::isfinite(x) || x < k.lo || x > k.hi) {
        std::ostringstream s;
        s << x << " is outside [" << k.lo << ", " << k.hi << "]";
        fail(file, where, s.str());
      }
      return x;
    }
    case KeyType::integer: {
      if (!v.is_number_integer()) wrong("expected an integer");
      const int64_t x = v.get<int64_t>();
      if (x < k.int_lo || x > k.int_hi) {
        fail(file, where,
             std::to_string(x) + " is outside [" + std::to_string(k.int_lo) + ", " + std::to_string(k.int_hi) + "]");
      }
      return x;
    }
    case KeyType::string:
    case KeyType::choice: {
      if (!v.is_string()) wrong("expected a string");
      if (k.type == KeyType::string) return v;
      const std::string s = v.get<std::string>();
      if (std::find(k.choices.begin(), k.choices.end(), s) != k.choices.end()) return v;
      std::string list;
      for (const auto& c : k.choices) list += (list.empty() ? "" : ", ") + c;
      fail(file, where, "'" + s + "' is not one of " + list);
    }
    case KeyType::vec3: {
      if (!v.is_array() || v.size() != 3) fail(file, where, "expected an array of three numbers");
      json out = json::array();
      for (int i = 0; i < 3; ++i) {
        if (!v[i].is_number()) fail(file, where + "[" + std::to_string(i) + "]", "expected a number");
        const float x = v[i].get<float>();
        if (!std::isfinite(x)) fail(file, where + "[" + std::to_string(i) + "]", "not finite");
        out.push_back(x);
      }
      return out;
    }
    case KeyType::resolution: {
      if (!v.is_array() || v.size() != 2 || !v[0].is_number_integer() || !v[1].is_number_integer()) {
        fail(file, where, "expected [width, height] integers");
      }
      const int64_t w = v[0].get<int64_t>(), h = v[1].get<int64_t>();
      if (w < 1 || h < 1 || w > kMaxImageSide || h > kMaxImageSide) {
        fail(file, where,
             std::to_string(w) + "x" + std::to_string(h) + " is outside 1.." + std::to_string(kMaxImageSide) +
                 " per side");
      }
      return v;
    }
    case KeyType::pass_list: {
      if (!v.is_array()) fail(file, where, "expected a list of pass names");
      std::vector<std::string> seen;
      for (size_t i = 0; i < v.size(); ++i) {
        const std::string at = where + "[" + std::to_string(i) + "]";
        if (!v[i].is_string() || (v[i] != "shadows" && v[i] != "reflections")) {
          fail(file, at, "expected \"shadows\" or \"reflections\"");
        }
        if (std::find(seen.begin(), seen.end(), v[i].get<std::string>()) != seen.end())
          fail(file, at, "\"" + v[i].get<std::string>() + "\" is listed twice");
        seen.push_back(v[i].get<std::string>());
      }
      return v;
    }
  }
  return v;
}

// The key's object ("" for a top-level key) and its name in it.
std::pair<std::string, std::string> split_key(const std::string& path) {
  const size_t dot = path.find('.');
  if (dot == std::string::npos) return {"", path};
  return {path.substr(0, dot), path.substr(dot + 1)};
}

// The keys allowed in one object of a scenario: the top level ("") or a top-level key's object.
std::set<std::string> keys_of(const std::string& object) {
  std::set<std::string> out;
  for (const ScenarioKey& k : scenario_keys()) {
    const auto [parent, leaf] = split_key(k.path);
    if (object.empty())
      out.insert(parent.empty() ? leaf : parent);
    else if (parent == object)
      out.insert(leaf);
  }
  return out;
}

void set_path(json& j, const std::string& path, const json& value) {
  json* cur = &j;
  std::stringstream ss(path);
  std::string part;
  std::vector<std::string> parts;
  while (std::getline(ss, part, '.')) parts.push_back(part);
  for (size_t i = 0; i + 1 < parts.size(); ++i) {
    if (!cur->contains(parts[i]) || !(*cur)[parts[i]].is_object()) (*cur)[parts[i]] = json::object();
    cur = &(*cur)[parts[i]];
  }
  (*cur)[parts.back()] = value;
}

}  // namespace

Scenario parse_scenario(const json& j, const std::string& file, const std::string& path) {
  static const std::set<std::string> top_keys = keys_of("");
  only_keys(j, top_keys, file, path);
  Scenario s;
  s.frame.rt.shadows = s.frame.rt.reflections = true;  // FrameSettings has them off; a scenario, on
  // In table order: an object's keys are checked (only_keys) as its first row is reached, and a row's own
  // checks see the rows before it.
  std::set<std::string> checked;
  for (const ScenarioKey& k : scenario_keys()) {
    const auto [parent, leaf] = split_key(k.path);
    const json* object = &j;
    if (!parent.empty()) {
      object = j.contains(parent) ? &j.at(parent) : nullptr;
      if (object && checked.insert(parent).second) only_keys(*object, keys_of(parent), file, join(path, parent));
    }
    const json* v = object && object->contains(leaf) ? &object->at(leaf) : nullptr;
    const KeyContext c{file, path, v != nullptr};
    k.apply(s, v ? read_value(k, *v, file, join(path, k.path)) : k.default_value, c);
  }
  s.error = j.contains("error");  // the object, even empty, asks for the measurement
  // A glTF path relative to the scenario file's folder (a file given on the command line keeps its own
  // folder; documents parsed without a file resolve against the working directory).
  s.scene_path = s.scene;
  if (s.scene.rfind("builtin:", 0) != 0 && std::filesystem::path(s.scene).is_relative() && !file.empty()) {
    const std::filesystem::path dir = std::filesystem::path(file).parent_path();
    if (!dir.empty()) s.scene_path = (dir / s.scene).lexically_normal().string();
  }
  s.scene_where = file + ": " + join(path, "scene");
  for (const std::string& p : s.trace_passes) {
    if ((p == "shadows" && !s.frame.rt.shadows) || (p == "reflections" && !s.frame.rt.reflections)) {
      fail(file, join(path, "trace.passes"), "traces the " + p + " pass, which is off");
    }
    if (s.frame.rt.traversal == Traversal::pipeline) {
      fail(file, join(path, "trace.passes"),
           "\"traversal\": \"pipeline\" has no instrumented variant (ray-generation shaders); trace with "
           "\"compute\" or \"ray-query\"");
    }
  }
  return s;
}

json Scenario::canonical() const {
  json j = json::object();
  for (const ScenarioKey& k : scenario_keys()) {
    if (k.canonical && (!k.canonical_when || k.canonical_when(*this))) set_path(j, k.path, k.canonical(*this));
  }
  return j;  // nlohmann::json objects are key-sorted: dump() is canonical
}

std::string Scenario::id() const { return stable_id(canonical().dump()); }

namespace {

using Axis = std::pair<std::string, json>;  // key path, values

// The report sections' shape is checked here, so a typo fails before the matrix runs, not in `report`
// afterwards; the metric names are checked by `report` (reports/tradeoff.cpp), which knows them.
void check_report(const json& rep, const std::string& file) {
  if (!rep.is_object()) fail(file, "report", "expected an object of report sections");
  only_keys(rep, {"tradeoffs", "cache_sampling", "depth_error"}, file, "report");
  for (const char* k : {"cache_sampling", "depth_error"}) {
    if (rep.contains(k) && !rep[k].is_boolean()) fail(file, join("report", k), "expected true or false");
  }
  if (!rep.contains("tradeoffs")) return;
  const json& ts = rep["tradeoffs"];
  if (!ts.is_array()) fail(file, "report.tradeoffs", "expected a list of trade-off objects");
  for (size_t i = 0; i < ts.size(); ++i) {
    const std::string at = "report.tradeoffs[" + std::to_string(i) + "]";
    only_keys(ts[i], {"title", "x", "y", "x_label", "y_label", "log_x", "log_y", "columns"}, file, at);
    for (const char* k : {"x", "y"}) {
      if (!ts[i].contains(k) || !ts[i][k].is_string())
        fail(file, join(at, k), "a metric name, missing or not a string");
    }
    for (const char* k : {"title", "x_label", "y_label"}) {
      if (ts[i].contains(k) && !ts[i][k].is_string()) fail(file, join(at, k), "expected a string");
    }
    for (const char* k : {"log_x", "log_y"}) {
      if (ts[i].contains(k) && !ts[i][k].is_boolean()) fail(file, join(at, k), "expected true or false");
    }
    if (ts[i].contains("columns")) {
      const json& c = ts[i]["columns"];
      if (!c.is_array() || !std::all_of(c.begin(), c.end(), [](const json& v) { return v.is_string(); }))
        fail(file, join(at, "columns"), "expected a list of metric names");
    }
  }
}

// The "axes" object's axes, in file order (`axis_order`), then any it does not list in key order.
std::vector<Axis> read_axes(const json& axes, const std::string& file, const std::vector<std::string>& axis_order) {
  if (!axes.is_object()) fail(file, "axes", "expected an object of key path -> list of values");
  std::vector<Axis> ax;
  std::vector<std::string> order = axis_order;
  for (const auto& [k, v] : axes.items()) {
    if (std::find(order.begin(), order.end(), k) == order.end()) order.push_back(k);
  }
  for (const std::string& k : order) {
    if (!axes.contains(k)) continue;
    const json& v = axes.at(k);
    if (k.empty() || k.front() == '.' || k.back() == '.' || k.find("..") != std::string::npos) {
      fail(file, "axes." + k, "is not a key path (keys joined by '.')");
    }
    if (!v.is_array() || v.empty()) fail(file, "axes." + k, "expected a non-empty list of values");
    ax.emplace_back(k, v);
  }
  return ax;
}

// "cells": named scenarios merged onto the base (JSON merge patch), a first axis called "case" whose
// values are the cells' names: a suite of unlike cases (hard_cases.json) rather than a product.
Axis read_cases(const json& cells, const std::string& file, std::vector<json>& patches) {
  if (!cells.is_array() || cells.empty()) fail(file, "cells", "expected a non-empty list of scenario objects");
  json names = json::array();
  std::set<std::string> seen;
  for (size_t c = 0; c < cells.size(); ++c) {
    const std::string where = "cells[" + std::to_string(c) + "]";
    if (!cells[c].is_object()) fail(file, where, "expected a scenario object");
    if (!cells[c].contains("name") || !cells[c]["name"].is_string() || cells[c]["name"].get<std::string>().empty()) {
      fail(file, where + ".name", "every cell needs a non-empty name");
    }
    const std::string name = cells[c]["name"].get<std::string>();
    if (!seen.insert(name).second) fail(file, where + ".name", "'" + name + "' names an earlier cell too");
    names.push_back(name);
    patches.push_back(cells[c]);
  }
  return {"case", names};
}

// "expect": per case name, the results a test holds the case to.
void check_expect(const json& expect, const std::string& file, const json* case_names) {
  if (!expect.is_object()) fail(file, "expect", "expected an object of cell name -> expectations");
  if (!case_names) fail(file, "expect", "applies to \"cells\", which this matrix has none of");
  for (const auto& [k, v] : expect.items()) {
    if (std::find(case_names->begin(), case_names->end(), json(k)) == case_names->end()) {
      fail(file, "expect." + k, "names no cell of \"cells\"");
    }
    if (!v.is_object()) fail(file, "expect." + k, "expected an object");
    only_keys(v,
              {"max_non_finite", "max_acne_fraction", "max_leak_fraction", "max_coverage_mismatch_fraction",
               "max_relmse", "max_depth_rel", "gpu_equals_cpu"},
              file, "expect." + k);
    for (const auto& [ek, ev] : v.items()) {
      if (ek == "gpu_equals_cpu" ? !ev.is_boolean() : !(ev.is_number() && ev.get<double>() >= 0.0)) {
        fail(file, "expect." + k + "." + ek,
             ek == "gpu_equals_cpu" ? "expected true or false" : "expected a number >= 0");
      }
    }
  }
}

void check_excludes(const json& excludes, const json& axes, bool has_cases, const std::string& file) {
  if (!excludes.is_array()) fail(file, "exclude", "expected a list of {axis: value} objects");
  for (size_t e = 0; e < excludes.size(); ++e) {
    const std::string at = "exclude[" + std::to_string(e) + "]";
    if (!excludes[e].is_object() || excludes[e].empty()) fail(file, at, "expected a non-empty object");
    for (const auto& [k, v] : excludes[e].items()) {
      if (!axes.contains(k) && !(k == "case" && has_cases)) fail(file, at + "." + k, "is not an axis");
    }
  }
}

// The size of the product, checked before each multiplication: many axes would otherwise wrap it around.
size_t product_size(const std::vector<Axis>& ax, const std::string& file) {
  constexpr size_t kMaxCells = 100000;
  size_t total = 1;
  for (const auto& a : ax) {
    if (total > kMaxCells / a.second.size()) {
      fail(file, "axes", "more than " + std::to_string(kMaxCells) + " cells (the limit of a matrix)");
    }
    total *= a.second.size();
  }
  return total;
}

// The cartesian product of the axes (the first varies slowest) applied to the base, minus the excluded
// combinations; each cell parsed, named and checked against the earlier ones' ids.
void expand(Matrix& m, const json& base, const std::vector<Axis>& ax, const std::vector<json>& case_patches,
            const json& excludes, const std::string& file) {
  const size_t total = product_size(ax, file);
  std::set<std::string> ids;
  for (size_t i = 0; i < total; ++i) {
    json cell = base;
    json coords = json::object();
    size_t rest = i;
    std::vector<size_t> pick(ax.size());
    for (size_t a = ax.size(); a-- > 0;) {
      pick[a] = rest % ax[a].second.size();
      rest /= ax[a].second.size();
    }
    for (size_t a = 0; a < ax.size(); ++a) {
      const json& v = ax[a].second[pick[a]];
      if (a == 0 && !case_patches.empty()) {
        cell.merge_patch(case_patches[pick[a]]);
      } else {
        set_path(cell, ax[a].first, v);
      }
      coords[ax[a].first] = v;
    }
    bool excluded = false;
    for (const auto& ex : excludes) {
      bool all = true;
      for (const auto& [k, v] : ex.items()) all = all && coords[k] == v;
      excluded = excluded || all;
    }
    if (excluded) continue;
    std::string where;
    for (size_t a = 0; a < ax.size(); ++a) {
      where += (where.empty() ? "" : ", ") + ax[a].first + "[" + std::to_string(pick[a]) + "]";
    }
    Scenario s = parse_scenario(cell, file, "axes (" + where + ")");
    if (s.name.empty()) s.name = m.name;
    if (!ids.insert(s.id()).second) fail(file, "axes (" + where + ")", "duplicates an earlier cell");
    m.cells.push_back(std::move(s));
    m.cell_axis_values.push_back(coords);
  }
  if (m.cells.empty()) fail(file, "exclude", "excludes every cell");
}

}  // namespace

void set_rounds(Matrix& m, std::uint32_t rounds, const std::string& where) {
  if (rounds < 1 || rounds > kMaxRounds)
    throw InputError(where + ": " + std::to_string(rounds) + " rounds (from 1 to " + std::to_string(kMaxRounds) + ")");
  for (const Scenario& c : m.cells)
    if (c.frames < rounds)
      throw InputError(where + ": " + std::to_string(rounds) + " rounds need at least " + std::to_string(rounds) +
                       " frames per cell; cell '" + c.name + "' measures " + std::to_string(c.frames));
  m.rounds = rounds;
}

Matrix parse_matrix(const json& doc, const std::string& file, const std::vector<std::string>& axis_order) {
  Matrix m;
  m.file = file;
  if (!doc.is_object()) fail(file, "", std::string("expected an object, got ") + doc.type_name());
  const bool is_matrix = doc.contains("base") || doc.contains("axes") || doc.contains("cells");
  if (!is_matrix) {
    m.cells.push_back(parse_scenario(doc, file));
    m.name = m.cells[0].name;
    m.cell_axis_values.push_back(json::object());
    return m;
  }
  only_keys(doc, {"name", "base", "axes", "exclude", "report", "cells", "expect", "rounds"}, file, "");
  if (doc.contains("name") && !doc["name"].is_string()) {
    fail(file, "name", std::string("expected a string, got ") + doc["name"].type_name());
  }
  if (doc.contains("base") && !doc["base"].is_object()) {
    fail(file, "base", std::string("expected a scenario object, got ") + doc["base"].type_name());
  }
  m.name = doc.value("name", "");
  if (doc.contains("report")) {
    check_report(doc["report"], file);
    m.report = doc["report"];
  }
  const json base = doc.value("base", json::object());
  parse_scenario(base, file, "base");  // validate the base alone first: clearer errors
  const json axes = doc.value("axes", json::object());
  std::vector<Axis> ax = read_axes(axes, file, axis_order);
  std::vector<json> case_patches;
  if (doc.contains("cells")) {
    Axis cases = read_cases(doc["cells"], file, case_patches);
    if (axes.contains("case")) fail(file, "axes.case", "\"case\" is the axis of \"cells\"");
    ax.insert(ax.begin(), std::move(cases));
  }
  for (const Axis& a : ax) m.axes.push_back(a.first);
  if (doc.contains("expect")) {
    check_expect(doc["expect"], file, case_patches.empty() ? nullptr : &ax[0].second);
    m.expect = doc["expect"];
  }
  const json excludes = doc.value("exclude", json::array());
  check_excludes(excludes, axes, !case_patches.empty(), file);
  expand(m, base, ax, case_patches, excludes, file);
  if (doc.contains("rounds")) {
    const json& r = doc["rounds"];
    if (!r.is_number_integer() || r.get<std::int64_t>() < 1 || r.get<std::int64_t>() > kMaxRounds)
      fail(file, "rounds", "expected an integer from 1 to " + std::to_string(kMaxRounds) + ", got " + r.dump());
    set_rounds(m, std::uint32_t(r.get<std::int64_t>()), file + ": field 'rounds'");
  }
  return m;
}

Matrix load_matrix(const std::string& path) {
  const std::string text = read_input_file(path, "scenario file");
  check_json_depth(text, path);
  json doc;
  std::vector<std::string> axis_order;
  try {
    // Parsed once more with insertion order kept, only to learn the order of the axes.
    const nlohmann::ordered_json ordered = nlohmann::ordered_json::parse(text);
    if (ordered.is_object() && ordered.contains("axes") && ordered["axes"].is_object()) {
      for (const auto& [k, v] : ordered["axes"].items()) axis_order.push_back(k);
    }
    doc = json::parse(text);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number like 1e400
    std::string what = e.what();
    for (char& c : what) c = c == '\n' ? ' ' : c;
    throw InputError(path + ": broken JSON: " + what);
  }
  return parse_matrix(doc, path, axis_order);
}

namespace {
// An environment variable as a count >= `min`, or nullopt when unset; InputError naming it when malformed.
std::optional<unsigned> env_count(const char* name, unsigned min) {
  const char* v = std::getenv(name);
  if (!v || !*v) return std::nullopt;
  unsigned n = 0;
  std::istringstream in(v);
  if (!(in >> n) || !in.eof() || n < min)
    throw InputError("--shard auto: " + std::string(name) + "='" + v + "' is not a number >= " + std::to_string(min));
  return n;
}
}  // namespace

Shard parse_shard(const std::string& text) {
  if (text == "auto") {
    // HP_SHARD_INDEX (1-based) and HP_SHARD_COUNT, as a CI matrix job sets them; else a Slurm job array's
    // SLURM_ARRAY_TASK_ID (from SLURM_ARRAY_TASK_MIN) and SLURM_ARRAY_TASK_COUNT.
    std::optional<unsigned> k = env_count("HP_SHARD_INDEX", 1), n = env_count("HP_SHARD_COUNT", 1);
    std::string from = "HP_SHARD_INDEX/HP_SHARD_COUNT";
    if (!k && !n) {
      const std::optional<unsigned> id = env_count("SLURM_ARRAY_TASK_ID", 0);
      const std::optional<unsigned> min = env_count("SLURM_ARRAY_TASK_MIN", 0);
      n = env_count("SLURM_ARRAY_TASK_COUNT", 1);
      if (id && *id >= min.value_or(0)) k = *id - min.value_or(0) + 1;
      from = "SLURM_ARRAY_TASK_ID/SLURM_ARRAY_TASK_COUNT";
    }
    if (!k || !n)
      throw InputError(
          "--shard auto: set HP_SHARD_INDEX (1-based) and HP_SHARD_COUNT, or run as a Slurm job array "
          "(SLURM_ARRAY_TASK_ID, SLURM_ARRAY_TASK_COUNT)");
    if (*k > *n)
      throw InputError("--shard auto: shard " + std::to_string(*k) + " of " + std::to_string(*n) + " (from " + from +
                       ") is outside 1.." + std::to_string(*n));
    return Shard{*k, *n};
  }
  Shard s;
  unsigned k = 0, n = 0;
  char slash = 0;
  std::istringstream in(text);
  if (!(in >> k >> slash >> n) || slash != '/' || !in.eof() || n == 0 || k == 0 || k > n) {
    throw InputError("--shard '" + text + "': expected K/N with 1 <= K <= N, or auto");
  }
  s.index = k;
  s.count = n;
  return s;
}

namespace {
// An axis value as `--filter` spells it: strings as they are, [128, 72] as 128x72, else JSON.
bool value_matches(const json& v, const std::string& text) {
  if (v.is_string()) return v.get<std::string>() == text;
  if (v.dump() == text) return true;
  if (v.is_array() && !v.empty() && std::all_of(v.begin(), v.end(), [](const json& e) { return e.is_number(); })) {
    std::string joined;
    for (const json& e : v) {
      if (!joined.empty()) joined += 'x';  // appended piece by piece: GCC 12 warns falsely (-Wrestrict) on a + b
      joined += e.dump();
    }
    return joined == text;
  }
  return false;
}
}  // namespace

std::vector<bool> select_cells(const Matrix& m, const std::vector<std::string>& filters) {
  std::vector<bool> keep(m.cells.size(), true);
  for (const std::string& f : filters) {
    const size_t eq = f.find('=');
    if (eq == std::string::npos) {  // a cell id
      for (size_t i = 0; i < m.cells.size(); ++i) keep[i] = keep[i] && m.cells[i].id() == f;
      continue;
    }
    const std::string key = f.substr(0, eq), value = f.substr(eq + 1);
    std::string axis;
    for (const std::string& a : m.axes) {
      const size_t dot = a.rfind('.');
      if (a == key || (dot != std::string::npos && a.substr(dot + 1) == key)) axis = a;
    }
    if (axis.empty()) {
      std::string names;
      for (const std::string& a : m.axes) names += (names.empty() ? "" : ", ") + a;
      throw InputError("--filter " + f + ": '" + key + "' is not an axis of matrix '" + m.name +
                       "' (axes: " + (names.empty() ? "none" : names) + ")");
    }
    for (size_t i = 0; i < m.cells.size(); ++i)
      keep[i] = keep[i] && m.cell_axis_values[i].contains(axis) && value_matches(m.cell_axis_values[i][axis], value);
  }
  if (!filters.empty() && std::none_of(keep.begin(), keep.end(), [](bool k) { return k; })) {
    std::string all;
    for (const std::string& f : filters) all += (all.empty() ? "" : " ") + f;
    throw InputError("--filter " + all + ": selects no cell of matrix '" + m.name + "' (run --list shows them)");
  }
  return keep;
}

}  // namespace hp
