// The Google Benchmark export: structure as benchmark 1.7 writes it, and (when installed) compare.py
// reading two exports.
#include "gbench_export.hpp"

#include "error.hpp"
#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <algorithm>

#include <cstdlib>
#include <filesystem>
#include <fstream>

namespace hp {
namespace {

using json = nlohmann::json;

test::SynthCell cell(const char* geometry, std::uint64_t seed, double scale = 1.0) {
  test::SynthCell c;
  c.axes = {{"geometry", geometry}, {"resolution", {128, 72}}};
  c.passes = test::passes(8, seed, 0.03, scale);
  return c;
}

TEST(GbenchExport, StructureMatchesBenchmarkJson) {
  const std::vector<CellResult> cells = {test::cell(cell("indexed", 1)), test::cell(cell("soup", 2))};
  const json doc = gbench_export(cells, "ms");
  ASSERT_TRUE(doc.contains("context"));
  EXPECT_EQ(doc["context"]["num_cpus"], 2);
  EXPECT_EQ(doc["context"]["library_build_type"], "release");
  const json& b = doc["benchmarks"];
  ASSERT_EQ(b.size(), 2u * 5u * (8u + 4u));  // cells x passes x (frames + mean/median/stddev/cv)
  const json& first = b[0];
  EXPECT_EQ(first["name"], "synth/geometry:indexed/resolution:128x72/gbuffer/manual_time");
  EXPECT_EQ(first["run_name"], first["name"]);
  EXPECT_EQ(first["run_type"], "iteration");
  EXPECT_EQ(first["repetitions"], 8);
  EXPECT_EQ(first["repetition_index"], 0);
  EXPECT_EQ(first["iterations"], 1);
  EXPECT_EQ(first["time_unit"], "ms");
  const std::vector<double> gb = pass_samples(cells[0].timing)[0].second;
  EXPECT_DOUBLE_EQ(first["real_time"].get<double>(), gb[0] / 1e6);
  const json& median = b[9];
  EXPECT_EQ(median["name"], "synth/geometry:indexed/resolution:128x72/gbuffer/manual_time_median");
  EXPECT_EQ(median["run_type"], "aggregate");
  EXPECT_EQ(median["aggregate_name"], "median");
  // The aggregates are the samples' own: the median of 8 is the mean of the middle two, as benchmark's.
  std::vector<double> sorted = gb;
  std::sort(sorted.begin(), sorted.end());
  ASSERT_EQ(sorted.size(), 8u);
  EXPECT_NEAR(median["real_time"].get<double>(), (sorted[3] + sorted[4]) / 2.0 / 1e6, 1e-12);
  double sum = 0.0;
  for (double v : gb) sum += v;
  EXPECT_EQ(b[8]["aggregate_name"], "mean");
  EXPECT_NEAR(b[8]["real_time"].get<double>(), sum / 8.0 / 1e6, 1e-12);
  EXPECT_NE(b[8]["real_time"], median["real_time"]);
  EXPECT_EQ(b[11]["aggregate_name"], "cv");
  EXPECT_EQ(b[11]["aggregate_unit"], "percentage");
  EXPECT_EQ(b[12]["family_index"], 1);
  // Other units scale.
  EXPECT_DOUBLE_EQ(gbench_export(cells, "us")["benchmarks"][0]["real_time"].get<double>(), gb[0] / 1e3);
  EXPECT_THROW(gbench_export(cells, "minutes"), InputError);
}

TEST(GbenchExport, CompareScriptReadsTwoExports) {
  const char* script = "/usr/share/benchmark/compare.py";
  if (!std::filesystem::exists(script)) GTEST_SKIP() << "compare.py not installed (Debian libbenchmark-tools)";
  // Debian's python3-scipy lives under /usr/bin/python3, which a pyenv or venv on PATH may hide.
  std::string python;
  for (const char* candidate : {"python3", "/usr/bin/python3"}) {
    if (std::system((std::string(candidate) + " -c 'import scipy' > /dev/null 2>&1").c_str()) == 0) {
      python = candidate;
      break;
    }
  }
  if (python.empty()) GTEST_SKIP() << "python3-scipy not installed";
  const std::string dir = test::temp_dir("gbench");
  test::write_results(dir + "/a", {test::line(cell("indexed", 1))});
  test::write_results(dir + "/b", {test::line(cell("indexed", 2, 1.3))});
  write_gbench_export(dir + "/a", dir + "/a.json");
  write_gbench_export(dir + "/b", dir + "/b.json");
  const std::string cmd =
      python + " " + script + " benchmarks " + dir + "/a.json " + dir + "/b.json > " + dir + "/out.txt 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::ifstream in(dir + "/out.txt");
  const std::string out((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // compare.py paired the benchmarks by name and ran its U test (8 repetitions a side).
  EXPECT_NE(out.find("synth/geometry:indexed/resolution:128x72/shadows/manual_time_pvalue"), std::string::npos) << out;
  EXPECT_NE(out.find("+0.3"), std::string::npos) << out;  // the 30% slower shadow pass
}

}  // namespace
}  // namespace hp
