#include "cell_record.hpp"

#include "error.hpp"

namespace hp {

using json = nlohmann::json;

namespace {

constexpr const char* kSchema = "hybridprof.cell";
constexpr int kVersion = 1;

json optional_number(const std::optional<double>& v) { return v ? json(*v) : json(nullptr); }

// The line's fields, read with errors that name the line and the field.
struct LineReader {
  const json& line;
  const std::string& where;

  [[noreturn]] void fail(const std::string& why) const { throw InputError(where + ": " + why); }
  // A member that is present and not null.
  const json* get(const char* key) const {
    const auto it = line.find(key);
    return it == line.end() || it->is_null() ? nullptr : &*it;
  }
  std::string optional_string(const char* key) const {
    const json* v = get(key);
    if (!v) return "";
    if (!v->is_string()) fail(std::string("field '") + key + "' is not a string");
    return v->get<std::string>();
  }
  const json* object(const char* key) const {
    const json* v = get(key);
    if (v && !v->is_object()) fail(std::string("field '") + key + "' is not an object");
    return v;
  }
  double number(const json& j, const std::string& field) const {
    if (!j.is_number()) fail("field '" + field + "' missing or not a number");
    return j.get<double>();
  }
  std::uint64_t count(const json& j, const std::string& field) const {
    // A line read from text holds counts as unsigned; one built in memory may hold a non-negative int.
    if (!j.is_number_integer() || (!j.is_number_unsigned() && j.get<std::int64_t>() < 0)) {
      fail("field '" + field + "' is not a count");
    }
    return j.get<std::uint64_t>();
  }
  std::optional<double> nullable_number(const json& obj, const char* key, const std::string& field) const {
    if (!obj.contains(key) || obj[key].is_null()) return std::nullopt;
    return number(obj[key], field);
  }
};

CellBvh parse_bvh(const LineReader& r, const json& b) {
  const auto member = [&](const char* key) -> const json& {
    static const json missing;
    return b.contains(key) ? b[key] : missing;
  };
  CellBvh out;
  out.build_ms = r.number(member("build_ms"), "bvh.build_ms");
  out.nodes = r.count(member("nodes"), "bvh.nodes");
  out.leaves = r.count(member("leaves"), "bvh.leaves");
  out.max_depth = int(r.count(member("max_depth"), "bvh.max_depth"));
  out.sah_cost = r.number(member("sah_cost"), "bvh.sah_cost");
  return out;
}

CellAccel parse_accel(const LineReader& r, const json& a) {
  const auto member = [&](const char* key) -> const json& {
    static const json missing;
    return a.contains(key) ? a[key] : missing;
  };
  const auto text = [&](const char* key) {
    if (!member(key).is_string()) r.fail(std::string("field 'accel.") + key + "' missing or not a string");
    return member(key).get<std::string>();
  };
  const auto flag = [&](const char* key) {
    if (!member(key).is_boolean()) r.fail(std::string("field 'accel.") + key + "' missing or not a boolean");
    return member(key).get<bool>();
  };
  CellAccel out;
  out.traversal = text("traversal");
  out.order = text("order");
  if (a.contains("layout")) out.layout = text("layout");
  if (a.contains("blas_count")) out.blas_count = r.count(member("blas_count"), "accel.blas_count");
  if (a.contains("instances")) out.instances = r.count(member("instances"), "accel.instances");
  out.compacted = flag("compacted");
  out.build_ms = r.number(member("build_ms"), "accel.build_ms");
  out.build_timed_on_device = flag("build_timed_on_device");
  out.triangles = r.count(member("triangles"), "accel.triangles");
  out.blas_bytes = r.count(member("blas_bytes"), "accel.blas_bytes");
  out.tlas_bytes = r.count(member("tlas_bytes"), "accel.tlas_bytes");
  out.scratch_bytes = r.count(member("scratch_bytes"), "accel.scratch_bytes");
  return out;
}

CellRoundVisit read_visit(const LineReader& r, const json& v, const std::string& prefix) {
  const auto member = [&](const char* key) -> const json& {
    static const json missing;
    return v.contains(key) ? v[key] : missing;
  };
  CellRoundVisit c;
  c.round = std::uint32_t(r.count(member("round"), prefix + "round"));
  c.position = std::uint32_t(r.count(member("position"), prefix + "position"));
  c.cells = std::uint32_t(r.count(member("cells"), prefix + "cells"));
  c.frames = std::uint32_t(r.count(member("frames"), prefix + "frames"));
  if (!member("rebuilt").is_boolean()) r.fail("field '" + prefix + "rebuilt' missing or not a boolean");
  c.rebuilt = v["rebuilt"].get<bool>();
  const json& l = member("load_1min");
  if (!l.is_object()) r.fail("field '" + prefix + "load_1min' missing or not an object");
  c.load = CellLoad{r.nullable_number(l, "start", prefix + "load_1min.start"),
                    r.nullable_number(l, "end", prefix + "load_1min.end")};
  return c;
}

CellRounds parse_rounds(const LineReader& r, const json& j) {
  const auto member = [&](const json& o, const char* key) -> const json& {
    static const json missing;
    return o.contains(key) ? o[key] : missing;
  };
  CellRounds out;
  out.count = std::uint32_t(r.count(member(j, "count"), "rounds.count"));
  out.seed = r.count(member(j, "seed"), "rounds.seed");
  const json& visits = member(j, "visits");
  if (!visits.is_array()) r.fail("field 'rounds.visits' missing or not a list");
  for (const json& v : visits) {
    if (!v.is_object()) r.fail("field 'rounds.visits' holds a non-object");
    CellRoundVisit c = read_visit(r, v, "rounds.visits.");
    out.visits.push_back(c);
  }
  return out;
}

CellExpect parse_expect(const LineReader& r, const json& e) {
  CellExpect out;
  out.spec = e.contains("spec") ? e["spec"] : json();
  if (!out.spec.is_object()) r.fail("field 'expect.spec' missing or not an object");
  if (!e.contains("unmet") || !e["unmet"].is_array()) r.fail("field 'expect.unmet' missing or not a list");
  for (const json& u : e["unmet"]) {
    if (!u.is_string()) r.fail("field 'expect.unmet' holds a non-string");
    out.unmet.push_back(u.get<std::string>());
  }
  return out;
}

}  // namespace

void to_json(json& j, const CellBvh& b) {
  j = {{"build_ms", b.build_ms},
       {"nodes", b.nodes},
       {"leaves", b.leaves},
       {"max_depth", b.max_depth},
       {"sah_cost", b.sah_cost}};
}

void to_json(json& j, const CellAccel& a) {
  j = {{"traversal", a.traversal},   {"order", a.order},
       {"layout", a.layout},         {"blas_count", a.blas_count},
       {"instances", a.instances},   {"compacted", a.compacted},
       {"build_ms", a.build_ms},     {"build_timed_on_device", a.build_timed_on_device},
       {"triangles", a.triangles},   {"blas_bytes", a.blas_bytes},
       {"tlas_bytes", a.tlas_bytes}, {"scratch_bytes", a.scratch_bytes}};
}

void to_json(json& j, const CellRoundVisit& v) {
  j = {{"round", v.round},
       {"position", v.position},
       {"cells", v.cells},
       {"frames", v.frames},
       {"rebuilt", v.rebuilt},
       {"load_1min", {{"start", optional_number(v.load.start)}, {"end", optional_number(v.load.end)}}}};
}

CellRoundVisit parse_round_visit(const json& v, const std::string& where) {
  const LineReader r{v, where};
  if (!v.is_object()) r.fail("field 'visit' missing or not an object");
  return read_visit(r, v, "visit.");
}

void to_json(json& j, const CellRounds& r) {
  json visits = json::array();
  for (const CellRoundVisit& v : r.visits) visits.push_back(v);
  j = {{"count", r.count}, {"seed", r.seed}, {"visits", std::move(visits)}};
}

bool operator==(const CellRecord& a, const CellRecord& b) {
  const auto same_timing = [](const TimingResult& x, const TimingResult& y) {
    return x.environment == y.environment && x.timings == y.timings && x.summary == y.summary &&
           x.counters == y.counters;
  };
  return a.id == b.id && a.matrix == b.matrix && a.name == b.name && a.axes == b.axes && a.config == b.config &&
         same_timing(a.result, b.result) && a.load_1min == b.load_1min && a.rounds == b.rounds &&
         a.triangles == b.triangles && a.bvh == b.bvh && a.accel == b.accel && a.cache == b.cache &&
         a.error == b.error && a.report == b.report && a.expect == b.expect && a.images == b.images &&
         a.wall_s == b.wall_s;
}

json to_json(const CellRecord& r) {
  json line;
  line["schema"] = kSchema;
  line["version"] = kVersion;
  line["id"] = r.id;
  line["matrix"] = r.matrix;
  line["name"] = r.name;
  line["axes"] = r.axes;
  line["config"] = r.config;
  line["result"] = timing_result_json(r.result.environment, r.result.timings);
  if (r.load_1min)
    line["load_1min"] = {{"start", optional_number(r.load_1min->start)}, {"end", optional_number(r.load_1min->end)}};
  if (r.triangles) line["scene"] = {{"triangles", *r.triangles}};
  if (r.bvh) line["bvh"] = *r.bvh;
  if (r.accel) line["accel"] = *r.accel;
  if (r.rounds) line["rounds"] = *r.rounds;
  if (!r.cache.is_null()) line["cache"] = r.cache;
  if (!r.error.is_null()) line["error"] = r.error;
  if (!r.report.is_null()) line["report"] = r.report;
  if (r.expect) line["expect"] = {{"spec", r.expect->spec}, {"unmet", r.expect->unmet}};
  line["images"] = r.images;
  line["wall_s"] = r.wall_s;
  return line;
}

CellRecord parse_cell_record(const json& line, const std::string& where) {
  if (!line.is_object() || line.value("schema", json()) != kSchema) {
    throw InputError(where + ": not a hybridprof cell (field 'schema' is not \"hybridprof.cell\")");
  }
  const LineReader r{line, where};
  if (!line.contains("result")) r.fail("field 'result' missing");
  const auto timing = [&] {
    try {
      return parse_timing_result(line["result"]);
    } catch (const InputError& e) {
      r.fail(std::string("result: ") + e.what());
    }
  };
  CellRecord c(timing());
  if (!line.contains("id") || !line["id"].is_string()) r.fail("field 'id' missing or not a string");
  c.id = line["id"].get<std::string>();
  c.matrix = r.optional_string("matrix");
  c.name = r.optional_string("name");
  if (const json* a = r.object("axes")) c.axes = *a;
  if (line.contains("config")) c.config = line["config"];
  if (const json* l = r.object("load_1min")) {
    c.load_1min =
        CellLoad{r.nullable_number(*l, "start", "load_1min.start"), r.nullable_number(*l, "end", "load_1min.end")};
  }
  if (const json* s = r.object("scene"); s && s->contains("triangles")) {
    c.triangles = r.count((*s)["triangles"], "scene.triangles");
  }
  if (const json* b = r.object("bvh")) c.bvh = parse_bvh(r, *b);
  if (const json* a = r.object("accel")) c.accel = parse_accel(r, *a);
  if (const json* x = r.object("rounds")) c.rounds = parse_rounds(r, *x);
  if (const json* v = r.object("cache")) c.cache = *v;
  if (const json* v = r.object("report")) c.report = *v;
  if (const json* v = r.object("error")) c.error = *v;
  if (const json* e = r.object("expect")) c.expect = parse_expect(r, *e);
  if (const json* im = r.object("images")) {
    for (const auto& [k, v] : im->items()) {
      if (!v.is_string()) r.fail("field 'images." + k + "' is not a string (a path)");
      c.images[k] = v.get<std::string>();
    }
  }
  if (const json* w = r.get("wall_s")) c.wall_s = r.number(*w, "wall_s");
  return c;
}

}  // namespace hp
