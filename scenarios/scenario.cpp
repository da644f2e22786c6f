#include "scenario.hpp"

#include "error.hpp"
#include "cachesim/preset.hpp"
#include "input_file.hpp"
#include "json_depth.hpp"
#include "stable_id.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
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

struct Reader {
  const json& j;
  const std::string& file;
  const std::string& path;

  const json* get(const char* key) const { return j.contains(key) ? &j.at(key) : nullptr; }
  std::string where(const char* key) const { return join(path, key); }

  bool boolean(const char* key, bool def) const {
    const json* v = get(key);
    if (!v) return def;
    if (!v->is_boolean()) fail(file, where(key), std::string("expected true or false, got ") + v->type_name());
    return v->get<bool>();
  }
  double number(const char* key, double def, double lo, double hi) const {
    const json* v = get(key);
    if (!v) return def;
    if (!v->is_number()) fail(file, where(key), std::string("expected a number, got ") + v->type_name());
    const double x = v->get<double>();
    if (!std::isfinite(x) || x < lo || x > hi) {
      std::ostringstream s;
      s << x << " is outside [" << lo << ", " << hi << "]";
      fail(file, where(key), s.str());
    }
    return x;
  }
  int64_t integer(const char* key, int64_t def, int64_t lo, int64_t hi) const {
    const json* v = get(key);
    if (!v) return def;
    if (!v->is_number_integer()) fail(file, where(key), std::string("expected an integer, got ") + v->type_name());
    const int64_t x = v->get<int64_t>();
    if (x < lo || x > hi) {
      fail(file, where(key), std::to_string(x) + " is outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    }
    return x;
  }
  std::string string(const char* key, const std::string& def) const {
    const json* v = get(key);
    if (!v) return def;
    if (!v->is_string()) fail(file, where(key), std::string("expected a string, got ") + v->type_name());
    return v->get<std::string>();
  }
  std::string choice(const char* key, const std::string& def, const std::vector<std::string>& choices) const {
    const std::string s = string(key, def);
    for (const auto& c : choices) {
      if (s == c) return s;
    }
    std::string list;
    for (const auto& c : choices) list += (list.empty() ? "" : ", ") + c;
    fail(file, where(key), "'" + s + "' is not one of " + list);
  }
  std::optional<glm::vec3> vec3(const char* key) const {
    const json* v = get(key);
    if (!v) return std::nullopt;
    if (!v->is_array() || v->size() != 3) fail(file, where(key), "expected an array of three numbers");
    glm::vec3 out(0.0f);
    for (int i = 0; i < 3; ++i) {
      if (!(*v)[i].is_number()) fail(file, where(key) + "[" + std::to_string(i) + "]", "expected a number");
      out[i] = (*v)[i].get<float>();
      if (!std::isfinite(out[i])) fail(file, where(key) + "[" + std::to_string(i) + "]", "not finite");
    }
    return out;
  }
  const json* object(const char* key, const std::set<std::string>& allowed) const {
    const json* v = get(key);
    if (v) only_keys(*v, allowed, file, where(key));
    return v;
  }
};

const std::set<std::string> kTopKeys = {"name", "scene", "camera", "light", "resolution", "reversed_z", "passes",
                                        "geometry", "jitter", "shadow_offset", "bias", "reflection_scale",
                                        "roughness_threshold", "reflection_shadows", "bvh", "frames", "warmup",
                                        "counters", "query_overhead", "overlap", "seed", "cache_preset", "inject", "trace",
                                        "reflection_path", "sort", "writeback", "transform", "error"};

json vec_json(const std::optional<glm::vec3>& v) {
  if (!v) return nullptr;
  return json::array({(*v).x, (*v).y, (*v).z});
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
  only_keys(j, kTopKeys, file, path);
  Reader r{j, file, path};
  Scenario s;
  s.name = r.string("name", "");
  s.scene = r.string("scene", s.scene);
  if (s.scene.empty()) fail(file, r.where("scene"), "empty scene");
  if (const json* c = r.object("camera", {"position", "target", "fov"})) {
    Reader cr{*c, file, r.where("camera")};
    s.camera_position = cr.vec3("position");
    s.camera_target = cr.vec3("target");
    if (c->contains("fov")) s.camera_fov_deg = float(cr.number("fov", 45.0, 1.0, 179.0));
    if (s.camera_position && s.camera_target && *s.camera_position == *s.camera_target) {
      fail(file, cr.where("target"), "equals camera.position");
    }
  }
  if (const json* l = r.object("light", {"direction", "intensity"})) {
    Reader lr{*l, file, r.where("light")};
    s.light_direction = lr.vec3("direction");
    if (s.light_direction && glm::length(*s.light_direction) == 0.0f) fail(file, lr.where("direction"), "zero vector");
    if (l->contains("intensity")) s.light_intensity = float(lr.number("intensity", 3.0, 0.0, 1e6));
  }
  FrameSettings& f = s.frame;
  if (const json* res = r.get("resolution")) {
    if (!res->is_array() || res->size() != 2 || !(*res)[0].is_number_integer() || !(*res)[1].is_number_integer()) {
      fail(file, r.where("resolution"), "expected [width, height] integers");
    }
    const int64_t w = (*res)[0].get<int64_t>(), h = (*res)[1].get<int64_t>();
    if (w < 1 || h < 1 || w > kMaxImageSide || h > kMaxImageSide) {
      fail(file, r.where("resolution"), std::to_string(w) + "x" + std::to_string(h) + " is outside 1.." +
                                            std::to_string(kMaxImageSide) + " per side");
    }
    f.width = uint32_t(w);
    f.height = uint32_t(h);
  }
  f.reversed_z = r.boolean("reversed_z", false);
  f.rt.shadows = true;
  f.rt.reflections = true;
  if (const json* p = r.object("passes", {"shadows", "reflections"})) {
    Reader pr{*p, file, r.where("passes")};
    f.rt.shadows = pr.boolean("shadows", true);
    f.rt.reflections = pr.boolean("reflections", true);
  }
  f.geometry = parse_geometry_layout(r.choice("geometry", "indexed", {"indexed", "soup"}));
  f.rt.jitter = parse_jitter_mode(r.choice("jitter", "per-thread", {"shared", "per-thread"}));
  f.rt.offset = parse_shadow_offset(r.choice("shadow_offset", "normal-bias", {"normal-bias", "robust"}));
  f.rt.bias = float(r.number("bias", 0.1, 0.0, 1e6));
  const double scale = r.number("reflection_scale", 1.0, 0.25, 1.0);
  if (scale != 1.0 && scale != 0.5 && scale != 0.25) fail(file, r.where("reflection_scale"), "must be 1, 0.5 or 0.25");
  f.rt.reflection_divisor = uint32_t(std::lround(1.0 / scale));
  f.rt.roughness_threshold = float(r.number("roughness_threshold", 0.35, 0.0, 1.01));
  f.rt.reflection_shadows = r.boolean("reflection_shadows", true);
  f.rt.reflection_path = parse_reflection_path(r.choice("reflection_path", "direct", {"direct", "compact"}));
  f.rt.sort = parse_sort_key(r.choice("sort", "none", {"none", "octant", "direction", "origin"}));
  f.rt.writeback = parse_writeback(r.choice("writeback", "index", {"index", "reproject"}));
  if (f.rt.reflection_path == ReflectionPath::direct && (f.rt.sort != SortKey::none || f.rt.writeback != Writeback::index)) {
    fail(file, r.where("sort"), "sort and writeback apply to \"reflection_path\": \"compact\" only");
  }
  if (const json* b = r.object("bvh", {"buckets", "full_sweep", "leaf_size", "granularity", "traversal_cost"})) {
    Reader br{*b, file, r.where("bvh")};
    f.bvh.buckets = int(br.integer("buckets", 12, 2, 1024));
    f.bvh.full_sweep = br.boolean("full_sweep", false);
    f.bvh.max_leaf_size = int(br.integer("leaf_size", 4, 1, 1 << 20));
    f.bvh.granularity = br.choice("granularity", "triangle", {"triangle", "object"}) == "object"
                            ? bvh::Granularity::object
                            : bvh::Granularity::triangle;
    f.bvh.traversal_cost = float(br.number("traversal_cost", 0.5, 1e-6, 1e6));
  }
  s.frames = uint32_t(r.integer("frames", 10, 1, 100000));
  s.warmup = uint32_t(r.integer("warmup", 3, 0, 100000));
  f.rt.counters = r.boolean("counters", true);
  s.query_overhead = r.boolean("query_overhead", false);
  s.overlap = r.boolean("overlap", true);
  f.rt.seed = uint32_t(r.integer("seed", 1, 0, 0xFFFFFFFFll));
  s.cache_preset = r.string("cache_preset", s.cache_preset);
  if (r.get("cache_preset")) {
    try {
      (void)cachesim::find_preset(s.cache_preset);  // an unknown name or a broken preset file fails here, not mid-run
    } catch (const InputError& e) {
      fail(file, r.where("cache_preset"), e.what());
    }
  }
  if (const json* t = r.object("trace", {"passes", "sample_every", "sample_block", "scale_model", "keep", "image_layout"})) {
    Reader tr{*t, file, r.where("trace")};
    if (const json* ps = tr.get("passes")) {
      if (!ps->is_array()) fail(file, tr.where("passes"), "expected a list of pass names");
      for (size_t i = 0; i < ps->size(); ++i) {
        const json& v = (*ps)[i];
        const std::string where = tr.where("passes") + "[" + std::to_string(i) + "]";
        if (!v.is_string() || (v != "shadows" && v != "reflections")) fail(file, where, "expected \"shadows\" or \"reflections\"");
        if (std::find(s.trace_passes.begin(), s.trace_passes.end(), v.get<std::string>()) != s.trace_passes.end())
          fail(file, where, "\"" + v.get<std::string>() + "\" is listed twice");
        s.trace_passes.push_back(v.get<std::string>());
      }
    }
    s.trace_sample_every = uint32_t(tr.integer("sample_every", 1, 1, 0xFFFFF));
    s.trace_sample_block = uint32_t(tr.integer("sample_block", 1, 1, 2048));
    if ((s.trace_sample_block & (s.trace_sample_block - 1)) != 0) fail(file, tr.where("sample_block"), "must be a power of two");
    s.trace_scale_model = tr.boolean("scale_model", true);
    s.trace_keep = tr.boolean("keep", false);
    s.trace_tiled_images = tr.choice("image_layout", "tiled", {"tiled", "linear"}) == "tiled";
  }
  if (const json* in = r.object("inject", {"pass", "fraction"})) {
    Reader ir{*in, file, r.where("inject")};
    s.inject_pass = ir.choice("pass", "shadows", {"shadows"});
    s.inject_fraction = float(ir.number("fraction", 0.0, 0.0, 1.0));
  }
  if (s.inject_fraction > 0.0f && !f.rt.shadows) fail(file, r.where("inject"), "injects work into shadows, which are off");
  f.rt.inject_shadow_fraction = s.inject_fraction;
  if (const json* t = r.object("transform", {"scale", "translate"})) {
    Reader tr{*t, file, r.where("transform")};
    s.world_scale = tr.number("scale", 1.0, 1e-6, 1e6);
    if (const auto v = tr.vec3("translate")) {
      s.world_translate = glm::dvec3(*v);
      if (glm::length(s.world_translate) > 1e7) fail(file, tr.where("translate"), "farther than 1e7 from the origin");
    }
  }
  if (const json* e = r.object("error", {"frames", "reference_samples", "threshold", "flip"})) {
    Reader er{*e, file, r.where("error")};
    s.error = true;
    s.error_frames = uint32_t(er.integer("frames", 16, 1, 4096));
    s.reference_samples = uint32_t(er.integer("reference_samples", 256, 1, 1 << 16));
    s.error_threshold = er.number("threshold", 0.1, 0.0, 1e6);
    s.error_flip = er.boolean("flip", true);
  }
  for (const std::string& p : s.trace_passes) {
    if ((p == "shadows" && !f.rt.shadows) || (p == "reflections" && !f.rt.reflections)) {
      fail(file, r.where("trace.passes"), "traces the " + p + " pass, which is off");
    }
  }
  return s;
}

json Scenario::canonical() const {
  const FrameSettings& f = frame;
  json j;
  j["scene"] = scene;
  j["camera"] = {{"position", vec_json(camera_position)}, {"target", vec_json(camera_target)},
                 {"fov", camera_fov_deg ? json(*camera_fov_deg) : json(nullptr)}};
  j["light"] = {{"direction", vec_json(light_direction)},
                {"intensity", light_intensity ? json(*light_intensity) : json(nullptr)}};
  j["resolution"] = {f.width, f.height};
  j["reversed_z"] = f.reversed_z;
  j["passes"] = {{"shadows", f.rt.shadows}, {"reflections", f.rt.reflections}};
  j["geometry"] = to_string(f.geometry);
  j["jitter"] = to_string(f.rt.jitter);
  j["shadow_offset"] = to_string(f.rt.offset);
  j["bias"] = f.rt.bias;
  j["reflection_scale"] = 1.0 / f.rt.reflection_divisor;
  j["roughness_threshold"] = f.rt.roughness_threshold;
  j["reflection_shadows"] = f.rt.reflection_shadows;
  // Only non-default compaction settings enter the canonical form, so the ids of every direct-path
  // scenario (and the committed baselines keyed by them) stay as they were.
  if (f.rt.reflection_path != ReflectionPath::direct) {
    j["reflection_path"] = to_string(f.rt.reflection_path);
    j["sort"] = to_string(f.rt.sort);
    j["writeback"] = to_string(f.rt.writeback);
  }
  j["bvh"] = {{"buckets", f.bvh.buckets},
              {"full_sweep", f.bvh.full_sweep},
              {"leaf_size", f.bvh.max_leaf_size},
              {"granularity", f.bvh.granularity == bvh::Granularity::object ? "object" : "triangle"},
              {"traversal_cost", f.bvh.traversal_cost}};
  j["frames"] = frames;
  j["warmup"] = warmup;
  j["counters"] = f.rt.counters;
  j["seed"] = f.rt.seed;
  j["cache_preset"] = cache_preset;
  j["inject"] = {{"pass", inject_pass}, {"fraction", inject_fraction}};
  j["trace"] = {{"passes", trace_passes},
                {"sample_every", trace_sample_every},
                {"image_layout", trace_tiled_images ? "tiled" : "linear"}};  // keep: where files go, not what runs
  if (trace_sample_block != 1) j["trace"]["sample_block"] = trace_sample_block;  // only when set: ids stay
  if (trace_sample_every > 1) j["trace"]["scale_model"] = trace_scale_model;  // irrelevant to a full trace
  // Like the compaction keys, a transform and error metrics enter only when set, so the ids of the
  // scenarios without them stay as they were.
  if (world_scale != 1.0 || world_translate != glm::dvec3(0.0)) {
    j["transform"] = {{"scale", world_scale},
                      {"translate", {world_translate.x, world_translate.y, world_translate.z}}};
  }
  if (query_overhead) j["query_overhead"] = true;  // only when set, like the keys above: ids stay
  if (!overlap) j["overlap"] = false;              // only when off: ids stay
  if (error) {
    j["error"] = {{"frames", error_frames}, {"reference_samples", reference_samples},
                  {"threshold", error_threshold}, {"flip", error_flip}};
  }
  return j;  // nlohmann::json objects are key-sorted: dump() is canonical
}

std::string Scenario::id() const {
  return stable_id(canonical().dump());
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
  only_keys(doc, {"name", "base", "axes", "exclude", "report", "cells", "expect"}, file, "");
  if (doc.contains("name") && !doc["name"].is_string()) {
    fail(file, "name", std::string("expected a string, got ") + doc["name"].type_name());
  }
  if (doc.contains("base") && !doc["base"].is_object()) {
    fail(file, "base", std::string("expected a scenario object, got ") + doc["base"].type_name());
  }
  m.name = doc.value("name", "");
  if (doc.contains("report")) {
    // The report sections' shape is checked here, so a typo fails before the matrix runs, not in `report`
    // afterwards; the metric names are checked by `report` (reports/tradeoff.cpp), which knows them.
    const json& rep = doc["report"];
    if (!rep.is_object()) fail(file, "report", "expected an object of report sections");
    only_keys(rep, {"tradeoffs", "cache_sampling", "depth_error"}, file, "report");
    for (const char* k : {"cache_sampling", "depth_error"}) {
      if (rep.contains(k) && !rep[k].is_boolean()) fail(file, join("report", k), "expected true or false");
    }
    if (rep.contains("tradeoffs")) {
      const json& ts = rep["tradeoffs"];
      if (!ts.is_array()) fail(file, "report.tradeoffs", "expected a list of trade-off objects");
      for (size_t i = 0; i < ts.size(); ++i) {
        const std::string at = "report.tradeoffs[" + std::to_string(i) + "]";
        only_keys(ts[i], {"title", "x", "y", "x_label", "y_label", "log_x", "log_y", "columns"}, file, at);
        for (const char* k : {"x", "y"}) {
          if (!ts[i].contains(k) || !ts[i][k].is_string()) fail(file, join(at, k), "a metric name, missing or not a string");
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
    m.report = rep;
  }
  const json base = doc.value("base", json::object());
  parse_scenario(base, file, "base");  // validate the base alone first: clearer errors
  const json axes = doc.value("axes", json::object());
  if (!axes.is_object()) fail(file, "axes", "expected an object of key path -> list of values");
  std::vector<std::pair<std::string, json>> ax;
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
    m.axes.push_back(k);
  }
  // "cells": named scenarios merged onto the base (JSON merge patch), a first axis called "case" whose
  // values are the cells' names: a suite of unlike cases (hard_cases.json) rather than a product.
  std::vector<json> case_patches;
  if (doc.contains("cells")) {
    const json& cells = doc["cells"];
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
      case_patches.push_back(cells[c]);
    }
    if (axes.contains("case")) fail(file, "axes.case", "\"case\" is the axis of \"cells\"");
    ax.insert(ax.begin(), {"case", names});
    m.axes.insert(m.axes.begin(), "case");
  }
  if (doc.contains("expect")) {
    if (!doc["expect"].is_object()) fail(file, "expect", "expected an object of cell name -> expectations");
    if (case_patches.empty()) fail(file, "expect", "applies to \"cells\", which this matrix has none of");
    for (const auto& [k, v] : doc["expect"].items()) {
      const json& names = ax[0].second;
      if (std::find(names.begin(), names.end(), json(k)) == names.end()) fail(file, "expect." + k, "names no cell of \"cells\"");
      if (!v.is_object()) fail(file, "expect." + k, "expected an object");
      only_keys(v, {"max_non_finite", "max_acne_fraction", "max_leak_fraction", "max_coverage_mismatch_fraction",
                    "max_relmse", "max_depth_rel", "gpu_equals_cpu"}, file, "expect." + k);
      for (const auto& [ek, ev] : v.items()) {
        if (ek == "gpu_equals_cpu" ? !ev.is_boolean() : !(ev.is_number() && ev.get<double>() >= 0.0)) {
          fail(file, "expect." + k + "." + ek, ek == "gpu_equals_cpu" ? "expected true or false" : "expected a number >= 0");
        }
      }
    }
    m.expect = doc["expect"];
  }
  const json excludes = doc.value("exclude", json::array());
  if (!excludes.is_array()) fail(file, "exclude", "expected a list of {axis: value} objects");
  for (size_t e = 0; e < excludes.size(); ++e) {
    if (!excludes[e].is_object() || excludes[e].empty()) fail(file, "exclude[" + std::to_string(e) + "]", "expected a non-empty object");
    for (const auto& [k, v] : excludes[e].items()) {
      if (!axes.contains(k) && !(k == "case" && !case_patches.empty())) {
        fail(file, "exclude[" + std::to_string(e) + "]." + k, "is not an axis");
      }
    }
  }
  // Checked before each multiplication: many axes would otherwise wrap the product around.
  constexpr size_t kMaxCells = 100000;
  size_t total = 1;
  for (const auto& a : ax) {
    if (total > kMaxCells / a.second.size()) {
      fail(file, "axes", "more than " + std::to_string(kMaxCells) + " cells (the limit of a matrix)");
    }
    total *= a.second.size();
  }
  std::set<std::string> ids;
  for (size_t i = 0; i < total; ++i) {
    json cell = base;
    json coords = json::object();
    size_t rest = i;
    // The first axis varies slowest.
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

Shard parse_shard(const std::string& text) {
  Shard s;
  unsigned k = 0, n = 0;
  char slash = 0;
  std::istringstream in(text);
  if (!(in >> k >> slash >> n) || slash != '/' || !in.eof() || n == 0 || k == 0 || k > n) {
    throw InputError("--shard '" + text + "': expected K/N with 1 <= K <= N");
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
      throw InputError("--filter " + f + ": '" + key + "' is not an axis of matrix '" + m.name + "' (axes: " +
                       (names.empty() ? "none" : names) + ")");
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
