// Speed against error: the Pareto front, the metric names, and the report sections a matrix's
// "report" spec asks for, on synthetic cells.
#include "tradeoff.hpp"

#include "error.hpp"
#include "report.hpp"
#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <regex>

namespace hp {
namespace {

using json = nlohmann::json;

const ReportFile* chart(const Report& r, const std::string& path) {
  for (const ReportFile& f : r.charts)
    if (f.path == path) return &f;
  return nullptr;
}
size_t occurrences(const std::string& s, const std::string& what) {
  size_t n = 0;
  for (size_t p = s.find(what); p != std::string::npos; p = s.find(what, p + 1)) ++n;
  return n;
}

// ---- Pareto front ----

TEST(ParetoFront, MinimisesBoth) {
  // (1,9) (2,4) (5,1) are the front; (3,6) is dominated by (2,4), (6,8) by all of them.
  EXPECT_EQ(pareto_front({{3, 6}, {1, 9}, {6, 8}, {5, 1}, {2, 4}}),
            (std::vector<bool>{false, true, false, true, true}));
  EXPECT_TRUE(pareto_front({}).empty());
  EXPECT_EQ(pareto_front({{7, 7}}), std::vector<bool>{true});
}

TEST(ParetoFront, TiesAndDuplicates) {
  // Same x: only the lower y is on the front; same y: only the lower x.
  EXPECT_EQ(pareto_front({{1, 5}, {1, 3}, {4, 1}, {6, 1}}), (std::vector<bool>{false, true, true, false}));
  // Exact duplicates dominate neither each other: both on the front (or both off it).
  EXPECT_EQ(pareto_front({{2, 2}, {2, 2}, {3, 3}, {3, 3}}), (std::vector<bool>{true, true, false, false}));
}

TEST(ParetoFront, NanNeverOnTheFrontAndDominatesNothing) {
  const double nan = std::nan("");
  EXPECT_EQ(pareto_front({{nan, 0}, {0, nan}, {5, 5}, {nan, nan}}), (std::vector<bool>{false, false, true, false}));
  EXPECT_EQ(pareto_front({{-INFINITY, 3}, {0, 0}}), (std::vector<bool>{true, true}));
}

// ---- metrics ----

test::SynthCell base_cell(json axes, std::uint64_t seed, double shadows_scale = 1.0) {
  test::SynthCell c;
  c.axes = std::move(axes);
  c.passes = test::passes(21, seed, 0.02, shadows_scale);
  c.counters_per_frame.set("shadows", "rays_cast", 10000);
  c.counters_per_frame.set("shadows", "nodes_visited", 150000);
  return c;
}

TEST(Metric, TimeSumsPassesPerFrameBeforeTheMedian) {
  test::SynthCell s;
  // Per-frame sums 2, 5, 5 ms: median 5, while the medians of the passes add to 4.
  s.passes = {{"a", {1e6, 2e6, 3e6}}, {"b", {1e6, 3e6, 2e6}}};
  const CellResult c = test::cell(s);
  const auto v = resolve_metric(c, "time:a+b", "t");
  ASSERT_TRUE(v);
  EXPECT_DOUBLE_EQ(v->value, 5.0);
  EXPECT_TRUE(v->is_time);
  EXPECT_FALSE(v->ci) << "3 frames reach no 95% CI";
  EXPECT_DOUBLE_EQ(resolve_metric(c, "time:frame", "t")->value, 5.0);
  EXPECT_DOUBLE_EQ(resolve_metric(c, "time:a", "t")->value, 2.0);
  std::string why;
  EXPECT_FALSE(resolve_metric(c, "time:a+zz", "t", &why));
  EXPECT_NE(why.find("zz"), std::string::npos);
}

TEST(Metric, TimeHasACiAndImageTimeScalesByFrames) {
  test::SynthCell s = base_cell(json::object(), 1);
  s.error = test::error_json(0.002, 40.0, 16);
  const CellResult c = test::cell(s);
  const auto t = resolve_metric(c, "time:shadows+reflections", "t");
  ASSERT_TRUE(t && t->ci);
  EXPECT_NEAR(t->value, 10.0, 0.1);
  EXPECT_LE(t->ci->first, t->value);
  EXPECT_GE(t->ci->second, t->value);
  EXPECT_NEAR(resolve_metric(c, "time:frame", "t")->value, 22.9, 0.3);
  const auto img = resolve_metric(c, "image_time:shadows+reflections", "t");
  ASSERT_TRUE(img && img->ci);
  EXPECT_DOUBLE_EQ(img->value, t->value * 16);
  EXPECT_DOUBLE_EQ(img->ci->second, t->ci->second * 16);
  // Without error metrics there is no frame count.
  EXPECT_FALSE(resolve_metric(test::cell(base_cell(json::object(), 1)), "image_time:shadows", "t"));
}

TEST(Metric, PerRayAndPointers) {
  test::SynthCell s = base_cell(json::object(), 1);
  s.error = test::error_json(0.002, std::nullopt);
  s.cache = test::cache_json("reflections", 900, 100, 50, 50, 1000, 100, 3.2);
  const CellResult c = test::cell(s);
  EXPECT_DOUBLE_EQ(resolve_metric(c, "per_ray:shadows/nodes_visited", "t")->value, 15.0);
  EXPECT_FALSE(resolve_metric(c, "per_ray:shadows/triangles_tested", "t"));   // not counted
  EXPECT_FALSE(resolve_metric(c, "per_ray:reflections/nodes_visited", "t"));  // no rays counted there
  EXPECT_DOUBLE_EQ(resolve_metric(c, "/error/image/relmse", "t")->value, 0.002);
  EXPECT_DOUBLE_EQ(resolve_metric(c, "/bvh/build_ms", "t")->value, 28.0);
  EXPECT_DOUBLE_EQ(resolve_metric(c, "/bvh/sah_cost", "t")->value, 5.957);
  EXPECT_DOUBLE_EQ(resolve_metric(c, "/cache/simulation_s", "t")->value, 3.2);
  EXPECT_DOUBLE_EQ(resolve_metric(c, "/error/shadow/acne", "t")->value, 12.0);
  EXPECT_DOUBLE_EQ(resolve_metric(c, "/error/depth/bins/1/mean_rel", "t")->value, 1e-7);
  std::string why;
  EXPECT_FALSE(resolve_metric(c, "/error/image/psnr_db", "t", &why));  // null: infinite, not a number
  EXPECT_EQ(why, "missing or null");
  EXPECT_FALSE(resolve_metric(c, "/error/reference/id", "t", &why));
  EXPECT_NE(why.find("string"), std::string::npos);
  EXPECT_FALSE(resolve_metric(c, "/error/depth/bins/x", "t"));
  EXPECT_FALSE(resolve_metric(c, "/result/summary", "t")) << "the timing object is not reachable";
}

TEST(Metric, BadNamesThrowNamingThem) {
  for (const char* bad : {"speed", "time:", "time:a++b", "time:frame+a", "per_ray:shadows", "per_ray:/rays",
                          "per_ray:a/b/c", "/error/~2", "relmse"}) {
    try {
      check_metric(bad, "report spec: tradeoffs[0] \"T\"");
      ADD_FAILURE() << bad << " accepted";
    } catch (const InputError& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find(std::string("'") + bad + "'"), std::string::npos) << m;
      EXPECT_NE(m.find("\"T\""), std::string::npos) << m;
    }
  }
  EXPECT_NO_THROW(check_metric("time:frame", "x"));
  EXPECT_NO_THROW(check_metric("image_time:shadows+reflections", "x"));
  EXPECT_NO_THROW(check_metric("/", "x"));
}

// ---- report sections ----

json tradeoff_spec() {
  return {{"tradeoffs",
           {{{"title", "Shadow time against image error"},
             {"x", "time:shadows"},
             {"y", "/error/image/relmse"},
             {"x_label", "shadow pass"},
             {"y_label", "relMSE"},
             {"log_y", true},
             {"columns", {"/error/image/psnr_db", "per_ray:shadows/nodes_visited", "/error/shadow/acne"}}}}}};
}

// spp 1..4: shadow medians 3.0, 2.4, 2.7, 1.8 ms with relMSE 0.001, 0.002, 0.003, 0.01: the front is
// spp 1, 2 and 4; spp 3 is dominated by spp 2. spp 5 has no error metrics.
std::vector<CellResult> tradeoff_matrix(json spec = tradeoff_spec()) {
  const double scale[] = {1.0, 0.8, 0.9, 0.6, 0.7};
  const double relmse[] = {0.001, 0.002, 0.003, 0.01, 0};
  std::vector<CellResult> cells;
  for (int i = 0; i < 5; ++i) {
    test::SynthCell s = base_cell({{"spp", i + 1}}, std::uint64_t(i + 1), scale[i]);
    s.report = spec;
    if (i < 4) s.error = test::error_json(relmse[i], i == 0 ? std::nullopt : std::optional<double>(40.0 - i));
    cells.push_back(test::cell(s));
  }
  return cells;
}

TEST(TradeoffSection, TableSortedByXWithFrontMarks) {
  const Report r = build_report(tradeoff_matrix());
  const std::string& md = r.markdown;
  ASSERT_NE(md.find("## Speed against error"), std::string::npos) << md;
  ASSERT_NE(md.find("### Shadow time against image error"), std::string::npos);
  EXPECT_NE(
      md.find("| cell | shadow pass (ms, 95% CI) | relMSE | `/error/image/psnr_db` | `per_ray:shadows/nodes_visited` | "
              "`/error/shadow/acne` | Pareto |"),
      std::string::npos)
      << md;
  // Rows in x order with the CI, the extra columns and the front marks.
  const std::regex row(
      R"(\| spp=(\d) \| (\d\.\d{3}) \[(\d\.\d{3}), (\d\.\d{3})\] \| ([0-9.]+) \| ([^|]+) \| 15 \| 12 \| (\*\*yes\*\* \(\d\)|no) \|)");
  std::vector<std::string> order, marks;
  for (auto it = std::sregex_iterator(md.begin(), md.end(), row); it != std::sregex_iterator(); ++it) {
    const std::smatch& m = *it;
    order.push_back(m[1]);
    marks.push_back(m[7]);
    EXPECT_LE(std::stod(m[3]), std::stod(m[2]));
    EXPECT_GE(std::stod(m[4]), std::stod(m[2]));
    EXPECT_EQ(m[6] == "—", m[1] == "1") << "spp 1 has an infinite PSNR: no number for the column";
  }
  EXPECT_EQ(order, (std::vector<std::string>{"4", "2", "3", "1"}));
  // The front is numbered in x order; the chart labels its points with these numbers.
  EXPECT_EQ(marks, (std::vector<std::string>{"**yes** (1)", "**yes** (2)", "no", "**yes** (3)"}));
  EXPECT_NE(md.find("3 of 4 cells are on the Pareto front"), std::string::npos);
  EXPECT_NE(md.find(": (1) spp=4 (1.8"), std::string::npos) << "the front listed in x order";
  EXPECT_NE(md.find("the other 1 are dominated"), std::string::npos);
  // The cell without error metrics is left out and named in a note.
  EXPECT_TRUE(std::regex_search(
      md, std::regex(R"(\*Note:\* Not available, left out: spp=5 \(`/error/image/relmse`: missing or null\))")))
      << md;
  // The chart: linked, with the front highlighted on a log y axis.
  EXPECT_NE(md.find("](charts/tradeoff_1.svg)"), std::string::npos);
  const ReportFile* svg = chart(r, "charts/tradeoff_1.svg");
  ASSERT_NE(svg, nullptr);
  EXPECT_EQ(occurrences(svg->content, "class=\"pareto\""), 1u);
  EXPECT_EQ(occurrences(svg->content, "class=\"point front\""), 3u);
  EXPECT_EQ(occurrences(svg->content, "class=\"point\""), 1u);
  EXPECT_NE(svg->content.find("relMSE (log)"), std::string::npos);
  EXPECT_NE(svg->content.find(">0.001<"), std::string::npos);
  for (const char* label : {">1</text>", ">2</text>", ">3</text>"})
    EXPECT_NE(svg->content.find(label), std::string::npos);
  EXPECT_EQ(svg->content.find(">spp=4</text>"), std::string::npos) << "front points carry numbers, not names";
}

// Without log_x / log_y in the spec an axis is log10 where its values span two decades or more (every
// value positive), so that a front from 170 to 140,000 wrong pixels is not flattened against the axis; the
// spec's own choice wins either way.
TEST(TradeoffSection, LogAxesWhereTheValuesSpanDecades) {
  json spec = tradeoff_spec();
  spec["tradeoffs"][0].erase("log_y");
  spec["tradeoffs"][0]["y"] = "/error/shadow/leaks";
  spec["tradeoffs"][0]["y_label"] = "leaks";
  std::vector<CellResult> cells = tradeoff_matrix(spec);
  const int leaks[] = {170, 1485, 23685, 140000};
  for (int i = 0; i < 4; ++i) cells[size_t(i)].line["error"]["shadow"]["leaks"] = leaks[i];
  const ReportFile* svg = chart(build_report(cells), "charts/tradeoff_1.svg");
  ASSERT_NE(svg, nullptr);
  EXPECT_NE(svg->content.find("leaks (log)"), std::string::npos) << "170 .. 140,000 spans three decades";
  EXPECT_EQ(svg->content.find("shadow pass (log)"), std::string::npos) << "1.8 .. 3.0 ms is one linear axis";
  // Less than a factor of 100: linear.
  for (int i = 0; i < 4; ++i) cells[size_t(i)].line["error"]["shadow"]["leaks"] = 100 + 30 * i;
  svg = chart(build_report(cells), "charts/tradeoff_1.svg");
  ASSERT_NE(svg, nullptr);
  EXPECT_EQ(svg->content.find("leaks (log)"), std::string::npos);
  // The spec says linear: linear, whatever the span.
  spec["tradeoffs"][0]["log_y"] = false;
  std::vector<CellResult> linear = tradeoff_matrix(spec);
  for (int i = 0; i < 4; ++i) linear[size_t(i)].line["error"]["shadow"]["leaks"] = leaks[i];
  svg = chart(build_report(linear), "charts/tradeoff_1.svg");
  ASSERT_NE(svg, nullptr);
  EXPECT_EQ(svg->content.find("leaks (log)"), std::string::npos);
}

// Cells of different scenes (here the same scene scaled by `transform`) are not one front: each scene gets
// its own heading, chart and front, so a cell of one scene never dominates a cell of another.
TEST(TradeoffSection, OneFrontPerScene) {
  std::vector<CellResult> cells;
  const double scale[] = {1.0, 0.8, 0.9, 0.6};
  const double relmse[] = {0.001, 0.002, 0.003, 0.01};
  for (int i = 0; i < 4; ++i) {
    test::SynthCell s = base_cell({{"spp", i % 2 + 1}, {"transform", {{"scale", i < 2 ? 1.0 : 1000.0}}}},
                                  std::uint64_t(i + 1), scale[i]);
    s.config_patch = {{"transform", {{"scale", i < 2 ? 1.0 : 1000.0}}}};
    s.report = tradeoff_spec();
    s.error = test::error_json(relmse[i], 40.0 - i);
    cells.push_back(test::cell(s));
  }
  const Report r = build_report(cells);
  const std::string& md = r.markdown;
  EXPECT_NE(md.find("The cells render 2 different scenes (scene or transform); each has its own Pareto front."),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("#### scene builtin:pica, transform.scale 1.0"), std::string::npos) << md;
  EXPECT_NE(md.find("#### scene builtin:pica, transform.scale 1000.0"), std::string::npos) << md;
  ASSERT_NE(chart(r, "charts/tradeoff_1_1.svg"), nullptr);
  ASSERT_NE(chart(r, "charts/tradeoff_1_2.svg"), nullptr);
  EXPECT_EQ(chart(r, "charts/tradeoff_1.svg"), nullptr);
  // Within each scene both cells trade speed for error: 2 of 2 on each front (one front over all four would
  // put the scaled scene's 0.6x cell against the first scene's).
  EXPECT_EQ(occurrences(md, "Every cell is on the Pareto front"), 2u) << md;
}

TEST(TradeoffSection, ErrorMetricsParagraphAndCellTable) {
  const std::string md = build_report(tradeoff_matrix()).markdown;
  ASSERT_NE(md.find("## Error metrics"), std::string::npos);
  for (const char* s :
       {"ε = 0.01", "peak = 1 ", "not OpenImageIO's PSNR, which uses max(1, peak)", "exceeds 0.1",
        "Andersson et al. 2020", "**acne** = shadowed in the frame but lit in the reference",
        "**leaks** = lit in the frame but shadowed", "|reconstructed − true world position| / true distance"})
    EXPECT_NE(md.find(s), std::string::npos) << s;
  // Per cell: spp 1 has identical images (PSNR null), spp 2 a finite one.
  EXPECT_NE(md.find("| PSNR (peak 1) | ∞ |"), std::string::npos) << md;
  EXPECT_NE(md.find("| PSNR (peak 1) | 38.00 dB |"), std::string::npos);
  for (const char* s :
       {"| reference | `0123456789abcdef`, 256 samples per pixel, rendered in 12.3 s (cached) |",
        "| frames accumulated | 16 |", "| relMSE (ε = 0.01) | 0.002 |", "| pixels over 0.1 | 120 (0.013% of 921,600) |",
        "| FLIP (mean) | 0.0500 |", "| shadow acne / leaks | 12 / 3 of 800,000 compared pixels |",
        "| shadow coverage mismatches | 40 |"})
    EXPECT_NE(md.find(s), std::string::npos) << s;
  EXPECT_EQ(occurrences(md, "Error against the reference:"), 4u);
  // No error metrics anywhere: no paragraph and no speed-against-error section without a spec.
  std::vector<CellResult> plain = {test::cell(base_cell({{"spp", 1}}, 1)), test::cell(base_cell({{"spp", 2}}, 2))};
  const std::string md2 = build_report(plain).markdown;
  EXPECT_EQ(md2.find("## Error metrics"), std::string::npos);
  EXPECT_EQ(md2.find("## Speed against error"), std::string::npos);
}

TEST(TradeoffSection, BadMetricThrowsNamingItAndTheSection) {
  json spec = tradeoff_spec();
  spec["tradeoffs"][0]["columns"] = {"per_ray:shadows"};
  try {
    build_report(tradeoff_matrix(spec));
    FAIL() << "accepted";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("'per_ray:shadows'"), std::string::npos) << m;
    EXPECT_NE(m.find("Shadow time against image error"), std::string::npos) << m;
  }
  spec = tradeoff_spec();
  spec["tradeoffs"][0]["x"] = "time:shadowz";  // a pass no cell ran: a typo, not "not available"
  try {
    build_report(tradeoff_matrix(spec));
    FAIL() << "accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("shadowz"), std::string::npos) << e.what();
  }
  spec = tradeoff_spec();
  spec["tradeoffs"][0].erase("y");
  EXPECT_THROW(build_report(tradeoff_matrix(spec)), InputError);
  EXPECT_THROW(build_report(tradeoff_matrix({{"tradeoffs", 3}})), InputError);
  EXPECT_THROW(build_report(tradeoff_matrix({{"depth_error", "yes"}})), InputError);
}

TEST(TradeoffSection, LogAxisFallsBackWhenAValueIsZero) {
  json spec = tradeoff_spec();
  spec["tradeoffs"][0]["y"] = "/error/shadow/leaks";
  spec["tradeoffs"][0]["y_label"] = "leaks";
  spec["tradeoffs"][0]["log_x"] = true;
  std::vector<CellResult> cells = tradeoff_matrix(spec);
  cells[1].line["error"]["shadow"]["leaks"] = 0;
  const Report r = build_report(cells);
  EXPECT_NE(r.markdown.find("The y axis is linear: a value is <= 0"), std::string::npos);
  EXPECT_EQ(r.markdown.find("The x axis is linear"), std::string::npos);
  const ReportFile* svg = chart(r, "charts/tradeoff_1.svg");
  ASSERT_NE(svg, nullptr);
  EXPECT_NE(svg->content.find("shadow pass (log)"), std::string::npos);
  EXPECT_EQ(svg->content.find("leaks (log)"), std::string::npos);
}

std::vector<CellResult> sampling_matrix() {
  // geometry=indexed traced in full and every 4th and 16th ray; geometry=soup only every 4th ray.
  struct Row {
    const char* geometry;
    int k;
    double l1_hits, l2_hits, buffer_misses, sim_s;
  };
  const Row rows[] = {{"indexed", 1, 900, 50, 100, 10.0},
                      {"indexed", 4, 890, 52, 120, 2.5},
                      {"indexed", 16, 850, 60, 200, 1.0},
                      {"soup", 4, 700, 40, 300, 2.0}};
  std::vector<CellResult> cells;
  std::uint64_t seed = 1;
  for (const Row& r : rows) {
    test::SynthCell s = base_cell({{"geometry", r.geometry}, {"trace.sample_every", r.k}}, seed++);
    s.config_patch = {{"trace", {{"passes", {"reflections"}}, {"sample_every", r.k}}}, {"trace.sample_every", nullptr}};
    s.cache = test::cache_json("reflections", r.l1_hits, 1000 - r.l1_hits, r.l2_hits, 100 - r.l2_hits, 1000,
                               r.buffer_misses, r.sim_s);
    s.report = {{"cache_sampling", true}};
    cells.push_back(test::cell(s));
  }
  return cells;
}

TEST(CacheSamplingSection, ErrorsAgainstTheFullTrace) {
  const Report r = build_report(sampling_matrix());
  const std::string& md = r.markdown;
  ASSERT_NE(md.find("### Cache simulation on sampled traces"), std::string::npos) << md;
  ASSERT_NE(md.find("#### reflections"), std::string::npos);
  for (const char* s :
       {"| geometry=indexed, bursts of 1 workgroup | 1 | 90.00% | — | 50.00% | — | — | 10.00 | 1× |",
        "| geometry=indexed, bursts of 1 workgroup | 4 | 89.00% | 1.000 | 52.00% | 2.000 | 2.000 | 2.50 | 4.0× |",
        "| geometry=indexed, bursts of 1 workgroup | 16 | 85.00% | 5.000 | 60.00% | 10.000 | 10.000 | 1.00 | 10.0× |"})
    EXPECT_NE(md.find(s), std::string::npos) << s << "\n" << md;
  EXPECT_LT(md.find("| geometry=indexed, bursts of 1 workgroup | 4 |"),
            md.find("| geometry=indexed, bursts of 1 workgroup | 16 |"));
  // Time against error: mean |error| over L1 and L2, the full trace at 0, every point on the front here.
  for (const char* s : {"| k=16, bursts of 1 | 1.000 | 7.500 | **yes** |",
                        "| k=4, bursts of 1 | 2.500 | 1.500 | **yes** |", "| full trace | 10.000 | 0.000 | **yes** |"})
    EXPECT_NE(md.find(s), std::string::npos) << s << "\n" << md;
  EXPECT_LT(md.find("| k=16, bursts of 1 |"), md.find("| full trace |"));  // sorted by time
  const ReportFile* tradeoff = chart(r, "charts/cache_sampling_tradeoff.svg");
  ASSERT_NE(tradeoff, nullptr);
  EXPECT_NE(tradeoff->content.find("class=\"pareto\""), std::string::npos);
  // The soup cell has no full-trace partner: listed, not compared.
  EXPECT_NE(md.find("Without a full-trace partner"), std::string::npos);
  EXPECT_NE(md.find("geometry=soup, sample_every=4 (sample_every 4)"), std::string::npos) << md;
  EXPECT_EQ(md.find("| geometry=soup"), std::string::npos);
  // The chart: error against k on log axes, one line per level.
  EXPECT_NE(md.find("](charts/cache_sampling.svg)"), std::string::npos);
  const ReportFile* svg = chart(r, "charts/cache_sampling.svg");
  ASSERT_NE(svg, nullptr);
  EXPECT_EQ(occurrences(svg->content, "class=\"line\""), 2u);
  EXPECT_NE(svg->content.find(">reflections L1<"), std::string::npos);
  EXPECT_NE(svg->content.find(">reflections L2<"), std::string::npos);
  // The cell's own cache table says how long the simulation took.
  EXPECT_NE(md.find("simulated in 2.50 s"), std::string::npos);
}

TEST(CacheSamplingSection, NoSampledCells) {
  std::vector<CellResult> cells = sampling_matrix();
  cells.erase(cells.begin() + 1, cells.end());
  const std::string md = build_report(cells).markdown;
  EXPECT_NE(md.find("No traced cell samples its trace"), std::string::npos) << md;
}

TEST(DepthErrorSection, OneLinePerCellAndOverallTable) {
  std::vector<CellResult> cells;
  std::uint64_t seed = 1;
  for (bool reversed : {false, true}) {
    test::SynthCell s = base_cell({{"reversed_z", reversed}, {"geometry", "indexed"}}, seed++);
    s.error = test::error_json(0.001, 40.0, 16, reversed ? 1.0 : 100.0);
    s.report = {{"depth_error", true}};
    cells.push_back(test::cell(s));
  }
  test::SynthCell none = base_cell({{"reversed_z", true}, {"geometry", "soup"}}, seed++);
  none.report = {{"depth_error", true}};
  cells.push_back(test::cell(none));
  const Report r = build_report(cells);
  const std::string& md = r.markdown;
  ASSERT_NE(md.find("### World-position reconstruction error by distance"), std::string::npos) << md;
  EXPECT_NE(md.find("| geometry=indexed, reversed_z=false | 900,000 | 0.0001 | 0.01 | 5 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| geometry=indexed, reversed_z=true | 900,000 | 1e-06 | 0.0001 | 5 |"), std::string::npos);
  EXPECT_NE(md.find("Without depth-error numbers: geometry=soup, reversed_z=true."), std::string::npos);
  const ReportFile* svg = chart(r, "charts/depth_error.svg");
  ASSERT_NE(svg, nullptr);
  EXPECT_NE(md.find("](charts/depth_error.svg)"), std::string::npos);
  EXPECT_EQ(occurrences(svg->content, "class=\"line\""), 2u);
  EXPECT_EQ(occurrences(svg->content, "class=\"point\""), 10u);
  EXPECT_NE(svg->content.find(">reversed_z=false<"), std::string::npos);
  EXPECT_NE(svg->content.find(">reversed_z=true<"), std::string::npos);
}

TEST(TradeoffSection, SpecReadBackFromResultsFile) {
  const std::string dir = test::temp_dir("tradeoff");
  std::vector<json> lines;
  for (int i = 0; i < 2; ++i) {
    test::SynthCell s = base_cell({{"spp", i + 1}}, std::uint64_t(i + 1), 1.0 - 0.2 * i);
    s.report = tradeoff_spec();
    s.error = test::error_json(0.001 * (i + 1), 30.0);
    lines.push_back(test::line(s));
  }
  test::write_results(dir, lines);
  const std::vector<CellResult> cells = load_cells(dir);
  EXPECT_EQ(cells[0].report, tradeoff_spec());
  EXPECT_EQ(cells[0].error["frames"], 16);
  EXPECT_TRUE(cells[0].line.contains("error"));
  EXPECT_FALSE(cells[0].line.contains("result"));
  write_report(dir);
  EXPECT_TRUE(std::filesystem::exists(dir + "/charts/tradeoff_1.svg"));
}

}  // namespace
}  // namespace hp
