#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include "error.hpp"
#include "timing/result_json.hpp"
#include "timing_fixture.hpp"

namespace hp {
namespace {

namespace fs = std::filesystem;

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::temp_directory_path() / ("hp_timing_test_" + std::to_string(::getpid()));
    fs::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

FrameTimings finished_run() {
  FrameTimings t(2, 8, TimingSource::GpuTimestamps);
  for (std::uint64_t i = 0; t.add(test::synthetic_frame(i)); ++i) {
  }
  QueryOverhead q = paired_query_overhead(std::vector<double>{1'000'400.0, 1'000'500.0, 1'000'600.0, 999'900.0,
                                                              1'001'000.0, 1'000'500.0, 1'000'550.0, 1'000'450.0},
                                          std::vector<double>(8, 1'000'000.0));
  t.set_query_overhead(q);
  Counters invocations;
  invocations.set("shadows", counter::compute_invocations, 3600);
  invocations.set("composite", counter::compute_invocations, 3600);
  t.set_frame_invocations(invocations);
  // Overlapped frames 50 us shorter than the serialized frames' 600 us of passes, 40 us after frame i.
  for (std::uint64_t i = 2; i < 10; ++i) {
    const std::uint64_t b = 5'000'000'000ull + i * 1'000'000 + 640'000;
    t.add_overlapped({b, b + 550'000 + i});
  }
  return t;
}

Environment fixed_environment() {
  Environment e = capture_environment({"llvmpipe", "cpu", "llvmpipe", "Mesa 22.3.6", "22.3.6", "1.3.230"});
  return e;
}

TEST(ResultJson, RoundTripThroughAFile) {
  TempDir dir;
  const fs::path file = dir.path / "timings.json";
  const FrameTimings run = finished_run();
  const Environment env = fixed_environment();
  SummaryOptions opt;
  opt.bootstrap_resamples = 200;
  write_timing_result(file, env, run, opt);
  // Only the result is left: the temporary file was renamed.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir.path), fs::directory_iterator{}), 1);

  const TimingResult back = read_timing_result(file);
  EXPECT_EQ(back.environment, env);
  EXPECT_EQ(back.timings, run);  // raw frames, warm-up count, source, overhead
  EXPECT_EQ(back.summary, run.summarize(opt));
  EXPECT_EQ(back.counters, run.total_counters());
  ASSERT_TRUE(back.summary.passes[0].duration_ns.median_ci_bootstrap.has_value());
}

TEST(ResultJson, SchemaFieldsAreWhereTheReportLooks) {
  const FrameTimings run = finished_run();
  const nlohmann::json doc = timing_result_json(fixed_environment(), run);
  EXPECT_EQ(doc["schema"], "hybridprof.timings");
  EXPECT_EQ(doc["timing"]["source"], "gpu-timestamps");
  EXPECT_EQ(doc["timing"]["measured_frames"], 8);
  EXPECT_EQ(doc["timing"]["warmup_frames"], 2);
  EXPECT_EQ(doc["timing"]["passes"][1]["pass"], "shadows");
  EXPECT_DOUBLE_EQ(doc["timing"]["passes"][1]["duration_ns"]["median"].get<double>(), 200'000.0);
  EXPECT_EQ(doc["timing"]["passes"][1]["duration_ns"]["median_ci"]["lower_rank"], 1);
  EXPECT_TRUE(doc["timing"]["passes"][1]["duration_ns"]["median_ci_bootstrap"].is_null());
  EXPECT_DOUBLE_EQ(doc["timing"]["query_overhead"]["overhead_fraction"].get<double>(), 0.0005);
  EXPECT_DOUBLE_EQ(doc["timing"]["query_overhead"]["paired_fraction"].get<double>(), 0.0005);
  EXPECT_TRUE(doc["timing"]["query_overhead"]["paired_fraction_ci"]["valid"].get<bool>());
  EXPECT_EQ(doc["frames"].size(), 8u);
  EXPECT_EQ(doc["frames"][0]["passes"][0]["begin_ns"], 5'002'000'000ull);  // frame 2: first kept
  EXPECT_EQ(doc["frames"][0]["counters"]["shadows"]["rays_cast"], 4096);
  EXPECT_EQ(doc["counters"]["reflections"]["nodes_visited"], 8 * 80'000);
  EXPECT_EQ(doc["invocations_per_frame"]["shadows"]["compute_invocations"], 3600);
  EXPECT_EQ(doc["counters"]["shadows"].count("compute_invocations"), 0u) << "not summed over frames";
  EXPECT_FALSE(doc["environment"]["cpu_model"].get<std::string>().empty());
  EXPECT_EQ(doc["environment"]["device"]["driver_name"], "llvmpipe");
  EXPECT_EQ(doc["environment"]["device"]["driver_version"], "22.3.6");
  EXPECT_EQ(doc["timing"]["pass_isolation"], "serialized");
  ASSERT_EQ(doc["overlapped_frames"].size(), 8u);
  EXPECT_EQ(doc["overlapped_frames"][0]["end_ns"].get<std::uint64_t>() -
                doc["overlapped_frames"][0]["begin_ns"].get<std::uint64_t>(),
            550'002u);
  // Serialized sum of frame i: 600,000 + i ns; overlapped span 550,000 + i ns: a saving of 50 us each.
  EXPECT_DOUBLE_EQ(doc["timing"]["overlap"]["saving_ns"].get<double>(), 50'000.0);
  EXPECT_EQ(doc["timing"]["overlap"]["frames"], 8);
  EXPECT_TRUE(doc["timing"]["overlap"]["saving_ns_ci"]["valid"].get<bool>());
}

TEST(ResultJson, ResultsFromBeforeIsolationReadAsUnisolated) {
  nlohmann::json doc = timing_result_json(fixed_environment(), finished_run());
  doc["timing"].erase("pass_isolation");
  doc["timing"].erase("overlap");
  doc.erase("overlapped_frames");
  doc["environment"]["device"].erase("driver_version");
  const TimingResult old = parse_timing_result(doc);
  EXPECT_EQ(old.summary.pass_isolation, PassIsolation::Unisolated);
  EXPECT_EQ(old.timings.pass_isolation(), PassIsolation::Unisolated);
  EXPECT_FALSE(old.summary.overlap.has_value());
  EXPECT_TRUE(old.timings.overlapped().empty());
  EXPECT_EQ(old.environment.device.driver_version, "");
  nlohmann::json bad = timing_result_json(fixed_environment(), finished_run());
  bad["timing"]["pass_isolation"] = "sometimes";
  try {
    parse_timing_result(bad);
    FAIL() << "accepted an unknown isolation";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "timing: field 'pass_isolation': unknown pass isolation 'sometimes'");
  }
  bad = timing_result_json(fixed_environment(), finished_run());
  bad["overlapped_frames"].erase(0);
  try {
    parse_timing_result(bad);
    FAIL() << "accepted 7 overlapped frames for 8 measured ones";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "field 'overlapped_frames' holds 7 frames but 'frames' holds 8 (one per measured frame)");
  }
}

TEST(ResultJson, BadDocumentsNameTheField) {
  nlohmann::json doc = timing_result_json(fixed_environment(), finished_run());
  {
    nlohmann::json bad = doc;
    bad["frames"][3]["passes"][1].erase("end_ns");
    try {
      parse_timing_result(bad);
      FAIL() << "accepted a pass without end_ns";
    } catch (const InputError& e) {
      EXPECT_STREQ(e.what(), "frames[3]: passes[1]: missing field 'end_ns'");
    }
  }
  {
    nlohmann::json bad = doc;
    bad["timing"]["passes"][0]["duration_ns"]["median"] = "fast";
    try {
      parse_timing_result(bad);
      FAIL() << "accepted a string median";
    } catch (const InputError& e) {
      EXPECT_STREQ(e.what(), "timing: passes[0]: duration_ns: field 'median' has the wrong type or range");
    }
  }
  {
    nlohmann::json bad = doc;
    bad["frames"].erase(0);
    EXPECT_THROW(parse_timing_result(bad), InputError);
  }
  {
    nlohmann::json bad = doc;
    bad["invocations_per_frame"]["shadows"]["compute_invocations"] = -1;
    EXPECT_THROW(parse_timing_result(bad), InputError);
  }
  {  // results written before invocations were counted apart still read, without them
    nlohmann::json old = doc;
    old.erase("invocations_per_frame");
    EXPECT_TRUE(parse_timing_result(old).timings.frame_invocations().empty());
  }
  EXPECT_THROW(parse_timing_result(nlohmann::json{{"schema", "other"}}), InputError);
}

TEST(ResultJson, UnreadableOrUnwritablePathsAreInputErrors) {
  TempDir dir;
  EXPECT_THROW(read_timing_result(dir.path / "absent.json"), InputError);
  { std::ofstream(dir.path / "broken.json") << "{ not json"; }
  EXPECT_THROW(read_timing_result(dir.path / "broken.json"), InputError);
  EXPECT_THROW(write_timing_result(dir.path / "no" / "such" / "dir.json", fixed_environment(), finished_run()),
               InputError);
}

}  // namespace
}  // namespace hp
