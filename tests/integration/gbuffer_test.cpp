// The G-buffer of builtin:cornell against analytic values: at pixels whose camera ray is known to reach a
// wall unobstructed (the scene documents those regions), the depth buffer equals the projected depth of
// the ray/plane intersection and the normal equals the wall's.
#include "vulkan_env.hpp"

#include "frame.hpp"
#include "scene/builtin_scenes.hpp"
#include "scene/load.hpp"

#include <cmath>
#include <cstdio>
#include <optional>

namespace hp {
namespace {

struct Plane {
  int axis;     // 0 x, 1 y, 2 z
  float value;  // the plane is p[axis] == value
  glm::vec3 normal;
};

// The nearest documented-unobstructed wall hit along the camera ray through pixel (x, y), if any.
std::optional<std::pair<glm::vec3, glm::vec3>> analytic_hit(const View& view, uint32_t x, uint32_t y, uint32_t w,
                                                            uint32_t h, const glm::vec3& eye) {
  const glm::vec3 far_point = unproject(view, float(x), float(y), w, h, view.reversed_z ? 0.0f : 1.0f);
  const glm::vec3 d = glm::normalize(far_point - eye);
  using namespace cornell;
  const Plane planes[] = {{1, kFloorY, {0, 1, 0}},
                          {1, kCeilingY, {0, -1, 0}},
                          {2, kBackZ, {0, 0, 1}},
                          {0, kLeftX, {1, 0, 0}},
                          {0, kRightX, {-1, 0, 0}}};
  float best = INFINITY;
  std::optional<std::pair<glm::vec3, glm::vec3>> hit;
  for (const Plane& p : planes) {
    if (d[p.axis] == 0.0f) continue;
    const float t = (p.value - eye[p.axis]) / d[p.axis];
    if (t <= 0.0f || t >= best) continue;
    const glm::vec3 q = eye + t * d;
    bool inside = q.x >= kLeftX - 1e-4f && q.x <= kRightX + 1e-4f && q.y >= kFloorY - 1e-4f &&
                  q.y <= kCeilingY + 1e-4f && q.z >= kBackZ - 1e-4f && q.z <= kOpenZ + 1e-4f;
    if (!inside) continue;
    best = t;
    hit = std::make_pair(q, p.normal);
  }
  if (!hit) return std::nullopt;
  const glm::vec3 q = hit->first;
  // Keep only the documented unobstructed regions.
  const bool in_slab = std::fabs(q.x) <= kClearSlabHalfWidth && std::fabs(eye.x) <= kClearSlabHalfWidth;
  const bool right_high = hit->second.x < 0.0f && q.y >= 0.6f;
  const bool left_front = hit->second.x > 0.0f && q.z >= 0.1f;
  if (!(in_slab || right_high || left_front)) return std::nullopt;
  return hit;
}

void check_cornell(bool reversed_z) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:cornell");
  ASSERT_TRUE(scene.has_camera);
  const uint32_t w = 320, h = 240;
  Frame frame(*ctx, scene, scene.camera, {w, h, reversed_z});
  frame.render();
  const std::vector<float> depth = frame.read_depth();
  const Image4f normal = frame.read_aov(Aov::normal);
  const View& view = frame.view();

  int checked = 0, centre_checked = 0;
  double max_depth_err = 0.0, max_pos_err = 0.0, max_normal_err = 0.0;
  for (uint32_t y = 2; y < h; y += 7) {
    for (uint32_t x = 3; x < w; x += 5) {
      auto hit = analytic_hit(view, x, y, w, h, scene.camera.position);
      if (!hit) continue;
      const float expected = project_depth(view, hit->first);
      const float got = depth[size_t(y) * w + x];
      max_depth_err = std::max(max_depth_err, double(std::fabs(got - expected)));
      const glm::vec3 p = unproject(view, float(x), float(y), w, h, got);
      max_pos_err = std::max(max_pos_err, double(glm::length(p - hit->first)));
      const float* n = normal.at(x, y);
      max_normal_err = std::max(max_normal_err, double(glm::length(glm::vec3(n[0], n[1], n[2]) - hit->second)));
      ++checked;
      if (std::fabs(hit->first.x) < 0.05f && hit->second.z > 0.5f) ++centre_checked;
    }
  }
  std::printf("cornell%s: %d analytic pixels, max |depth err| %.3g, max position err %.3g, max normal err %.3g\n",
              reversed_z ? " (reversed-Z)" : "", checked, max_depth_err, max_pos_err, max_normal_err);
  // Tolerances: the rasterizer interpolates z/w in float at the pixel centre (a few ulp near 1); normals
  // are stored as half floats (relative precision 2^-11).
  EXPECT_GT(checked, 300) << "too few analytic pixels: the test would prove little";
  EXPECT_GT(centre_checked, 3) << "the back-wall centre region was not sampled";
  EXPECT_LT(max_depth_err, 1e-6) << "depth vs analytic";
  EXPECT_LT(max_pos_err, 5e-4) << "world position reconstructed from depth vs analytic (scene units)";
  EXPECT_LT(max_normal_err, 2e-3) << "G-buffer normal vs wall normal";

  // The image centre sees the back wall at (0, 1, -1), 4.5 units away.
  const uint32_t cx = w / 2, cy = h / 2;
  const glm::vec3 c = unproject(view, float(cx) - 0.5f, float(cy) - 0.5f, w, h, depth[size_t(cy) * w + cx]);
  EXPECT_NEAR(c.z, -1.0f, 1e-3f);
}

TEST(GBuffer, CornellDepthAndNormalMatchAnalytic) { check_cornell(false); }
TEST(GBuffer, CornellReversedZMatchesAnalytic) { check_cornell(true); }

TEST(GBuffer, BackgroundKeepsClearValueAndAovsAreBounded) {
  HP_REQUIRE_VULKAN(ctx);
  const Scene scene = load_scene("builtin:cornell");
  Camera cam = scene.camera;
  cam.position = {0.0f, 1.0f, 12.0f};  // far enough that the box does not fill the image
  Frame frame(*ctx, scene, cam, {160, 120, false});
  frame.render();
  const std::vector<float> depth = frame.read_depth();
  EXPECT_EQ(depth[0], 1.0f) << "top-left corner sees the sky";
  const Image4f rough = frame.read_aov(Aov::roughness);
  const Image4f albedo = frame.read_aov(Aov::albedo);
  size_t covered = 0;
  for (size_t i = 0; i < depth.size(); ++i) {
    const bool bg = depth[i] == 1.0f;
    ASSERT_EQ(rough.rgba[i * 4 + 3], bg ? 0.0f : 1.0f);
    if (!bg) {
      ++covered;
      ASSERT_GE(rough.rgba[i * 4], 0.0f);
      ASSERT_LE(rough.rgba[i * 4], 1.0f);
      ASSERT_LE(albedo.rgba[i * 4], 1.0f);
    }
  }
  // The box is in view but does not fill it: both kinds of pixel were checked.
  EXPECT_GT(covered, depth.size() / 50);  // 900 of 19,200 pixels
  EXPECT_LT(covered, depth.size() * 9 / 10);
}

}  // namespace
}  // namespace hp
