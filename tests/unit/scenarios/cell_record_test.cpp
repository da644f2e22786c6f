// The results.jsonl line: one writer (to_json) and one reader (parse_cell_record). The writer is pinned
// to the line the runner assembled by hand before CellRecord existed (legacy_line below, kept as it was),
// and to a committed line; the reader gives back what the writer wrote, and reads every committed
// results file.
#include "cell_record.hpp"
#include "error.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace hp {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

const fs::path kSource = HP_SOURCE_DIR;

Environment environment() {
  Environment env;
  env.cpu_model = "AMD EPYC";
  env.core_count = 2;
  env.lp_num_threads = "unset";
  env.build_type = "Release";
  env.compiler = "gcc 12.2.0";
  env.git_commit = "132857c";
  env.date_utc = "2026-12-02T00:14:36Z";
  env.hostname = "vm";
  env.os = "Linux 6.1.0-18-amd64 x86_64";
  env.load_1min = 1.25;
  env.cpu_governor = "unknown";
  env.device = {"llvmpipe (LLVM 15.0.6, 256 bits)", "cpu", "llvmpipe", "Mesa 22.3.6", "22.3.6", "1.3.230"};
  return env;
}

FrameTimings timings() {
  std::vector<FrameSample> frames;
  std::vector<FrameSpan> overlapped;
  std::uint64_t t = 1'000'000;
  for (int f = 0; f < 3; ++f) {
    FrameSample s;
    for (const char* pass : {"gbuffer", "shadows", "reflections"}) {
      s.passes.push_back({pass, t, t + 100'000 + std::uint64_t(f) * 7'000, "graphics"});
      t += 120'000 + std::uint64_t(f) * 7'000;
    }
    s.cpu_wall_ns = 500'000 + std::uint64_t(f) * 11'000;
    s.counters.add("shadows", "rays", 9216);
    frames.push_back(s);
    overlapped.push_back({t, t + 300'000 + std::uint64_t(f) * 5'000});
    t += 400'000;
  }
  Counters invocations;
  invocations.add("shadows", "compute_invocations", 9216);
  return FrameTimings::from_measured(1, TimingSource::GpuTimestamps, frames, std::nullopt, invocations, overlapped,
                                     PassIsolation::Serialized);
}

// The inputs of one cell as the runner has them once it has measured it.
struct Measured {
  Environment env = environment();
  FrameTimings timings = hp::timings();
  std::optional<double> load_end = 1.5;
  json axes = {{"case", "a"}, {"geometry", "soup"}};
  json config = {{"scene", "builtin:pica"}, {"frames", 3}, {"geometry", "soup"}};
  std::size_t triangles = 4321;
  double build_ms = 0.763504;
  std::size_t nodes = 2709, leaves = 1355;
  int max_depth = 15;
  double sah_cost = 19.829422499685528;
  json cache = {{"preset", "vega56"},
                {"passes", json::array({{{"pass", "shadows"}, {"l1", {{"hits", 10}, {"misses", 2}}}}})}};
  json error = {{"frames", 2}, {"image", {{"relmse", 0.001}, {"psnr_db", nullptr}}}};
  json report = {{"depth_error", true}};
  json expect_spec = {{"max_relmse", 0.01}};
  std::vector<std::string> unmet = {"relMSE 0.02 > 0.01 (max_relmse)"};
  json images = {{"color", "cells/0123/color.png"}, {"shadow", "cells/0123/shadow.png"}};
  double wall_s = 1.875;
};

// The line as scenarios/runner.cpp assembled it before CellRecord (same statements, same order).
json legacy_line(const Measured& in) {
  json line;
  line["schema"] = "hybridprof.cell";
  line["version"] = 1;
  line["id"] = "0123456789abcdef";
  line["matrix"] = "m";
  line["name"] = "a";
  line["axes"] = in.axes;
  line["config"] = in.config;
  line["result"] = timing_result_json(in.env, in.timings);
  line["load_1min"] = {{"start", in.env.load_1min ? json(*in.env.load_1min) : json(nullptr)},
                       {"end", in.load_end ? json(*in.load_end) : json(nullptr)}};
  line["scene"] = {{"triangles", in.triangles}};
  line["bvh"] = {{"build_ms", in.build_ms},
                 {"nodes", in.nodes},
                 {"leaves", in.leaves},
                 {"max_depth", in.max_depth},
                 {"sah_cost", in.sah_cost}};
  line["cache"] = in.cache;
  line["error"] = in.error;
  line["report"] = in.report;
  line["expect"] = {{"spec", in.expect_spec}, {"unmet", in.unmet}};
  line["images"] = in.images;
  line["wall_s"] = in.wall_s;
  return line;
}

// The same cell as the runner builds its record now.
CellRecord record(const Measured& in) {
  CellRecord r(TimingResult{in.env, in.timings, in.timings.summarize(), in.timings.total_counters()});
  r.id = "0123456789abcdef";
  r.matrix = "m";
  r.name = "a";
  r.axes = in.axes;
  r.config = in.config;
  r.load_1min = CellLoad{in.env.load_1min, in.load_end};
  r.triangles = in.triangles;
  r.bvh = CellBvh{in.build_ms, in.nodes, in.leaves, in.max_depth, in.sah_cost};
  r.cache = in.cache;
  r.error = in.error;
  r.report = in.report;
  r.expect = CellExpect{in.expect_spec, in.unmet};
  for (const auto& [k, v] : in.images.items()) r.images[k] = v.get<std::string>();
  r.wall_s = in.wall_s;
  return r;
}

std::string error_of(const json& line) {
  try {
    parse_cell_record(line, "r.jsonl:3");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(CellRecord, WritesTheLineTheRunnerWrote) {
  const Measured in;
  EXPECT_EQ(to_json(record(in)).dump(), legacy_line(in).dump());
  // Without the optional parts: no bvh (no ray traced), cache, error, report or expect, an unreadable load.
  Measured bare;
  bare.env.load_1min.reset();
  bare.load_end.reset();
  json legacy = legacy_line(bare);
  for (const char* k : {"bvh", "cache", "error", "report", "expect"}) legacy.erase(k);
  CellRecord r = record(bare);
  r.bvh.reset();
  r.cache = r.error = r.report = nullptr;
  r.expect.reset();
  EXPECT_EQ(to_json(r).dump(), legacy.dump());
}

TEST(CellRecord, WritesTheCommittedLine) {
  const fs::path file = kSource / "tests/unit/scenarios/data/cell_record.jsonl";
  if (std::getenv("HP_UPDATE_EXPECTED")) {  // regenerates the file, after a deliberate change of the line
    std::ofstream(file) << to_json(record(Measured{})).dump() << "\n";
  }
  std::ifstream in(file);
  ASSERT_TRUE(in) << "tests/unit/scenarios/data/cell_record.jsonl";
  std::string expected;
  std::getline(in, expected);
  EXPECT_EQ(to_json(record(Measured{})).dump(), expected)
      << "the results.jsonl line changed: if on purpose, update the file (and the readers of old lines)";
}

TEST(CellRecord, ReadsBackWhatItWrites) {
  const CellRecord r = record(Measured{});
  EXPECT_TRUE(parse_cell_record(to_json(r), "r.jsonl:1") == r);
  CellRecord bare = r;
  bare.bvh.reset();
  bare.load_1min = CellLoad{};
  bare.cache = bare.error = bare.report = nullptr;
  bare.expect.reset();
  bare.images.clear();
  EXPECT_TRUE(parse_cell_record(to_json(bare), "r.jsonl:1") == bare);
  EXPECT_FALSE(parse_cell_record(to_json(bare), "r.jsonl:1") == r);
}

TEST(CellRecord, DriverAccelerationStructureRoundTrips) {
  CellRecord r = record(Measured{});
  r.accel = CellAccel{"pipeline", "morton", "flat", 1, 1, true, 8.25, true, 59894, 6u << 20, 4096, 1u << 20};
  const json line = to_json(r);
  ASSERT_TRUE(line.contains("accel"));
  EXPECT_EQ(line["accel"]["order"], "morton");
  EXPECT_TRUE(parse_cell_record(line, "r.jsonl:1") == r);
  json bad = line;
  bad["accel"].erase("blas_bytes");
  EXPECT_EQ(error_of(bad), "r.jsonl:3: field 'accel.blas_bytes' is not a count");
  bad = line;
  bad["accel"]["traversal"] = 3;
  EXPECT_EQ(error_of(bad), "r.jsonl:3: field 'accel.traversal' missing or not a string");
}

// The interleaved rounds a cell was measured in: written, read back, and errors that name the field.
TEST(CellRecord, RoundsRoundTrip) {
  CellRecord r = record(Measured{});
  r.rounds = CellRounds{3,
                        42,
                        {{0, 1, 4, 2, true, {0.5, 0.75}},
                         {1, 3, 4, 1, false, {0.75, std::nullopt}},
                         {2, 0, 4, 1, false, {1.0, 1.25}}}};
  const json line = to_json(r);
  ASSERT_TRUE(line.contains("rounds"));
  EXPECT_EQ(line["rounds"]["visits"][1]["load_1min"]["end"], nullptr);
  EXPECT_EQ(line["rounds"]["visits"][0]["position"], 1);
  EXPECT_TRUE(parse_cell_record(line, "r.jsonl:1") == r);
  json bad = line;
  bad["rounds"]["visits"][2].erase("frames");
  EXPECT_EQ(error_of(bad), "r.jsonl:3: field 'rounds.visits.frames' is not a count");
  bad = line;
  bad["rounds"]["visits"][0]["rebuilt"] = 1;
  EXPECT_EQ(error_of(bad), "r.jsonl:3: field 'rounds.visits.rebuilt' missing or not a boolean");
}

TEST(CellRecord, ErrorsNameTheLineAndTheField) {
  const json good = to_json(record(Measured{}));
  EXPECT_EQ(error_of(json::array()), "r.jsonl:3: not a hybridprof cell (field 'schema' is not \"hybridprof.cell\")");
  json j = good;
  j.erase("result");
  EXPECT_EQ(error_of(j), "r.jsonl:3: field 'result' missing");
  j = good;
  j["result"].erase("frames");
  EXPECT_EQ(error_of(j).rfind("r.jsonl:3: result: ", 0), 0u) << error_of(j);
  j = good;
  j["id"] = 5;
  EXPECT_EQ(error_of(j), "r.jsonl:3: field 'id' missing or not a string");
  j = good;
  j["axes"] = 5;
  EXPECT_EQ(error_of(j), "r.jsonl:3: field 'axes' is not an object");
  j = good;
  j["scene"]["triangles"] = -1;
  EXPECT_EQ(error_of(j), "r.jsonl:3: field 'scene.triangles' is not a count");
  j = good;
  j["bvh"].erase("nodes");
  EXPECT_EQ(error_of(j), "r.jsonl:3: field 'bvh.nodes' is not a count");
  j = good;
  j["images"]["color"] = 1;
  EXPECT_EQ(error_of(j), "r.jsonl:3: field 'images.color' is not a string (a path)");
  j = good;
  j["expect"]["unmet"] = "x";
  EXPECT_EQ(error_of(j), "r.jsonl:3: field 'expect.unmet' missing or not a list");
}

TEST(CellRecord, ReadsEveryCommittedResultsFile) {
  size_t lines = 0;
  for (const auto& e : fs::recursive_directory_iterator(kSource / "reports")) {
    if (e.path().filename() != "results.jsonl") continue;
    std::ifstream in(e.path());
    std::string text;
    for (size_t n = 1; std::getline(in, text); ++n) {
      if (text.empty()) continue;
      const std::string where = e.path().string() + ":" + std::to_string(n);
      EXPECT_NO_THROW(parse_cell_record(json::parse(text), where)) << where;
      ++lines;
    }
  }
  EXPECT_GT(lines, 100u);
}

}  // namespace
}  // namespace hp
