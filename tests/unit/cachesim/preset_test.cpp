#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "cachesim/preset.hpp"
#include "common/scratch_dir.hpp"
#include "error.hpp"

namespace hp::cachesim {
namespace {

const char* kValid = R"({
  "name": "t", "sources": ["test"], "compute_units": 2, "wave_width": 64, "max_waves_per_cu": 4,
  "coalescing": "line",
  "l1": {"size_bytes": 16384, "line_bytes": 64, "ways": 4},
  "l2": {"size_bytes": 65536, "line_bytes": 64, "ways": 16, "channels": 4, "replacement": "fifo"}
})";

std::string error_of(const std::string& text) {
  try {
    parse_preset(text, "custom.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  return s.replace(at, from.size(), to);
}

TEST(Preset, ShippedPresetsLoadWithTheirFigures) {
  Preset v = find_preset("vega56");
  EXPECT_EQ(v.compute_units, 56u);
  EXPECT_EQ(v.wave_width, 64u);
  EXPECT_EQ(v.l1.size_bytes, 16u << 10);
  EXPECT_EQ(v.l1.ways, 4u);
  EXPECT_EQ(v.l2.size_bytes, 4u << 20);
  EXPECT_EQ(v.l2.channels, 16u);
  EXPECT_FALSE(v.sources.empty());
  Preset g = find_preset("ga102");
  EXPECT_EQ(g.wave_width, 32u);
  EXPECT_EQ(g.coalescing, Coalescing::sector);
  EXPECT_EQ(g.l1.sector_bytes, 32u);
  Preset h = find_preset("h100");
  EXPECT_EQ(h.compute_units, 132u);
  EXPECT_EQ(h.l2.size_bytes, 50u << 20);
  EXPECT_EQ(find_preset(std::string(HP_TEST_PRESET_DIR) + "/vega56.json").name, "vega56");
}

TEST(Preset, UnknownNameListsKnownPresets) {
  try {
    find_preset("vega65");
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("vega65"), std::string::npos);
    EXPECT_NE(m.find("ga102, h100, vega56"), std::string::npos) << m;
  }
}

TEST(Preset, ValidOneParses) {
  Preset p = parse_preset(kValid, "custom.json");
  EXPECT_EQ(p.l2.replacement, Replacement::fifo);
  EXPECT_EQ(p.l1.sector_bytes, 64u);
}

TEST(Preset, ErrorsNameFileAndKeyPath) {
  EXPECT_EQ(error_of(replace(kValid, "\"ways\": 4}", "\"ways\": 4, \"assoc\": 2}")),
            "custom.json: l1.assoc: unknown key");
  EXPECT_EQ(error_of(replace(kValid, "\"compute_units\": 2", "\"compute_units\": \"2\"")),
            "custom.json: compute_units: expected a positive integer, got \"2\"");
  EXPECT_EQ(error_of(replace(kValid, "\"line_bytes\": 64, \"ways\": 4", "\"line_bytes\": 48, \"ways\": 4")),
            "custom.json: l1.line_bytes: 48 is not a power of two");
  EXPECT_NE(
      error_of(replace(kValid, "\"size_bytes\": 16384", "\"size_bytes\": 16000")).find("custom.json: l1.size_bytes:"),
      std::string::npos);
  EXPECT_EQ(error_of(replace(kValid, "\"fifo\"", "\"plru\"")),
            "custom.json: l2.replacement: 'plru' is not lru, fifo or random");
  EXPECT_EQ(error_of(replace(kValid, "\"coalescing\": \"line\",", "")), "custom.json: coalescing: missing");
  EXPECT_EQ(error_of(replace(kValid, "\"name\"", "\"nme\"")), "custom.json: name: missing");
  EXPECT_NE(error_of("{ not json").find("custom.json: invalid JSON"), std::string::npos);
  EXPECT_EQ(error_of(replace(kValid, "\"wave_width\": 64", "\"wave_width\": -1")),
            "custom.json: wave_width: expected a positive integer, got -1");
  EXPECT_EQ(error_of(replace(kValid, "\"sources\": [\"test\"]", "\"sources\": [3]")),
            "custom.json: sources[0]: expected a string");
}

TEST(Preset, L1HitCountingIsOptionalAndNamed) {
  EXPECT_EQ(parse_preset(kValid, "custom.json").l1_hit_counting, HitCounting::request);
  for (const auto& [text, c] :
       {std::pair{"request", HitCounting::request}, std::pair{"quarter_wave", HitCounting::quarter_wave},
        std::pair{"lane", HitCounting::lane}}) {
    const Preset p =
        parse_preset(replace(kValid, "\"coalescing\": \"line\",",
                             "\"coalescing\": \"line\", \"l1_hit_counting\": \"" + std::string(text) + "\","),
                     "custom.json");
    EXPECT_EQ(p.l1_hit_counting, c) << text;
    EXPECT_STREQ(to_string(c), text);
  }
  EXPECT_EQ(error_of(replace(kValid, "\"coalescing\": \"line\",",
                             "\"coalescing\": \"line\", \"l1_hit_counting\": \"lanes\",")),
            "custom.json: l1_hit_counting: 'lanes' is not request, quarter_wave or lane");
  EXPECT_EQ(error_of(replace(kValid, "\"coalescing\": \"line\",", "\"coalescing\": \"line\", \"l1_hit_counting\": 4,")),
            "custom.json: l1_hit_counting: expected a string, got 4");
  // The L2 is always counted per request: the key belongs to the preset, not to a cache.
  EXPECT_EQ(error_of(replace(kValid, "\"ways\": 4}", "\"ways\": 4, \"hit_counting\": \"lane\"}")),
            "custom.json: l1.hit_counting: unknown key");
  for (const char* name : {"vega56", "ga102", "h100"})
    EXPECT_EQ(find_preset(name).l1_hit_counting, HitCounting::request);
  HitCounting c = HitCounting::lane;
  EXPECT_FALSE(parse_hit_counting("Lane", c));
  EXPECT_EQ(c, HitCounting::lane);
  EXPECT_TRUE(parse_hit_counting("quarter_wave", c));
  EXPECT_EQ(c, HitCounting::quarter_wave);
}

// Audit find (2026-11-30): a 2^44-byte L2 overflowed the set arithmetic and corrupted the heap; a billion
// compute units was a bad_alloc. The simulator's bounds are named instead.
TEST(Preset, SizesBeyondTheSimulatorsLimitsAreNamed) {
  EXPECT_EQ(error_of(replace(kValid, "\"size_bytes\": 65536", "\"size_bytes\": 17592186044416")),
            "custom.json: l2.size_bytes: 17592186044416 exceeds the limit of 1 GiB");
  EXPECT_EQ(error_of(replace(kValid, "\"ways\": 16", "\"ways\": 8192")),
            "custom.json: l2.ways: 8192 exceeds the limit of 4096");
  EXPECT_EQ(error_of(replace(kValid, "\"compute_units\": 2", "\"compute_units\": 1000000000")),
            "custom.json: compute_units: at most 4096");
  // Each CU has its own L1: 4096 CUs of 512 KiB are 2 GiB of L1 in all.
  std::string big = replace(kValid, "\"compute_units\": 2", "\"compute_units\": 4096");
  big = replace(big, "\"size_bytes\": 16384", "\"size_bytes\": 524288");
  EXPECT_NE(error_of(big).find("custom.json: l1: size_bytes x compute_units"), std::string::npos) << error_of(big);
  // At the limits themselves: accepted.
  EXPECT_NO_THROW(parse_preset(replace(kValid, "\"size_bytes\": 65536", "\"size_bytes\": 1073741824"), "custom.json"));
}

TEST(Preset, FileErrorsNameThePath) {
  const auto dir = hp::test::scratch_dir();
  const auto f = dir / "bad.json";
  std::ofstream(f) << replace(kValid, "\"channels\": 4", "\"channels\": 0");
  try {
    find_preset(f.string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), f.string() + ": l2.channels: expected a positive integer, got 0");
  }
  EXPECT_THROW(find_preset((dir / "missing.json").string()), InputError);
  try {
    find_preset(dir.string() + "/");  // a folder given as the preset
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("is a directory, not a cache preset"), std::string::npos) << e.what();
  }
}

TEST(Preset, ScaledForSamplingKeepsPerCuResourcesAndShrinksTheShared) {
  const Preset v = find_preset("vega56");
  EXPECT_EQ(scale_for_sampling(v, 1).compute_units, v.compute_units);
  EXPECT_EQ(scale_for_sampling(v, 1).name, v.name);
  const Preset s = scale_for_sampling(v, 4);
  EXPECT_EQ(s.compute_units, 14u);                    // 56 / 4
  EXPECT_EQ(s.l1.size_bytes, v.l1.size_bytes);        // each CU keeps its L1 ...
  EXPECT_EQ(s.max_waves_per_cu, v.max_waves_per_cu);  // ... and its occupancy
  EXPECT_EQ(s.l2.size_bytes, v.l2.size_bytes / 4);
  EXPECT_EQ(s.l2.ways, v.l2.ways);
  EXPECT_EQ(s.l2.line_bytes, v.l2.line_bytes);
  EXPECT_TRUE(check_config(s.l2).empty()) << check_config(s.l2);
  EXPECT_EQ(s.name, "vega56/4");
  // Far past the CU count: one CU, and an L2 that still holds one set per channel.
  const Preset tiny = scale_for_sampling(v, 1u << 19);
  EXPECT_EQ(tiny.compute_units, 1u);
  EXPECT_TRUE(check_config(tiny.l2).empty()) << check_config(tiny.l2);
  EXPECT_GE(tiny.l2.size_bytes, uint64_t(tiny.l2.line_bytes) * tiny.l2.ways);
  for (const char* name : {"ga102", "h100"}) {
    const Preset p = find_preset(name);
    const Preset q = scale_for_sampling(p, 16);
    EXPECT_TRUE(check_config(q.l2).empty()) << name;
    EXPECT_LT(q.l2.size_bytes, p.l2.size_bytes) << name;
  }
}

}  // namespace
}  // namespace hp::cachesim
