#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "cache_analysis.hpp"
#include "common/scratch_dir.hpp"

namespace hp {
namespace {

// One pass of 64 lanes (one wave64) that all read one 64-byte line, replayed by CacheAnalysis on vega56 or on
// a copy of it that counts the L1 per lane.
nlohmann::json tables(const std::string& preset) {
  trace::TraceHeader h;
  trace::BufferInfo b;
  b.id = 0;
  b.name = "buf";
  b.base_address = 0x10000;
  b.size_bytes = 1 << 20;
  h.buffers.push_back(b);
  trace::PassInfo pass{std::string("p"), {}};
  pass.dispatch.workgroup_size[0] = 64;
  pass.dispatch.workgroup_count[0] = 1;
  std::vector<trace::TraceRecord> recs;
  for (uint32_t l = 0; l < 64; ++l) recs.push_back({l, 0, HP_TRACE_INFO(0u, HP_TRACE_LOAD, 4u), (l % 16) * 4});
  CacheAnalysisOptions o;
  o.preset = preset;
  o.curves = false;
  CacheAnalysis a(h, o);
  const uint32_t p = a.begin_pass(pass);
  a.write_records(p, recs, 0, 1);
  return a.finish()["passes"][0];
}

std::string lane_preset() {
  std::ifstream in(std::string(HP_TEST_PRESET_DIR) + "/vega56.json");
  std::stringstream text;
  text << in.rdbuf();
  std::string s = text.str();
  const std::string key = "\"coalescing\": \"line\",";
  const size_t at = s.find(key);
  EXPECT_NE(at, std::string::npos);
  s.insert(at + key.size(), " \"l1_hit_counting\": \"lane\",");
  const auto path = hp::test::scratch_dir() / "lane_preset.json";
  std::ofstream(path) << s;
  return path.string();
}

TEST(CacheAnalysis, TablesCarryTheL1UnderEveryCounting) {
  const nlohmann::json req = tables("vega56"), lane = tables(lane_preset());
  // The study's table ("l1") as before under the default counting: one request, one miss.
  EXPECT_EQ(req["l1_hit_counting"], "request");
  EXPECT_EQ(req["l1"]["requests"], 1u);
  EXPECT_EQ(req["l1"]["hits"], 0u);
  EXPECT_EQ(req["l1"]["misses"], 1u);
  EXPECT_EQ(req["buffers"]["buf"]["l1_requests"], 1u);
  // Every counting beside it, the same in both replays.
  for (const nlohmann::json* t : {&req, &lane}) {
    const nlohmann::json& c = (*t)["l1_by_counting"];
    EXPECT_EQ(c["request"]["lookups"], 1u);
    EXPECT_EQ(c["request"]["hits"], 0u);
    EXPECT_EQ(c["quarter_wave"]["lookups"], 4u);
    EXPECT_EQ(c["quarter_wave"]["hits"], 3u);
    EXPECT_EQ(c["lane"]["lookups"], 64u);
    EXPECT_EQ(c["lane"]["hits"], 63u);
    EXPECT_DOUBLE_EQ(c["lane"]["hit_rate"].get<double>(), 63.0 / 64.0);
    for (const char* k : {"request", "quarter_wave", "lane"}) EXPECT_EQ(c[k]["misses"], 1u) << k;
    const nlohmann::json& bc = (*t)["buffers"]["buf"]["l1_by_counting"];
    EXPECT_EQ(bc["lane"]["lookups"], 64u);
    EXPECT_EQ(bc["lane"]["misses"], 1u);
    EXPECT_EQ(bc["quarter_wave"]["hits"], 3u);
  }
  // A preset that counts per lane: "l1" is counted per lane, misses and the L2 unchanged.
  EXPECT_EQ(lane["l1_hit_counting"], "lane");
  EXPECT_EQ(lane["l1"]["requests"], 64u);
  EXPECT_EQ(lane["l1"]["hits"], 63u);
  EXPECT_EQ(lane["l1"]["misses"], 1u);
  EXPECT_EQ(lane["buffers"]["buf"]["l1_requests"], 64u);
  EXPECT_EQ(lane["buffers"]["buf"]["l1_misses"], 1u);
  EXPECT_EQ(lane["l2"], req["l2"]);
}

}  // namespace
}  // namespace hp
