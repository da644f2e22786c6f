// The matrix runner on a real device: one flushed line per cell, resume after an interruption (a torn last
// line included), shards that partition the matrix, and merge.
#include "vulkan_env.hpp"

#include "error.hpp"
#include "runner.hpp"

#include <filesystem>
#include <fstream>

namespace hp {
namespace {

namespace fs = std::filesystem;

Matrix tiny_matrix() {
  return parse_matrix(nlohmann::json::parse(R"({"name": "tiny",
      "base": {"scene": "builtin:cornell", "resolution": [32, 24], "frames": 2, "warmup": 0},
      "axes": {"geometry": ["indexed", "soup"], "seed": [1, 2]}})"),
                      "tiny.json");
}

TEST(Runner, ResumesShardsAndMerges) {
  HP_REQUIRE_VULKAN(ctx);
  const fs::path root = fs::temp_directory_path() / ("hp_runner_" + std::to_string(::getpid()));
  fs::remove_all(root);
  const Matrix m = tiny_matrix();
  ASSERT_EQ(m.cells.size(), 4u);
  RunOptions o;
  o.progress = false;

  // Shard 1/2 then 2/2 into separate folders; each runs two cells.
  o.out_dir = (root / "s1").string();
  o.shard = parse_shard("1/2");
  RunSummary s1 = run_matrix(m, o);
  EXPECT_EQ(s1.in_shard, 2u);
  EXPECT_EQ(s1.ran, 2u);
  o.out_dir = (root / "s2").string();
  o.shard = parse_shard("2/2");
  EXPECT_EQ(run_matrix(m, o).ran, 2u);
  const size_t merged = merge_results((root / "all").string(), {(root / "s1").string(), (root / "s2").string()});
  EXPECT_EQ(merged, 4u);
  const auto all = read_results((root / "all").string());
  ASSERT_EQ(all.size(), 4u);
  for (const auto& line : all) {
    EXPECT_EQ(line["schema"], "hybridprof.cell");
    EXPECT_TRUE(fs::exists(root / "all" / line["images"]["color"].get<std::string>()));
    EXPECT_GT(line["result"]["timing"]["passes"].size(), 0u);
    // The machine's load as the cell started and once its frames were timed.
    EXPECT_TRUE(line["load_1min"]["start"].is_number()) << line["load_1min"];
    EXPECT_TRUE(line["load_1min"]["end"].is_number()) << line["load_1min"];
    EXPECT_EQ(line["result"]["environment"]["load_1min"], line["load_1min"]["start"]);
  }
  // Merging again adds nothing (de-duplicated by id).
  EXPECT_EQ(merge_results((root / "all").string(), {(root / "s1").string()}), 0u);

  // Interrupted run: the first shard's folder gets a torn line; the full run resumes, runs the 2 missing
  // cells, and the file is whole again.
  { std::ofstream(root / "s1" / "results.jsonl", std::ios::app) << "{\"id\": \"torn"; }
  o.out_dir = (root / "s1").string();
  o.shard = Shard{};
  RunSummary resumed = run_matrix(m, o);
  EXPECT_EQ(resumed.already_done, 2u);
  EXPECT_EQ(resumed.ran, 2u);
  EXPECT_EQ(read_results(o.out_dir).size(), 4u);
  EXPECT_EQ(run_matrix(m, o).ran, 0u) << "a finished matrix runs nothing again";

  // The folder records its matrix; another matrix's run into it, or a merge with it, is refused.
  const nlohmann::json folder = nlohmann::json::parse(std::ifstream(root / "s1" / "matrix.json"));
  EXPECT_EQ(folder["matrix"], "tiny");
  EXPECT_EQ(folder["cells"], 4);
  const Matrix other = parse_matrix(nlohmann::json::parse(R"({"name": "other",
      "base": {"scene": "builtin:cornell", "resolution": [32, 24], "frames": 2, "warmup": 0},
      "axes": {"seed": [7]}})"),
                                    "other.json");
  try {
    run_matrix(other, o);
    ADD_FAILURE() << "ran another matrix into tiny's folder";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("holds the results of matrix 'tiny' (4 cells"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("not of 'other' (1 cells"), std::string::npos) << e.what();
  }
  EXPECT_EQ(read_results(o.out_dir).size(), 4u) << "the refused run wrote nothing";
  RunOptions oo = o;
  oo.out_dir = (root / "other").string();
  EXPECT_EQ(run_matrix(other, oo).ran, 1u);
  EXPECT_THROW(merge_results((root / "mixed").string(), {(root / "s1").string(), oo.out_dir}), InputError);
  EXPECT_FALSE(fs::exists(root / "mixed"));
  // A folder from before folders recorded their matrix: foreign cells are refused too.
  fs::remove(root / "other" / "matrix.json");
  EXPECT_THROW(run_matrix(m, oo), InputError);

  // A cell measured by another build is stale: removed and run again, the others kept, one line per cell.
  {
    std::vector<nlohmann::json> lines = read_results(o.out_dir);
    lines[1]["result"]["environment"]["git_commit"] = "0123456789ab";
    std::ofstream f(root / "s1" / "results.jsonl", std::ios::trunc);
    for (const auto& l : lines) f << l.dump() << "\n";
  }
  const std::string stale_id = read_results(o.out_dir)[1]["id"];
  const RunSummary again = run_matrix(m, o);
  EXPECT_EQ(again.stale, 1u);
  EXPECT_EQ(again.ran, 1u);
  EXPECT_EQ(again.already_done, 3u);
  const auto after = read_results(o.out_dir);
  ASSERT_EQ(after.size(), 4u);
  EXPECT_EQ(after.back()["id"], stale_id) << "the re-run cell is appended";
  EXPECT_NE(after.back()["result"]["environment"]["git_commit"], "0123456789ab");

  // A shard whose results are not cells: the merge names the line and writes nothing (audit find: the good
  // shard's lines and images used to be merged before the bad one failed).
  fs::create_directories(root / "bad");
  std::ofstream(root / "bad" / "results.jsonl") << "[1, 2]\n";
  ASSERT_FALSE(fs::exists(root / "merged_new"));
  try {
    merge_results((root / "merged_new").string(), {(root / "s2").string(), (root / "bad").string()});
    ADD_FAILURE() << "a results line that is not a cell was merged";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad/results.jsonl:1: not a hybridprof cell"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(root / "merged_new")) << "a failed merge left output behind";
  // Resuming into a folder whose results file is not cells is an input error too, not a library exception.
  o.out_dir = (root / "bad").string();
  EXPECT_THROW(run_matrix(m, o), InputError);
  fs::remove_all(root);
}

}  // namespace
}  // namespace hp
