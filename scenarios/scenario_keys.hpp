// The keys of a scenario object, as one table: key path, type, range or choices, default and a line of
// description per key. The table drives parse_scenario (which keys exist where, their types and ranges,
// what an absent key means), Scenario::canonical (which keys enter it, and when), `hybridprof run
// --list-keys` and the key reference in docs/scenarios.md, "Scenario keys" (generated: a test holds it to the code).
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace hp {

struct Scenario;

enum class KeyType {
  boolean,
  number,   ///< finite, within [lo, hi]
  integer,  ///< within [int_lo, int_hi]
  string,
  choice,      ///< a string, one of `choices`
  vec3,        ///< [x, y, z] finite numbers (read as float)
  resolution,  ///< [width, height] integers, 1..kMaxImageSide
  pass_list,   ///< a list of distinct pass names ("shadows", "reflections")
};

/// Where a key is read, for the key's own checks: fail() throws the InputError "FILE: PATH.KEY: why".
struct KeyContext {
  const std::string& file;
  const std::string& path;  ///< the scenario object's path ("" at the top level, "base", "axes (...)")
  bool present = false;     ///< the key was given (else the value is the default)
  [[noreturn]] void fail(const std::string& key_path, const std::string& why) const;
};

struct ScenarioKey {
  std::string path;  ///< "bvh.buckets": a top-level key or one member of a top-level object
  KeyType type = KeyType::string;
  double lo = 0, hi = 0;                ///< number
  std::int64_t int_lo = 0, int_hi = 0;  ///< integer
  std::vector<std::string> choices;     ///< choice
  /// The value an absent key takes (null: none, an optional stays unset).
  nlohmann::json default_value;
  std::string default_text;  ///< the docs' default when not the default value's JSON
  std::string range_text;    ///< the docs' range when not derived from the type
  std::string description;
  /// Sets the scenario from the checked value (or the default); may check more (cross-key checks see the
  /// keys before it in the table: the table's order is the order keys are read and errors found).
  std::function<void(Scenario&, const nlohmann::json&, const KeyContext&)> apply;
  /// The key's value in the canonical form; empty: never in it (a label, or where files go).
  std::function<nlohmann::json(const Scenario&)> canonical;
  /// When the key enters the canonical form; empty: always. Keys added after the first ids were written
  /// enter only off their default, so the ids of scenarios without them (and baselines keyed by them) stay.
  std::function<bool(const Scenario&)> canonical_when;
};

/// Every scenario key, in reading order.
const std::vector<ScenarioKey>& scenario_keys();

/// The table as markdown (| key | type | range / choices | default | description |), one row per key.
std::string scenario_keys_markdown();

}  // namespace hp
