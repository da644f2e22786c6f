// Whole frames: every built-in and shared scene renders without NaN, with a non-constant image and
// without validation messages.
#include "vulkan_env.hpp"

#include "frame.hpp"
#include "scene/load.hpp"

#include <cmath>
#include <filesystem>

namespace hp {
namespace {

struct ImageStats {
  double mean_luma = 0.0, var_luma = 0.0;
  size_t nan = 0;
  size_t distinct_rows = 0;
};

ImageStats stats(const Image4f& img) {
  ImageStats s;
  double sum = 0.0, sum2 = 0.0;
  const size_t n = size_t(img.width) * img.height;
  for (size_t i = 0; i < n; ++i) {
    const float* p = &img.rgba[i * 4];
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      ++s.nan;
      continue;
    }
    const double l = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    sum += l;
    sum2 += l * l;
  }
  s.mean_luma = sum / double(n);
  s.var_luma = sum2 / double(n) - s.mean_luma * s.mean_luma;
  return s;
}

void render_and_check(const std::string& spec, uint32_t w, uint32_t h) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene(spec);
  const Camera cam = scene.has_camera ? scene.camera : auto_frame(scene, float(w) / float(h));
  Frame frame(*ctx, scene, cam, {w, h, false});
  frame.render();
  const Image4f color = frame.read_color();
  const ImageStats s = stats(color);
  EXPECT_EQ(s.nan, 0u) << spec << ": NaN/Inf pixels";
  EXPECT_GT(s.var_luma, 1e-4) << spec << ": image is (nearly) constant";
  // The scene must cover a real part of the image (auto-framing or the scene camera works).
  const std::vector<float> depth = frame.read_depth();
  size_t covered = 0;
  for (float d : depth) covered += d != 1.0f;
  EXPECT_GT(covered, depth.size() / 20) << spec << ": geometry covers under 5% of the image";
  EXPECT_LT(covered, depth.size()) << spec << ": no sky visible at all (camera inside geometry?)";
}

TEST(Frame, Pica) { render_and_check("builtin:pica", 320, 180); }
TEST(Frame, Cornell) { render_and_check("builtin:cornell", 200, 150); }

TEST(Frame, SharedScenes) {
  const std::filesystem::path root = std::filesystem::path(HP_SHARED_DIR) / "scenes";
  if (!std::filesystem::exists(root)) GTEST_SKIP() << root << " is absent";
  int n = 0;
  for (const char* f :
       {"DamagedHelmet/DamagedHelmet.gltf", "WaterBottle/WaterBottle.gltf", "Balloon/scene.gltf", "Pine/scene.gltf"}) {
    if (!std::filesystem::exists(root / f)) continue;
    SCOPED_TRACE(f);
    render_and_check((root / f).string(), 160, 120);
    ++n;
  }
  EXPECT_GT(n, 0);
}

TEST(Frame, ComposeIsLitFromTheLightSide) {
  HP_REQUIRE_VULKAN(ctx);
  // The Cornell back wall faces +z and the light comes from +z: it must be brighter than with the light
  // behind it (only ambient then).
  Scene lit = load_scene("builtin:cornell");
  Scene unlit = lit;
  unlit.light.direction = {0.0f, 0.0f, -1.0f};
  const auto centre_luma = [&](const Scene& s) {
    Frame f(*ctx, s, s.camera, {64, 48, false});
    f.render();
    const Image4f c = f.read_color();
    const float* p = c.at(32, 24);
    return 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2];
  };
  EXPECT_GT(centre_luma(lit), 2.0f * centre_luma(unlit));
}

}  // namespace
}  // namespace hp
