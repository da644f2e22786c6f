#include "cachesim/preset.hpp"

#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "error.hpp"
#include "input_file.hpp"
#include "json_depth.hpp"

namespace hp::cachesim {

namespace {

using nlohmann::json;

// Walks one JSON object, consuming keys; every error names the origin and the full key path.
struct Fields {
  const json& obj;
  std::string origin, path;
  std::set<std::string> used;

  [[noreturn]] void fail(const std::string& key, const std::string& why) const {
    throw InputError(origin + ": " + path + key + ": " + why);
  }
  const json* find(const std::string& key) {
    used.insert(key);
    auto it = obj.find(key);
    return it == obj.end() ? nullptr : &*it;
  }
  const json& need(const std::string& key) {
    const json* v = find(key);
    if (!v) fail(key, "missing");
    return *v;
  }
  uint64_t positive(const std::string& key, const json* v) {
    if (!v->is_number_unsigned() || v->get<uint64_t>() == 0) fail(key, "expected a positive integer, got " + v->dump());
    return v->get<uint64_t>();
  }
  uint32_t u32(const std::string& key) {
    uint64_t v = positive(key, &need(key));
    if (v > 0xFFFFFFFFull) fail(key, "too large");
    return uint32_t(v);
  }
  uint32_t u32_or(const std::string& key, uint32_t fallback) {
    const json* v = find(key);
    if (!v) return fallback;
    uint64_t x = positive(key, v);
    if (x > 0xFFFFFFFFull) fail(key, "too large");
    return uint32_t(x);
  }
  std::string string(const std::string& key, bool required = true) {
    const json* v = required ? &need(key) : find(key);
    if (!v) return {};
    if (!v->is_string()) fail(key, "expected a string, got " + v->dump());
    return v->get<std::string>();
  }
  void no_unknown_keys() const {
    for (auto it = obj.begin(); it != obj.end(); ++it)
      if (!used.count(it.key())) fail(it.key(), "unknown key");
  }
};

CacheConfig parse_cache(const json& j, const std::string& origin, const std::string& key) {
  if (!j.is_object()) throw InputError(origin + ": " + key + ": expected an object");
  Fields f{j, origin, key + "."};
  CacheConfig c;
  c.size_bytes = f.positive("size_bytes", &f.need("size_bytes"));
  c.line_bytes = f.u32("line_bytes");
  c.sector_bytes = f.u32_or("sector_bytes", c.line_bytes);
  c.ways = f.u32("ways");
  c.channels = f.u32_or("channels", 1);
  c.channel_interleave_bytes = f.u32_or("channel_interleave_bytes", 0);
  const std::string repl = f.string("replacement", false);
  if (repl.empty() || repl == "lru")
    c.replacement = Replacement::lru;
  else if (repl == "fifo")
    c.replacement = Replacement::fifo;
  else if (repl == "random")
    c.replacement = Replacement::random;
  else
    f.fail("replacement", "'" + repl + "' is not lru, fifo or random");
  if (const json* s = f.find("seed")) {
    if (!s->is_number_unsigned()) f.fail("seed", "expected a non-negative integer, got " + s->dump());
    c.seed = s->get<uint64_t>();
  }
  f.no_unknown_keys();
  if (std::string err = check_config(c); !err.empty()) throw InputError(origin + ": " + key + "." + err);
  return c;
}

std::filesystem::path exe_dir() {
  std::error_code ec;
  auto p = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::filesystem::path() : p.parent_path();
}

}  // namespace

const char* to_string(HitCounting c) {
  switch (c) {
    case HitCounting::request: return "request";
    case HitCounting::quarter_wave: return "quarter_wave";
    case HitCounting::lane: return "lane";
  }
  return "?";
}

bool parse_hit_counting(std::string_view text, HitCounting& out) {
  for (HitCounting c : {HitCounting::request, HitCounting::quarter_wave, HitCounting::lane})
    if (text == to_string(c)) {
      out = c;
      return true;
    }
  return false;
}

Preset parse_preset(std::string_view text, const std::string& origin) {
  check_json_depth(text, origin);
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {  // parse_error, and out_of_range for a number like 1e400
    throw InputError(origin + ": invalid JSON: " + e.what());
  }
  if (!j.is_object()) throw InputError(origin + ": expected a JSON object");
  Fields f{j, origin, ""};
  Preset p;
  p.name = f.string("name");
  p.description = f.string("description", false);
  const json& src = f.need("sources");
  if (!src.is_array() || src.empty()) f.fail("sources", "expected a non-empty array of strings");
  for (size_t i = 0; i < src.size(); ++i) {
    if (!src[i].is_string()) f.fail("sources[" + std::to_string(i) + "]", "expected a string");
    p.sources.push_back(src[i].get<std::string>());
  }
  p.compute_units = f.u32("compute_units");
  if (p.compute_units > 4096) f.fail("compute_units", "at most 4096");
  p.wave_width = f.u32("wave_width");
  if (p.wave_width > 1024) f.fail("wave_width", "at most 1024");
  p.max_waves_per_cu = f.u32("max_waves_per_cu");
  if (p.max_waves_per_cu > 1024) f.fail("max_waves_per_cu", "at most 1024");
  const std::string co = f.string("coalescing");
  if (co == "line")
    p.coalescing = Coalescing::line;
  else if (co == "sector")
    p.coalescing = Coalescing::sector;
  else
    f.fail("coalescing", "'" + co + "' is not line or sector");
  if (f.find("l1_hit_counting")) {
    const std::string hc = f.string("l1_hit_counting");
    if (!parse_hit_counting(hc, p.l1_hit_counting))
      f.fail("l1_hit_counting", "'" + hc + "' is not request, quarter_wave or lane");
  }
  p.l1 = parse_cache(f.need("l1"), origin, "l1");
  p.l2 = parse_cache(f.need("l2"), origin, "l2");
  if (p.l1.size_bytes * p.compute_units > kMaxCacheBytes)
    f.fail("l1", "size_bytes x compute_units = " + std::to_string(p.l1.size_bytes * p.compute_units) +
                     " bytes of L1 in all exceeds the limit of 1 GiB");
  f.no_unknown_keys();
  if (p.l1.line_bytes != p.l2.line_bytes)
    throw InputError(origin + ": l2.line_bytes: must equal l1.line_bytes (the L1 forwards whole lines)");
  if (p.l1.sector_bytes != p.l2.sector_bytes)
    throw InputError(origin + ": l2.sector_bytes: must equal l1.sector_bytes");
  return p;
}

Preset load_preset_file(const std::filesystem::path& path) {
  Preset p = parse_preset(read_input_file(path, "cache preset"), path.string());
  p.file = path;
  return p;
}

std::vector<std::filesystem::path> preset_dirs() {
  std::vector<std::filesystem::path> dirs;
#ifdef HP_CACHESIM_PRESET_DIR
  dirs.emplace_back(HP_CACHESIM_PRESET_DIR);
#endif
  if (auto e = exe_dir(); !e.empty()) {
    dirs.push_back(e / "presets");
    dirs.push_back(e / ".." / "share" / "hybridprof" / "presets");
  }
  return dirs;
}

std::vector<std::string> known_presets() {
  std::set<std::string> names;
  for (const auto& d : preset_dirs()) {
    std::error_code ec;
    for (auto it = std::filesystem::directory_iterator(d, ec); !ec && it != std::filesystem::directory_iterator();
         it.increment(ec))
      if (it->path().extension() == ".json") names.insert(it->path().stem().string());
  }
  return {names.begin(), names.end()};
}

Preset find_preset(std::string_view name_or_path) {
  const std::string arg(name_or_path);
  if (arg.find('/') != std::string::npos || (arg.size() > 5 && arg.ends_with(".json"))) return load_preset_file(arg);
  for (const auto& d : preset_dirs()) {
    std::error_code ec;
    const auto file = d / (arg + ".json");
    if (std::filesystem::is_regular_file(file, ec)) return load_preset_file(file);
  }
  std::string known;
  for (const auto& n : known_presets()) known += (known.empty() ? "" : ", ") + n;
  throw InputError("unknown preset '" + arg + "' (known: " + (known.empty() ? "none found" : known) + ")");
}

Preset scale_for_sampling(const Preset& p, uint32_t k) {
  if (k <= 1) return p;
  Preset s = p;
  s.name = p.name + "/" + std::to_string(k);
  s.compute_units = std::max<uint32_t>(1, (p.compute_units + k / 2) / k);
  CacheConfig& l2 = s.l2;
  const uint64_t set_bytes = uint64_t(l2.line_bytes) * l2.ways;
  while (l2.channels > 1 && p.l2.size_bytes / k < set_bytes * l2.channels) l2.channels /= 2;
  const uint64_t unit = set_bytes * l2.channels;
  l2.size_bytes = std::max<uint64_t>(unit, (p.l2.size_bytes / k) / unit * unit);
  if (!check_config(l2).empty()) l2 = p.l2;  // cannot scale: keep the full L2 (stated by the name only)
  return s;
}

}  // namespace hp::cachesim
