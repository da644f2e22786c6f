// The matrix runner on a real device: one flushed line per cell, resume after an interruption (a torn last
// line included), shards that partition the matrix, and merge.
#include "vulkan_env.hpp"

#include "error.hpp"
#include "runner.hpp"

#include <filesystem>
#include <fstream>
#include <map>
#include <set>

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
  // With --reuse-stale such a cell is kept, marked, and not run again.
  {
    std::vector<nlohmann::json> lines = read_results(o.out_dir);
    lines[0]["result"]["environment"]["git_commit"] = "0123456789ab";
    std::ofstream f(root / "s1" / "results.jsonl", std::ios::trunc);
    for (const auto& l : lines) f << l.dump() << "\n";
  }
  RunOptions reuse = o;
  reuse.reuse_stale = true;
  const RunSummary kept = run_matrix(m, reuse);
  EXPECT_EQ(kept.ran, 0u);
  EXPECT_EQ(kept.stale_reused, 1u);
  const auto marked = read_results(o.out_dir);
  ASSERT_EQ(marked.size(), 4u);
  EXPECT_NE(marked[0]["stale"]["measured_by"].get<std::string>().find("commit 0123456789ab"), std::string::npos);
  EXPECT_FALSE(marked[1].contains("stale"));
  EXPECT_EQ(run_matrix(m, reuse).stale_reused, 0u) << "marked once";
  EXPECT_EQ(run_matrix(m, o).stale, 1u) << "without the option the stale cell runs again";

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

// Interleaved rounds: every round visits each cell once in a shuffled order and times its share of the
// frames; frames beyond --live-frames are rebuilt; each finished round is journalled, so a run that fails
// in its last round loses no finished round, and the resumed run times only what is missing.
TEST(Runner, InterleavesRoundsAndResumesFromTheJournal) {
  HP_REQUIRE_VULKAN(ctx);
  const fs::path root = fs::temp_directory_path() / ("hp_rounds_" + std::to_string(::getpid()));
  fs::remove_all(root);
  const Matrix m = parse_matrix(nlohmann::json::parse(R"({"name": "tiny_rounds", "rounds": 3,
      "base": {"scene": "builtin:cornell", "resolution": [32, 24], "frames": 4, "warmup": 1},
      "axes": {"geometry": ["indexed", "soup"], "seed": [1, 2]}})"),
                                "tiny_rounds.json");
  ASSERT_EQ(m.rounds, 3u);
  RunOptions o;
  o.progress = false;
  o.live_frames = 2;  // four cells: frames are evicted and rebuilt
  o.out_dir = (root / "all").string();
  EXPECT_EQ(run_matrix(m, o).ran, 4u);
  EXPECT_FALSE(fs::exists(root / "all" / "rounds.jsonl")) << "the journal goes once every cell has its record";
  const auto lines = read_results(o.out_dir);
  ASSERT_EQ(lines.size(), 4u);
  std::map<std::uint32_t, std::set<std::uint32_t>> positions;  // per round: the positions the cells took
  size_t rebuilt_later = 0;
  for (const auto& line : lines) {
    const nlohmann::json& r = line["rounds"];
    EXPECT_EQ(r["count"], 3);
    ASSERT_EQ(r["visits"].size(), 3u);
    std::vector<std::uint32_t> frames;
    for (const auto& v : r["visits"]) {
      positions[v["round"].get<std::uint32_t>()].insert(v["position"].get<std::uint32_t>());
      EXPECT_EQ(v["cells"], 4);
      frames.push_back(v["frames"].get<std::uint32_t>());
      if (v["round"] != 0 && v["rebuilt"].get<bool>()) ++rebuilt_later;
      EXPECT_TRUE(v["load_1min"]["start"].is_number());
    }
    EXPECT_EQ(frames, (std::vector<std::uint32_t>{2, 1, 1})) << "4 frames over 3 rounds";
    EXPECT_TRUE(r["visits"][0]["rebuilt"].get<bool>());
    // The pooled result: 4 measured frames, each marked with its round.
    const auto& fr = line["result"]["frames"];
    ASSERT_EQ(fr.size(), 4u);
    std::vector<int> rounds;
    for (const auto& f : fr) rounds.push_back(f["round"].get<int>());
    EXPECT_EQ(rounds, (std::vector<int>{0, 0, 1, 2}));
    EXPECT_EQ(line["result"]["timing"]["measured_frames"], 4);
  }
  for (std::uint32_t r = 0; r < 3; ++r)
    EXPECT_EQ(positions[r], (std::set<std::uint32_t>{0, 1, 2, 3})) << "round " << r << " visits every cell once";
  EXPECT_GT(rebuilt_later, 0u) << "with two live frames for four cells, later rounds rebuild some";

  // The folder records the rounds: the same matrix in another number of rounds is refused.
  Matrix five = m;
  set_rounds(five, 4, "test");
  EXPECT_THROW(run_matrix(five, o), InputError);
  EXPECT_THROW(set_rounds(five, 5, "test"), InputError) << "5 rounds of 4 frames";

  // A run that fails as it finishes its first cell (the reference cache is a file: the error measurement
  // cannot save its reference): every round measured before the failure is in the journal.
  const Matrix em = parse_matrix(nlohmann::json::parse(R"({"name": "tiny_error", "rounds": 2,
      "base": {"scene": "builtin:cornell", "resolution": [32, 24], "frames": 2, "warmup": 0,
               "error": {"reference_samples": 4}},
      "axes": {"seed": [1, 2]}})"),
                                 "tiny_error.json");
  std::ofstream(root / "not_a_folder") << "x";
  ::setenv("HP_REFERENCE_CACHE", (root / "not_a_folder").c_str(), 1);
  o.out_dir = (root / "err").string();
  EXPECT_THROW(run_matrix(em, o), InputError);
  ::unsetenv("HP_REFERENCE_CACHE");
  EXPECT_TRUE(read_results(o.out_dir).empty());
  size_t journalled = 0;
  {
    std::ifstream j(root / "err" / "rounds.jsonl");
    for (std::string l; std::getline(j, l);) ++journalled;
  }
  EXPECT_EQ(journalled, 3u) << "both cells' first round and one cell's second";
  // An append torn by the interruption: cut off, the finished rounds kept.
  { std::ofstream(root / "err" / "rounds.jsonl", std::ios::app) << "{\"schema\": \"hybridprof.ro"; }
  const RunSummary resumed = run_matrix(em, o);
  EXPECT_EQ(resumed.ran, 2u);
  const auto done = read_results(o.out_dir);
  ASSERT_EQ(done.size(), 2u);
  for (const auto& line : done) {
    EXPECT_EQ(line["rounds"]["visits"].size(), 2u);
    EXPECT_EQ(line["result"]["frames"].size(), 2u);
    EXPECT_TRUE(line["error"].is_object());
  }
  EXPECT_FALSE(fs::exists(root / "err" / "rounds.jsonl"));
  fs::remove_all(root);
}

}  // namespace
}  // namespace hp
