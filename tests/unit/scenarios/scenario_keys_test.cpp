// The scenario key table: docs/scenarios.md's key reference is the generated table (so the docs cannot drift
// from the parser), and the table covers every key the parser reads and the canonical form holds.
#include "error.hpp"
#include "scenario.hpp"
#include "scenario_keys.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace hp {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

constexpr const char* kBegin = "<!-- scenario-keys:begin";
constexpr const char* kEnd = "<!-- scenario-keys:end -->";

TEST(ScenarioKeys, DocsHoldTheGeneratedTable) {
  std::ifstream in(fs::path(HP_SOURCE_DIR) / "docs" / "scenarios.md");
  ASSERT_TRUE(in);
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string readme = ss.str();
  const size_t begin = readme.find(kBegin), end = readme.find(kEnd);
  ASSERT_NE(begin, std::string::npos) << "docs/scenarios.md: no " << kBegin;
  ASSERT_NE(end, std::string::npos) << "docs/scenarios.md: no " << kEnd;
  const size_t table = readme.find('\n', begin) + 1;
  ASSERT_LT(table, end);
  EXPECT_EQ(readme.substr(table, end - table), scenario_keys_markdown())
      << "docs/scenarios.md: the key table differs from the code's; replace it with the output of "
         "`hybridprof run --list-keys`";
}

// Every leaf of a JSON object as a key path ("bvh.buckets").
void leaves(const json& j, const std::string& prefix, std::set<std::string>& out) {
  for (const auto& [k, v] : j.items()) {
    const std::string path = prefix.empty() ? k : prefix + "." + k;
    if (v.is_object())
      leaves(v, path, out);
    else
      out.insert(path);
  }
}

TEST(ScenarioKeys, CoverTheCanonicalFormAndEveryKeyParses) {
  std::set<std::string> table;
  for (const ScenarioKey& k : scenario_keys()) {
    EXPECT_TRUE(table.insert(k.path).second) << k.path << " is in the table twice";
    EXPECT_FALSE(k.description.empty()) << k.path;
    ASSERT_TRUE(k.apply) << k.path;
  }
  // A scenario with every conditional key on: its canonical form's keys are all table keys.
  const Scenario s =
      parse_scenario(json::parse(R"({"reflection_path": "compact", "query_overhead": true, "traversal": "ray-query",
      "overlap": false, "trace": {"passes": ["shadows"], "sample_every": 2, "sample_block": 4},
      "transform": {"scale": 2}, "error": {}})"),
                     "f.json");
  std::set<std::string> canonical;
  leaves(s.canonical(), "", canonical);
  // The compute traversal's node layout (not with a driver traversal).
  leaves(parse_scenario(json::parse(R"({"bvh": {"node_layout": "wide4"}})"), "f.json").canonical(), "", canonical);
  for (const std::string& k : canonical) EXPECT_TRUE(table.count(k)) << k << " is canonical but not in the table";
  for (const std::string& k : table) {
    if (k == "name" || k == "trace.keep") continue;  // a label, and where files go: not what runs
    EXPECT_TRUE(canonical.count(k)) << k << " never enters the canonical form";
  }
}

TEST(ScenarioKeys, MarkdownRowsAreOnePerKey) {
  const std::string md = scenario_keys_markdown();
  EXPECT_EQ(size_t(std::count(md.begin(), md.end(), '\n')), scenario_keys().size() + 2);
  EXPECT_NE(md.find("| `bvh.buckets` | integer | 2..1024 | `12` | "), std::string::npos) << md;
  EXPECT_NE(md.find("| `geometry` | string | `\"indexed\"`, `\"soup\"` | `\"indexed\"` | "), std::string::npos) << md;
}

}  // namespace
}  // namespace hp
