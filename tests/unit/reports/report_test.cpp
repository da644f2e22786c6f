// The markdown report on synthetic cells: its tables, numbers, sentences, charts and files.
#include "report.hpp"

#include "error.hpp"
#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <regex>

namespace hp {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

test::SynthCell cell(const char* geometry, json resolution, std::uint64_t seed, double shadows_scale = 1.0) {
  test::SynthCell c;
  c.axes = {{"geometry", geometry}, {"resolution", resolution}};
  c.passes = test::passes(21, seed, 0.02, shadows_scale);
  // 10,000 shadow rays a frame at a 3 ms median: 3.33 Mrays/s.
  c.counters_per_frame.set("shadows", "rays_cast", 10000);
  c.counters_per_frame.set("shadows", "nodes_visited", 150000);
  c.counters_per_frame.set("shadows", "triangles_tested", 25000);
  return c;
}

std::vector<CellResult> matrix() {
  // geometry x resolution; soup's shadow pass is 30% slower and visits 10% more nodes.
  std::vector<CellResult> cells;
  std::uint64_t seed = 1;
  for (const char* g : {"indexed", "soup"}) {
    for (json r : {json{64, 36}, json{128, 72}}) {
      test::SynthCell c = cell(g, r, seed++, std::string(g) == "soup" ? 1.3 : 1.0);
      if (std::string(g) == "soup") c.counters_per_frame.set("shadows", "nodes_visited", 165000);
      cells.push_back(test::cell(c));
    }
  }
  return cells;
}

TEST(Report, HasEverySection) {
  const Report r = build_report(matrix());
  const std::string& md = r.markdown;
  for (const char* s : {"# hybridprof report: synth", "## Environment", "## Charts", "## Cells",
                        "## Comparisons along each axis", "### `geometry`", "### `resolution`", "## Cache simulation"})
    EXPECT_NE(md.find(s), std::string::npos) << s;
  EXPECT_NE(md.find("llvmpipe (LLVM 15.0.6, 256 bits)"), std::string::npos);
  EXPECT_NE(md.find("| LP_NUM_THREADS | unset |"), std::string::npos);
  EXPECT_EQ(md.find("Warning"), std::string::npos);
  EXPECT_NE(md.find("No cell carries cache-simulator tables"), std::string::npos);
  // Per cell: the timing table with 21 frames and a valid CI, the counters, the BVH, the images.
  EXPECT_NE(md.find("| pass | median (ms) | 95% CI of the median (ms) | frames | CV |"), std::string::npos);
  EXPECT_TRUE(std::regex_search(md, std::regex(R"(\| shadows \| 3\.0\d\d \| \[2\.9\d\d, 3\.0\d\d\] \| 21 \| 1\.\d%)")));
  EXPECT_TRUE(std::regex_search(md, std::regex(R"(\| shadows \| 10,000 \| 15\.00 \| 2\.50 \| 3\.3\d \|)")))
      << "Mrays/s";
  EXPECT_NE(md.find("BVH: 69,227 nodes, 34,614 leaves, depth 19"), std::string::npos);
  EXPECT_NE(md.find("(cells/" + matrix()[0].id + "/color.png)"), std::string::npos);
  EXPECT_NE(md.find("shadow mask"), std::string::npos);
}

// Under each pass table: how the passes were kept apart, and the overlapped frame against the serialized
// sum, with the verdict its paired CI supports.
TEST(Report, StatesIsolationAndWhatOverlapSaves) {
  test::SynthCell c = cell("indexed", json{64, 36}, 1);
  std::vector<double> sums(21, 0.0);
  for (const auto& [pass, d] : c.passes)
    for (size_t f = 0; f < d.size(); ++f) sums[f] += d[f];
  auto with_saving = [&](double ns) {
    test::SynthCell x = c;
    for (double s : sums) x.overlapped_ns.push_back(s - ns);
    return build_report({test::cell(x)}).markdown;
  };
  const std::string none = build_report({test::cell(c)}).markdown;
  EXPECT_NE(none.find("Passes are serialized for these times"), std::string::npos);
  EXPECT_EQ(none.find("frame as the application records it"), std::string::npos) << "not measured: not claimed";
  const std::string saves = with_saving(2e6);
  EXPECT_NE(saves.find(": overlapping the passes saves 2.000 ms (95% CI 2.000 to 2.000 ms)"), std::string::npos)
      << saves;
  const std::string slower = with_saving(-1e6);
  EXPECT_NE(slower.find("the overlapped frame is slower by 1.000 ms"), std::string::npos);
  // Savings of -1, 0 and +1 ms spread over the pairs: the CI holds 0.
  test::SynthCell mixed = c;
  for (size_t f = 0; f < sums.size(); ++f) mixed.overlapped_ns.push_back(sums[f] - double(int(f % 3) - 1) * 1e6);
  const std::string noise = build_report({test::cell(mixed)}).markdown;
  EXPECT_NE(noise.find(": no measurable saving from overlap (paired over 21 frame pairs"), std::string::npos) << noise;
  test::SynthCell few = c;
  for (auto& [pass, d] : few.passes) d.resize(3);
  for (size_t f = 0; f < 3; ++f) few.overlapped_ns.push_back(sums[f]);
  const std::string short_run = build_report({test::cell(few)}).markdown;
  EXPECT_NE(short_run.find("too few pairs for a 95% CI, so it cannot be told from noise"), std::string::npos);
}

TEST(Report, ComparisonsStateWhatChangedAndByHowMuch) {
  const std::string md = build_report(matrix()).markdown;
  // indexed -> soup, per resolution: the shadow pass ~30% slower with a tiny p, nodes +10%.
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      md, m,
      std::regex(
          R"(Changing geometry from indexed to soup \(with resolution=64x36\) made shadows (\d+\.\d)% slower \([0-9.]+ → [0-9.]+ ms, Holm p < 0\.001\))")))
      << md;
  EXPECT_NEAR(std::stod(m[1]), 30.0, 2.0);
  EXPECT_NE(md.find("the work per frame changed: shadows nodes_visited +10.0%"), std::string::npos);
  // Same geometry, other resolution: our synthetic times do not depend on it.
  EXPECT_NE(md.find(
                "Changing resolution from 64x36 to 128x72 (with geometry=indexed) changed no pass time significantly"),
            std::string::npos);
  EXPECT_NE(md.find("the work counters were identical"), std::string::npos);
  // The study's Table 1 beside the geometry axis, with its two headline figures.
  for (const char* s :
       {"4,873,530", "6,251,450", "5,374,096", "5,979,267", "by 28.3% with a shared offset and by 11.3% without",
        "once GPU traces are captured: this run's cells carry no cache tables"})
    EXPECT_NE(md.find(s), std::string::npos) << s;
}

TEST(Report, ChartsAreBarAndLineCharts) {
  const Report r = build_report(matrix());
  ASSERT_EQ(r.charts.size(), 3u);  // pass times + time vs resolution for each geometry
  EXPECT_EQ(r.charts[0].path, "charts/pass_times.svg");
  EXPECT_EQ(r.charts[1].path, "charts/vs_resolution_1.svg");
  EXPECT_NE(r.charts[0].content.find("class=\"bar\""), std::string::npos);
  EXPECT_NE(r.charts[1].content.find("<polyline"), std::string::npos);
  EXPECT_NE(r.markdown.find("![median pass time per cell](charts/pass_times.svg)"), std::string::npos);
}

// A matrix of more than 12 cells gets several pass-time charts of at most 12 cells each (parts of equal
// size), on one shared y scale, instead of one strip thousands of pixels wide.
TEST(Report, ManyCellsSplitThePassTimeChart) {
  std::vector<CellResult> cells;
  for (std::uint64_t i = 0; i < 26; ++i) {
    // The last cell's shadows are 3x slower: every part's axis must still reach its height.
    test::SynthCell c = cell(i % 2 ? "soup" : "indexed", json{64 + int(i), 36}, i + 1, i == 25 ? 3.0 : 1.0);
    cells.push_back(test::cell(c));
  }
  const Report r = build_report(cells);
  std::vector<const ReportFile*> parts;
  for (const ReportFile& f : r.charts)
    if (f.path.rfind("charts/pass_times", 0) == 0) parts.push_back(&f);
  ASSERT_EQ(parts.size(), 3u);
  std::string top_tick;
  for (size_t k = 0; k < parts.size(); ++k) {
    EXPECT_EQ(parts[k]->path, "charts/pass_times_" + std::to_string(k + 1) + ".svg");
    const std::string& svg = parts[k]->content;
    size_t groups = 0;
    for (size_t at = svg.find("class=\"group\""); at != std::string::npos; at = svg.find("class=\"group\"", at + 1))
      ++groups;
    EXPECT_GE(groups, 8u);
    EXPECT_LE(groups, 12u);
    // The y axis' last tick label is the same in every part: one scale.
    std::string last;
    const std::regex y_tick(R"(class="tick"[^>]*text-anchor="end">([0-9.]+)<)");
    for (auto it = std::sregex_iterator(svg.begin(), svg.end(), y_tick); it != std::sregex_iterator(); ++it)
      last = (*it)[1];
    ASSERT_FALSE(last.empty()) << svg.substr(0, 2000);
    if (k == 0) top_tick = last;
    EXPECT_EQ(last, top_tick) << "part " << k + 1;
    EXPECT_NE(r.markdown.find("](" + parts[k]->path + ")"), std::string::npos);
  }
  EXPECT_NE(parts[0]->content.find("cells 1–8 of 26"), std::string::npos);
  EXPECT_NE(parts[2]->content.find("cells 18–26 of 26"), std::string::npos);
  EXPECT_EQ(r.markdown.find("charts/pass_times.svg"), std::string::npos);
}

TEST(Report, WarnsWhenEnvironmentsDiffer) {
  test::SynthCell a = cell("indexed", json{64, 36}, 1), b = cell("soup", json{64, 36}, 2);
  b.device = "NVIDIA H100";
  b.commit = "def456";
  const std::string md = build_report({test::cell(a), test::cell(b)}).markdown;
  EXPECT_NE(md.find("**Warning:** the cells ran with different device, commit"), std::string::npos) << md;
  EXPECT_NE(md.find("abc123; def456"), std::string::npos);
}

// Verdicts: one family, Holm-adjusted; a pass whose work counters and cache counts are identical in both
// cells is "no change" even when its frames moved (machine drift), and findings.json says what the
// markdown says.
TEST(Report, IdenticalWorkIsNoChangeAndFindingsHoldTheVerdicts) {
  auto traced = [](const char* g, std::uint64_t seed, double shadows_scale, double l1_hits) {
    test::SynthCell c = cell(g, json{64, 36}, seed, shadows_scale);
    json level = {{"requests", l1_hits + 1000}, {"hits", l1_hits}, {"misses", 1000}};
    c.cache = {{"preset", "vega56"}, {"passes", {{{"pass", "shadows"}, {"l1", level}, {"l2", level}}}}};
    return test::cell(c);
  };
  // The shadow pass is 30% slower in the second cell. Same counters and cache counts: drift, no change.
  const Report same = build_report({traced("indexed", 1, 1.0, 5000), traced("soup", 2, 1.3, 5000)});
  EXPECT_NE(same.markdown.find("shadows did the same work in both cells (identical work counters and cache counts): "
                               "no change"),
            std::string::npos)
      << same.markdown;
  EXPECT_EQ(same.markdown.find("shadows 30"), same.markdown.find("shadows 30")) << "no slower claim for shadows";
  EXPECT_TRUE(std::regex_search(same.markdown, std::regex(R"(\| shadows \|[^\n]*\| no change \|)"))) << same.markdown;
  const json f = json::parse(same.findings);
  EXPECT_EQ(f["correction"], "holm");
  bool found = false;
  for (const json& e : f["comparisons"]) {
    if (e["pass"] != "shadows") continue;
    found = true;
    EXPECT_EQ(e["axis"], "geometry");
    EXPECT_EQ(e["from"], "indexed");
    EXPECT_EQ(e["to"], "soup");
    EXPECT_EQ(e["fixed"], (json{{"resolution", {64, 36}}}));
    EXPECT_EQ(e["metric"], "time_ms");
    EXPECT_EQ(e["verdict"], "no change");
    EXPECT_TRUE(e["identical_work"].get<bool>());
    EXPECT_NEAR(e["change"].get<double>(), 0.3, 0.03);
    ASSERT_TRUE(e["ci"].is_array());
    EXPECT_LT(e["ci"][0].get<double>(), e["ci"][1].get<double>());
  }
  EXPECT_TRUE(found);
  // Other cache counts: the work differs, and the same 30% is a real "slower", in both outputs.
  const Report other = build_report({traced("indexed", 1, 1.0, 5000), traced("soup", 2, 1.3, 6000)});
  EXPECT_TRUE(std::regex_search(other.markdown, std::regex(R"(made shadows \d+\.\d% slower)"))) << other.markdown;
  const json g = json::parse(other.findings);
  for (const json& e : g["comparisons"]) {
    if (e["pass"] == "shadows") {
      EXPECT_EQ(e["verdict"], "slower");
    }
  }
}

// The driver's traversal is not counted (its node and triangle counters are 0): equal counters and cache
// counts of two driver-traversal cells do not make their passes' work identical, and a real slowdown stays
// "slower". The traversal section sets them beside the compute cell, with the acceleration structure.
TEST(Report, DriverTraversalsAreComparedNotAssumedIdentical) {
  auto traversal_cell = [](const char* traversal, const char* order, std::uint64_t seed, double scale) {
    test::SynthCell c = cell("indexed", json{64, 36}, seed, scale);
    c.axes = {{"traversal", traversal}, {"as_order", order}};
    if (std::string(traversal) != "compute") {
      // As the runner writes a driver cell's config: its layout too (the grouping must ignore it).
      c.config_patch = {{"traversal", traversal}, {"as_order", order}, {"as_layout", "flat"}};
      c.counters_per_frame.set("shadows", "nodes_visited", 0);
      c.counters_per_frame.set("shadows", "triangles_tested", 0);
    }
    json level = {{"requests", 6000}, {"hits", 5000}, {"misses", 1000}};
    c.cache = {{"preset", "vega56"}, {"passes", {{{"pass", "shadows"}, {"l1", level}, {"l2", level}}}}};
    CellResult r = test::cell(c);
    if (std::string(traversal) != "compute") {
      r.line["accel"] = {
          {"traversal", traversal},        {"order", order},     {"compacted", false},    {"build_ms", 8.5},
          {"build_timed_on_device", true}, {"triangles", 59894}, {"blas_bytes", 6 << 20}, {"tlas_bytes", 4096},
          {"scratch_bytes", 1 << 20}};
    }
    return r;
  };
  const Report r = build_report({traversal_cell("compute", "leaf", 1, 1.0), traversal_cell("ray-query", "leaf", 2, 3.0),
                                 traversal_cell("ray-query", "morton", 3, 3.9)},
                                json::array({{{"id", "abc"},
                                              {"axes", {{"traversal", "pipeline"}, {"as_order", "leaf"}}},
                                              {"reason", "'GPU' has no ray-tracing pipelines"}}}));
  EXPECT_EQ(r.markdown.find("did the same work in both cells"), std::string::npos) << r.markdown;
  EXPECT_TRUE(std::regex_search(r.markdown, std::regex(R"(from leaf to morton[^\n]*made shadows \d+\.\d% slower)")))
      << r.markdown;
  EXPECT_NE(r.markdown.find("they do not count the driver's traversal"), std::string::npos);
  EXPECT_NE(r.markdown.find("## Compute BVH against the driver's ray tracing"), std::string::npos);
  EXPECT_NE(r.markdown.find("the tables below are the traced shaders' own accesses"), std::string::npos)
      << "a driver cell's cache tables say what they hold";
  // 10,000 shadow rays a frame: 3.33 Mrays/s at 3 ms (compute), a third of that at 9 ms (ray-query, leaf).
  EXPECT_TRUE(std::regex_search(r.markdown, std::regex(R"(\| compute \| shadows \| 3\.\d+ \|[^\n]*\| 3\.\d\d \|)")))
      << r.markdown;
  EXPECT_TRUE(std::regex_search(
      r.markdown,
      std::regex(R"(\| ray-query \(leaf\) \| shadows \|[^\n]*\| \+\d+\.\d% \| 1\.\d\d \| 8\.50 \| 6\.00 \|)")))
      << r.markdown;
  // A cell's work table: the compute cell's nodes and triangles per ray, a dash for the driver's (not counted).
  EXPECT_TRUE(std::regex_search(r.markdown, std::regex(R"(\| shadows \| 10,000 \| \d+\.\d\d \| \d+\.\d\d \|)")))
      << r.markdown;
  EXPECT_TRUE(std::regex_search(r.markdown, std::regex(R"(\| shadows \| 10,000 \| — \| — \|)"))) << r.markdown;
  EXPECT_EQ(r.markdown.find("| shadows | 10,000 | 0.00 | 0.00 |"), std::string::npos) << r.markdown;
  EXPECT_NE(r.markdown.find("## Cells not run on this device"), std::string::npos);
  EXPECT_NE(r.markdown.find("- `abc` (as_order=leaf, traversal=pipeline): 'GPU' has no ray-tracing pipelines"),
            std::string::npos)
      << r.markdown;
  const json found = json::parse(r.findings);
  ASSERT_FALSE(found["comparisons"].empty());
  for (const json& e : found["comparisons"]) EXPECT_FALSE(e["identical_work"].get<bool>());
}

// Interleaved cells are compared by their round medians, against the noise floor between rounds.
test::SynthCell rounds_cell(const char* g, std::uint64_t seed, std::uint32_t rounds, std::size_t frames,
                            double shadows_scale, const std::vector<double>& round_factor, double l1_hits) {
  test::SynthCell c = cell(g, json{64, 36}, seed, shadows_scale);
  c.passes = test::passes(frames, seed, 0.02, shadows_scale);
  c.rounds = rounds;
  // The machine's state per round: every pass of every cell measured in that round is scaled alike.
  for (auto& [pass, d] : c.passes)
    for (size_t f = 0; f < d.size(); ++f) d[f] *= round_factor[f % rounds];
  // Other cache counts per cell: the work is not identical, so only the times decide.
  json level = {{"requests", l1_hits + 1000}, {"hits", l1_hits}, {"misses", 1000}};
  c.cache = {{"preset", "vega56"}, {"passes", {{{"pass", "shadows"}, {"l1", level}, {"l2", level}}}}};
  return c;
}

std::map<std::string, json> findings_by_pass(const Report& r) {
  std::map<std::string, json> out;
  const json all = json::parse(r.findings);
  for (const json& e : all["comparisons"]) out[e["pass"].get<std::string>()] = e;
  return out;
}

// A/A while the machine's load climbs round after round (+6% a round, up to +42%): the same in both
// cells, since each round visits both. No pass is "slower" or "faster"; frame by frame the drift is
// between frames of one cell, not between the cells.
TEST(Report, InterleavedAaUnderDriftIsNoChange) {
  const std::vector<double> drift = {1.0, 1.06, 1.12, 1.18, 1.24, 1.30, 1.36, 1.42};
  const Report r = build_report({test::cell(rounds_cell("indexed", 1, 8, 16, 1.0, drift, 5000)),
                                 test::cell(rounds_cell("soup", 2, 8, 16, 1.0, drift, 6000))});
  const auto f = findings_by_pass(r);
  ASSERT_EQ(f.size(), 5u);
  for (const auto& [pass, e] : f) {
    EXPECT_EQ(e["verdict"], "no change") << e.dump();
    EXPECT_EQ(e["samples"], "paired round medians");
    EXPECT_EQ(e["n"], (json{8, 8}));
    EXPECT_GT(e["noise_floor"].get<double>(), 0.0);
  }
  EXPECT_NE(r.markdown.find("measured in 8 interleaved rounds"), std::string::npos) << r.markdown;
  EXPECT_NE(r.markdown.find("compared by their round medians"), std::string::npos);
}

// A true +10% on the shadow pass, 8 rounds of 2 frames, a quiet machine: caught, with an interval that
// holds +10% and excludes 0, outside a noise floor of a few percent; the other passes are no change.
TEST(Report, InterleavedTrueShiftIsSlower) {
  const std::vector<double> quiet(8, 1.0);
  const Report r = build_report({test::cell(rounds_cell("indexed", 1, 8, 16, 1.0, quiet, 5000)),
                                 test::cell(rounds_cell("soup", 2, 8, 16, 1.1, quiet, 6000))});
  const auto f = findings_by_pass(r);
  const json& sh = f.at("shadows");
  EXPECT_EQ(sh["verdict"], "slower") << sh.dump();
  EXPECT_NEAR(sh["change"].get<double>(), 0.10, 0.02);
  EXPECT_LT(sh["ci"][0].get<double>(), 0.10);
  EXPECT_GT(sh["ci"][0].get<double>(), 0.0);
  EXPECT_GT(sh["ci"][1].get<double>(), 0.10);
  EXPECT_LT(sh["noise_floor"].get<double>(), 0.08);
  for (const char* p : {"gbuffer", "reflections", "accumulate", "composite"})
    EXPECT_EQ(f.at(p)["verdict"], "no change") << p << f.at(p).dump();
  EXPECT_TRUE(
      std::regex_search(r.markdown,
                        std::regex(R"(\| shadows \|[^\n]*\| \+\d+\.\d% \[\+\d+\.\d%, \+\d+\.\d%\] \| ±\d+\.\d% \|)")))
      << r.markdown;
}

// A bimodal machine (rounds alternate between a fast and a 30% slower state) and a +5% change: the
// change is inside what the pass moves between rounds of one cell, so it is "no change", not "slower".
TEST(Report, InterleavedChangeInsideTheNoiseFloorIsNoChange) {
  // 40 rounds: enough for the rank test to call the +5% significant (the soup's fast rounds beat the fast
  // rounds, its slow ones the slow ones), so only the noise floor keeps it from "slower".
  std::vector<double> bimodal;
  for (int r = 0; r < 40; ++r) bimodal.push_back(r % 2 ? 1.3 : 1.0);
  const Report r = build_report({test::cell(rounds_cell("indexed", 1, 40, 80, 1.0, bimodal, 5000)),
                                 test::cell(rounds_cell("soup", 2, 40, 80, 1.05, bimodal, 6000))});
  const json sh = findings_by_pass(r).at("shadows");
  EXPECT_LE(sh["p_holm"].get<double>(), 0.05) << sh.dump();
  EXPECT_EQ(sh["verdict"], "no change") << sh.dump();
  EXPECT_GT(sh["noise_floor"].get<double>(), 0.2);
}

// Significant and larger than the noise floor, but with an interval that reaches into the floor: the run
// cannot tell it from what an A/A moves, so "inconclusive", neither "slower" nor "no change".
TEST(Report, InterleavedChangeWhoseIntervalReachesTheFloorIsInconclusive) {
  std::vector<double> alternating;
  for (int r = 0; r < 16; ++r) alternating.push_back(r % 2 ? 1.08 : 1.0);
  test::SynthCell a = rounds_cell("indexed", 1, 16, 32, 1.0, alternating, 5000);
  test::SynthCell b = rounds_cell("soup", 2, 16, 32, 1.10, alternating, 6000);
  for (test::SynthCell* c : {&a, &b}) {
    std::uint64_t seed = c == &a ? 11 : 12;
    c->passes = test::passes(32, seed, 0.08, c == &a ? 1.0 : 1.10);
    for (auto& [pass, d] : c->passes)
      for (size_t f = 0; f < d.size(); ++f) d[f] *= alternating[f % 16];
  }
  const json sh = findings_by_pass(build_report({test::cell(a), test::cell(b)})).at("shadows");
  ASSERT_LE(sh["p_holm"].get<double>(), 0.05) << sh.dump();
  ASSERT_GT(sh["change"].get<double>(), sh["noise_floor"].get<double>()) << sh.dump();
  ASSERT_LE(sh["ci"][0].get<double>(), sh["noise_floor"].get<double>()) << sh.dump();
  EXPECT_EQ(sh["verdict"], "inconclusive") << sh.dump();
}

// Three rounds a side: no p can reach 0.05 (2 / C(6, 3) = 0.1), whatever the frames: "inconclusive".
TEST(Report, TooFewRoundsAreInconclusive) {
  const std::vector<double> quiet(3, 1.0);
  const Report r = build_report({test::cell(rounds_cell("indexed", 1, 3, 30, 1.0, quiet, 5000)),
                                 test::cell(rounds_cell("soup", 2, 3, 30, 1.5, quiet, 6000))});
  const auto f = findings_by_pass(r);
  ASSERT_EQ(f.size(), 5u);
  for (const auto& [pass, e] : f) EXPECT_EQ(e["verdict"], "inconclusive") << e.dump();
}

// The report opens with the study's questions: per comparison the study made, in its direction (soup ->
// indexed), our verdicts for time and the reflection pass's L1/L2 hits and hit rates beside Table 1's
// figures for the same context, and whether they agree.
TEST(Report, OpensWithTheStudysQuestions) {
  auto traced = [](const char* geometry, std::uint64_t seed, double l1_hits, double l1_misses) {
    test::SynthCell c = cell(geometry, json{64, 36}, seed);
    c.axes = {{"geometry", geometry}};
    c.config_patch = {{"jitter", "shared"}};
    json l1 = {{"requests", l1_hits + l1_misses}, {"hits", l1_hits}, {"misses", l1_misses}};
    json l2 = {{"requests", 3000}, {"hits", 1000}, {"misses", 2000}};
    // Per lane, as the model counts it beside the requests: more hits, the same misses.
    json by = {{"lane", {{"lookups", 7 * l1_hits + l1_misses}, {"hits", 7 * l1_hits}, {"misses", l1_misses}}}};
    c.cache = {{"preset", "vega56"},
               {"passes", {{{"pass", "reflections"}, {"l1", l1}, {"l2", l2}, {"l1_by_counting", by}}}}};
    return test::cell(c);
  };
  // Cells in the other order (indexed first): the section still reads soup -> indexed.
  const Report r = build_report({traced("indexed", 1, 4000, 1000), traced("soup", 2, 5000, 1000)});
  const std::string& md = r.markdown;
  const size_t q = md.find("## The study's questions");
  ASSERT_NE(q, std::string::npos) << md;
  EXPECT_LT(q, md.find("## Environment")) << "first";
  EXPECT_NE(md.find("### Index buffer (EBO) against de-indexed triangles: `geometry` soup → indexed"),
            std::string::npos);
  // Ours: 5,000 -> 4,000 L1 hits (-20.0%), lower; the study (offset, since jitter is shared): +28.3%.
  EXPECT_NE(md.find("| L1 hits | 5,000 → 4,000 | -20.0% | lower | 4,873,530 → 6,251,450 (+28.3%, offset + noEBO → "
                    "offset + EBO) | disagrees |"),
            std::string::npos)
      << md;
  // Hit rate: 83.3% -> 80.0%, the study's 94.4% -> 96.0%.
  EXPECT_NE(md.find("| L1 hit rate | 83.3% → 80.0% | -3.3 pp | lower | 94.4% → 96.0% (+1.7 pp"), std::string::npos)
      << md;
  // Per lane: 35,000 -> 28,000 (-20.0%), at 97.2% -> 96.6% (-0.67 pp).
  EXPECT_NE(md.find("| L1 hits per lane | 35,000 → 28,000 | -20.0% | lower | 4,873,530 → 6,251,450"), std::string::npos)
      << md;
  EXPECT_NE(md.find("| L1 hit rate per lane | 97.2% → 96.6% | -0.7 pp | lower |"), std::string::npos) << md;
  // L2: the same counts in both cells, the study's hits fell: no change here.
  EXPECT_NE(md.find("| L2 hits | 1,000 → 1,000 | +0.0% | same | 115,552 → 91,876 (-20.5%"), std::string::npos) << md;
  EXPECT_NE(md.find("disagrees: no change here"), std::string::npos);
  EXPECT_NE(md.find("| reflections time |"), std::string::npos);
  EXPECT_NE(md.find("not comparable: the study gives no time for this comparison"), std::string::npos);
  // Without cache tables the counts are not comparable, and say why.
  test::SynthCell a = cell("soup", json{64, 36}, 1), b = cell("indexed", json{64, 36}, 2);
  a.axes = {{"geometry", "soup"}};
  b.axes = {{"geometry", "indexed"}};
  const std::string bare = build_report({test::cell(a), test::cell(b)}).markdown;
  EXPECT_NE(bare.find("not comparable: this run's cells carry no cache tables of the reflection pass"),
            std::string::npos)
      << bare;
  // An axis the study did not vary: no such section.
  test::SynthCell small = cell("indexed", json{64, 36}, 1), big = cell("indexed", json{128, 72}, 2);
  small.axes = {{"resolution", {64, 36}}};
  big.axes = {{"resolution", {128, 72}}};
  EXPECT_EQ(build_report({test::cell(small), test::cell(big)}).markdown.find("## The study's questions"),
            std::string::npos);
}

// A cell kept by `run --reuse-stale` (measured by another build): the report says so, and no time compared
// with it gets a verdict other than "inconclusive", however large the change.
TEST(Report, StaleCellsAreMarkedAndInconclusive) {
  CellResult a = test::cell(cell("indexed", json{64, 36}, 1)), b = test::cell(cell("soup", json{64, 36}, 2, 1.5));
  a.axes = {{"geometry", "indexed"}};
  b.axes = {{"geometry", "soup"}};
  b.line["stale"] = {{"measured_by", "commit 0123456789ab, llvmpipe / Mesa"}, {"reused_by", "commit abc123"}};
  const Report r = build_report({a, b});
  EXPECT_NE(r.markdown.find("> **Stale:** measured by commit 0123456789ab, llvmpipe / Mesa, kept by `run "
                            "--reuse-stale` under commit abc123"),
            std::string::npos)
      << r.markdown;
  const auto f = findings_by_pass(r);
  ASSERT_EQ(f.size(), 5u);
  for (const auto& [pass, e] : f) EXPECT_EQ(e["verdict"], "inconclusive") << e.dump();
}

// Too few frames for any p to reach 0.05: "inconclusive", never "slower" or "no change".
TEST(Report, TooFewFramesAreInconclusive) {
  auto few = [](const char* g, std::uint64_t seed, double scale) {
    test::SynthCell c = cell(g, json{64, 36}, seed, scale);
    c.passes = test::passes(3, seed, 0.02, scale);
    return test::cell(c);
  };
  const Report r = build_report({few("indexed", 1, 1.0), few("soup", 2, 1.5)});
  size_t n = 0;
  const json f = json::parse(r.findings);
  for (const json& e : f["comparisons"]) {
    EXPECT_EQ(e["verdict"], "inconclusive") << e.dump();
    ++n;
  }
  EXPECT_GT(n, 0u);
}

TEST(Report, RendersCacheTablesWhenPresent) {
  // The schema analyse_trace writes (profiler/cache_analysis.cpp).
  auto with_cache = [](const char* g, double l1_hits, std::uint64_t seed) {
    test::SynthCell c = cell(g, json{64, 36}, seed);
    json level1 = {{"requests", l1_hits + 291719}, {"hits", l1_hits}, {"misses", 291719}};
    json level2 = {{"requests", 333027}, {"hits", 115552}, {"misses", 217475}};
    c.cache = {{"preset", "vega56"},
               {"passes",
                {{{"pass", "reflections"},
                  {"l1", level1},
                  {"l2", level2},
                  {"buffers",
                   {{"bvh_nodes",
                     {{"l1_requests", 4100000}, {"l1_misses", 100000}, {"l2_requests", 100000}, {"l2_misses", 7}}}}},
                  {"mrc", {{"l1", {{"points", {{1024, 0.5}, {2048, 0.3}, {4096, 0.1}}}}}}},
                  {"heatmaps", {{"l1_misses", "cells/x/reflections_l1_misses.png"}}},
                  {"heatmap_max", {{"l1_misses", 95}}}}}}};
    return test::cell(c);
  };
  const Report r = build_report({with_cache("indexed", 4873530, 1), with_cache("soup", 6251450, 2)});
  const std::string& md = r.markdown;
  EXPECT_NE(md.find("| pass | L1 hit | L1 miss | L2 hit | L2 miss | L1 hit rate | L2 hit rate |"), std::string::npos);
  EXPECT_NE(md.find("| reflections | 4,873,530 | 291,719 | 115,552 | 217,475 | 94.4% | 34.7% |"), std::string::npos)
      << md;
  EXPECT_NE(md.find("| reflections | bvh_nodes | 4,100,000 | 100,000 | 97.6% |"), std::string::npos);
  EXPECT_NE(md.find("reflections L1 hits +28.3% (4,873,530 → 6,251,450)"), std::string::npos);
  EXPECT_NE(md.find("(cells/x/reflections_l1_misses.png)"), std::string::npos);
  // Each heatmap with its colour bar, up to the count the tables give as the top of its scale.
  const auto bar = std::find_if(r.charts.begin(), r.charts.end(), [](const ReportFile& f) {
    return f.path.starts_with("charts/heatmap_") && f.path.ends_with("_reflections_l1_misses.svg");
  });
  ASSERT_NE(bar, r.charts.end());
  EXPECT_NE(bar->content.find("reflections L1 misses per pixel (log scale)"), std::string::npos);
  EXPECT_NE(bar->content.find(">95</text>"), std::string::npos);
  EXPECT_NE(md.find("![colour bar](" + bar->path + ")"), std::string::npos) << md;
  EXPECT_NE(md.find("2 of 2 cells carry cache tables"), std::string::npos);
  EXPECT_NE(md.find("Our L1-hit changes for the same comparison"), std::string::npos);
  EXPECT_EQ(std::count_if(r.charts.begin(), r.charts.end(),
                          [](const ReportFile& f) { return f.path.starts_with("charts/mrc_"); }),
            2);
  // Cache counts are deterministic metrics; the curves are not listed.
  const auto m = deterministic_metrics(with_cache("indexed", 4873530, 1));
  EXPECT_EQ(m.at("cache/reflections/l1/hits"), 4873530);
  EXPECT_EQ(m.at("cache/reflections/buffers/bvh_nodes/l1_misses"), 100000);
  EXPECT_EQ(m.count("cache/reflections/mrc/l1/points"), 0u);
  // Invocations counted in the run's untimed frame are a per-frame metric of their own.
  auto counted = with_cache("indexed", 4873530, 1);
  Counters invocations;
  invocations.set("shadows", counter::compute_invocations, 2304);
  counted.timing.timings.set_frame_invocations(invocations);
  const auto mi = deterministic_metrics(counted);
  EXPECT_EQ(mi.at("shadows/compute_invocations_per_frame"), 2304);
  EXPECT_EQ(mi.count("shadows/compute_invocations"), 0u);
}

TEST(Report, SingleCellAndFewFrames) {
  test::SynthCell c;
  c.passes = test::passes(3, 1);
  const std::string md = build_report({test::cell(c)}).markdown;
  EXPECT_NE(md.find("— (n < 6)"), std::string::npos);
  EXPECT_NE(md.find("no axes"), std::string::npos);
}

TEST(Report, WritesFilesAtomically) {
  const std::string dir = test::temp_dir("report");
  std::vector<json> lines;
  std::uint64_t seed = 1;
  for (const char* g : {"indexed", "soup"}) lines.push_back(test::line(cell(g, json{64, 36}, seed++)));
  test::write_results(dir, lines);
  const std::string path = write_report(dir);
  EXPECT_EQ(path, dir + "/report.md");
  EXPECT_TRUE(fs::exists(dir + "/report.md"));
  EXPECT_TRUE(fs::exists(dir + "/charts/pass_times.svg"));
  for (const auto& e : fs::recursive_directory_iterator(dir))
    EXPECT_EQ(e.path().string().find(".tmp."), std::string::npos) << e.path();
  // Charts of an earlier report that this one does not draw are removed; other files in charts/ stay.
  std::ofstream(dir + "/charts/vs_width_7.svg") << "<svg/>";
  std::ofstream(dir + "/charts/pass_times.png") << "png";
  write_report(dir);
  EXPECT_FALSE(fs::exists(dir + "/charts/vs_width_7.svg"));
  EXPECT_TRUE(fs::exists(dir + "/charts/pass_times.png"));
  EXPECT_TRUE(fs::exists(dir + "/charts/pass_times.svg"));
  std::ifstream report_in(dir + "/report.md");
  const std::string md{std::istreambuf_iterator<char>(report_in), {}};
  for (const auto& e : fs::directory_iterator(dir + "/charts")) {
    if (e.path().extension() == ".svg") {
      EXPECT_NE(md.find("charts/" + e.path().filename().string()), std::string::npos) << e.path();
    }
  }
  EXPECT_THROW(write_report(dir + "/nothing"), InputError);
  std::ofstream(dir + "/results.jsonl", std::ios::app) << "{not json\n";
  EXPECT_THROW(write_report(dir), InputError);
}

}  // namespace
}  // namespace hp
