// The hard-case suite (scenarios/hard_cases.json): every case runs through the scenario runner against its
// CPU reference and must meet the expectations the file states (no NaN pixels, acne and leaks under their
// bounds with the robust offset, positions reconstructed within their bound), and the GPU's rays must get
// the CPU reference traversal's answers. Cases whose glTF scene is absent (no ../shared) are skipped.
#include "cpu_agreement.hpp"
#include "vulkan_env.hpp"

#include "runner.hpp"
#include "scene/load.hpp"

#include <filesystem>
#include <unistd.h>

namespace hp {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// The suite with its scenes ("../../shared/", relative to scenarios/) in this build's shared folder, and cases
// without their scene dropped.
Matrix load_suite(std::vector<std::string>& skipped) {
  Matrix m = load_matrix(std::string(HP_SOURCE_DIR) + "/scenarios/hard_cases.json");
  Matrix kept = m;
  kept.cells.clear();
  kept.cell_axis_values.clear();
  for (size_t i = 0; i < m.cells.size(); ++i) {
    Scenario s = m.cells[i];
    if (s.scene.rfind("../../shared/", 0) == 0) {
      s.scene_path = std::string(HP_SHARED_DIR) + "/" + s.scene.substr(13);
      if (!fs::exists(s.scene_path)) {
        skipped.push_back(s.name);
        continue;
      }
    }
    kept.cells.push_back(s);
    kept.cell_axis_values.push_back(m.cell_axis_values[i]);
  }
  return kept;
}

TEST(HardCases, TheSuiteStatesAnExpectationForEveryCase) {
  std::vector<std::string> skipped;
  const Matrix m = load_suite(skipped);
  const Matrix all = load_matrix(std::string(HP_SOURCE_DIR) + "/scenarios/hard_cases.json");
  EXPECT_GE(all.cells.size(), 10u);
  for (const Scenario& s : all.cells) {
    ASSERT_TRUE(all.expect.contains(s.name)) << s.name;
    EXPECT_EQ(all.expect[s.name].value("max_non_finite", -1), 0) << s.name;
    EXPECT_TRUE(all.expect[s.name].value("gpu_equals_cpu", false)) << s.name;
    EXPECT_EQ(s.frame.rt.offset, ShadowOffset::robust) << s.name;
    EXPECT_TRUE(s.error) << s.name << " must be measured against its reference";
  }
}

TEST(HardCases, MeetTheirExpectations) {
  HP_REQUIRE_VULKAN(ctx);
  std::vector<std::string> skipped;
  const Matrix m = load_suite(skipped);
  for (const std::string& s : skipped) std::printf("skipped (scene absent): %s\n", s.c_str());
  const fs::path out = fs::temp_directory_path() / ("hp_hard_cases_" + std::to_string(::getpid()));
  fs::remove_all(out);
  RunOptions o;
  o.out_dir = out.string();
  o.progress = false;
  run_matrix(m, o);
  const std::vector<json> lines = read_results(o.out_dir);
  ASSERT_EQ(lines.size(), m.cells.size());
  for (const json& line : lines) {
    const std::string name = line.value("name", "");
    ASSERT_TRUE(line.contains("expect")) << name;
    EXPECT_TRUE(line["expect"]["unmet"].empty()) << name << ": " << line["expect"]["unmet"].dump();
    // The measurement itself is there: a bound on a missing number would prove nothing.
    EXPECT_GT(line["error"]["shadow"]["compared"].get<uint64_t>(), 1000u) << name;
    std::printf("%-22s acne %s leaks %s of %s, mismatched %s, depth max %.3g, relMSE %.4g\n", name.c_str(),
                line["error"]["shadow"]["acne"].dump().c_str(), line["error"]["shadow"]["leaks"].dump().c_str(),
                line["error"]["shadow"]["compared"].dump().c_str(), line["error"]["coverage_mismatch"].dump().c_str(),
                line["error"]["depth"]["max_rel"].get<double>(), line["error"]["image"]["relmse"].get<double>());
  }
  fs::remove_all(out);
}

TEST(HardCases, GpuRaysGetTheCpuReferenceAnswers) {
  HP_REQUIRE_VULKAN(ctx);
  std::vector<std::string> skipped;
  const Matrix m = load_suite(skipped);
  for (const Scenario& s : m.cells) {
    if (!m.expect[s.name].value("gpu_equals_cpu", false)) continue;
    const CellScene cs = prepare_cell_scene(s, load_scene(s.scene_path));
    FrameSettings fs = s.frame;
    fs.rt.dump_rays = true;
    // Every visible pixel reflects, so each case also casts closest-hit rays (several cases' materials are
    // all rougher than the default threshold and would cast none).
    fs.rt.reflections = true;
    fs.rt.roughness_threshold = 1.01f;
    Frame frame(*ctx, cs.scene, cs.camera, fs);
    frame.render();
    // The passes run the reference's traversal operation for operation: every ray gets the same answer.
    const Agreement sa = compare(frame, frame.rt_passes()->read_shadow_dump(*ctx), true, (s.name + " shadows").c_str());
    EXPECT_GT(sa.rays, 1000u) << s.name;
    EXPECT_EQ(sa.equal, sa.rays) << s.name;
    const Agreement ra =
        compare(frame, frame.rt_passes()->read_reflection_dump(*ctx), false, (s.name + " reflections").c_str());
    EXPECT_GT(ra.rays, 1000u) << s.name;
    EXPECT_EQ(ra.equal, ra.rays) << s.name;
  }
}

}  // namespace
}  // namespace hp
