// The CPU reference renderer and the comparison of a frame against it (no Vulkan here).
#include "error.hpp"
#include "reference/compare.hpp"
#include "reference/reference.hpp"
#include "scene/builtin_scenes.hpp"
#include "view.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <unistd.h>

namespace hp {
namespace {

ReferenceSettings small(uint32_t w, uint32_t h, uint32_t samples = 16) {
  ReferenceSettings s;
  s.width = w;
  s.height = h;
  s.samples = samples;
  return s;
}

bool all_finite(const Image4f& im) {
  for (float v : im.rgba) {
    if (!std::isfinite(v)) return false;
  }
  return true;
}

double relmse(const Image4f& a, const Image4f& b) {
  double sum = 0.0;
  size_t n = 0;
  for (size_t i = 0; i < a.rgba.size(); ++i) {
    if (i % 4 == 3) continue;
    const double d = double(a.rgba[i]) - b.rgba[i];
    sum += d * d / (double(b.rgba[i]) * b.rgba[i] + 0.01);
    ++n;
  }
  return sum / double(n);
}

TEST(Reference, CornellFactsHold) {
  const Scene scene = make_cornell_scene();
  const ReferenceImage r = render_reference(scene, scene.camera, small(81, 61, 4));
  ASSERT_TRUE(all_finite(r.color));
  // The image centre sees the back wall at (0, 1, -1): 4.5 in front of the camera, lit (README of the scene).
  const float* p = r.position.at(40, 30);
  EXPECT_EQ(p[3], 1.0f);
  EXPECT_NEAR(p[0], 0.0f, 0.06f);
  EXPECT_NEAR(p[2], -4.5f, 1e-3f);
  EXPECT_EQ(r.shading.at(40, 30)[0], 1.0f);
  EXPECT_NEAR(r.shading.at(40, 30)[3], 1.0f, 1e-5f);  // normal +z
  // The ceiling faces away from the light: every ceiling pixel (normal -y) is dark; the floor has both the
  // boxes' shadows and lit parts.
  int ceiling = 0, ceiling_lit = 0, floor_lit = 0, floor_dark = 0;
  for (uint32_t y = 0; y < 61; ++y) {
    for (uint32_t x = 0; x < 81; ++x) {
      const float* s = r.shading.at(x, y);
      if (s[0] < 0.0f) continue;
      if (s[2] < -0.99f) ++ceiling, ceiling_lit += s[0] > 0.5f;
      if (s[2] > 0.99f) (s[0] > 0.5f ? floor_lit : floor_dark)++;
    }
  }
  EXPECT_GT(ceiling, 50);
  EXPECT_EQ(ceiling_lit, 0);
  EXPECT_GT(floor_lit, 50);
  EXPECT_GT(floor_dark, 10);
}

TEST(Reference, AxisAlignedAndGrazingLightsGiveNoNaN) {
  for (const glm::vec3 dir :
       {glm::vec3(0, 1, 0), glm::vec3(1, 0, 0), glm::vec3(0, 0, 1), glm::normalize(glm::vec3(1.0f, 1e-4f, 0.0f))}) {
    Scene scene = make_pica_scene();
    scene.light.direction = dir;
    const Camera cam = auto_frame(scene, 64.0f / 36.0f);
    const ReferenceImage r = render_reference(scene, cam, small(64, 36, 4));
    EXPECT_TRUE(all_finite(r.color)) << dir.x << " " << dir.y << " " << dir.z;
    EXPECT_TRUE(all_finite(r.shading));
  }
}

TEST(Reference, ScaleInvariant) {
  // The camera is moved off the box's symmetry axis: from (0, 1, z) the wall corners project exactly
  // onto pixel-centre diagonals, where floor and wall tie and rounding picks either.
  Scene base = make_cornell_scene();
  base.camera.position += glm::vec3(0.13f, 0.07f, 0.0f);
  const ReferenceImage r1 = render_reference(base, base.camera, small(64, 48, 8));
  for (const double scale : {1e-3, 1e3}) {
    Scene s = base;
    Camera c = base.camera;
    transform_world(s, c, scale, glm::dvec3(0.0));
    const ReferenceImage r = render_reference(s, c, small(64, 48, 8));
    EXPECT_LT(relmse(r.color, r1.color), 1e-4) << scale;
    int differ = 0;
    for (uint32_t i = 0; i < 64 * 48; ++i) differ += (r.shading.rgba[4 * i] > 0.5f) != (r1.shading.rgba[4 * i] > 0.5f);
    EXPECT_LE(differ, 3) << scale;  // edge pixels at most
    // Positions scale with the world.
    EXPECT_NEAR(r.position.at(32, 24)[2] / scale, r1.position.at(32, 24)[2],
                1e-3 * std::abs(r1.position.at(32, 24)[2]));
  }
}

TEST(Reference, ReflectionsConvergeWithSamples) {
  const Scene scene = make_pica_scene();
  const Camera cam = auto_frame(scene, 64.0f / 36.0f);
  const ReferenceImage truth = render_reference(scene, cam, small(64, 36, 1024));
  const double e4 = relmse(render_reference(scene, cam, small(64, 36, 4)).color, truth.color);
  const double e64 = relmse(render_reference(scene, cam, small(64, 36, 64)).color, truth.color);
  EXPECT_GT(e4, 0.0);
  EXPECT_LT(e64, e4 * 0.5);
}

// Audit find (2026-11-30): a camera straight above its target, with the default up vector (0, 1, 0), gave a
// NaN view and an empty image. The view now falls back to another up axis.
TEST(View, LookingAlongTheUpVectorStillSees) {
  Camera cam;
  cam.position = {0.0f, 10.0f, 0.0f};
  cam.target = {0.0f, 0.0f, 0.0f};
  const View v = make_view(cam, 1.0f, false);
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) ASSERT_TRUE(std::isfinite(v.view_proj_rel[c][r])) << c << "," << r;
  // The centre of the image looks straight down: its point at some depth lies below the eye on the y axis.
  const glm::vec3 p = unproject(v, 31.5f, 31.5f, 64, 64, 0.5f);
  EXPECT_NEAR(p.x, 0.0f, 1e-3f);
  EXPECT_NEAR(p.z, 0.0f, 1e-3f);
  EXPECT_LT(p.y, 10.0f);
  // And the reference renderer sees the box from above.
  const Scene scene = make_cornell_scene();
  const Aabb b = world_bounds(scene);
  const glm::vec3 centre = (b.min + b.max) * 0.5f;
  Camera above = scene.camera;
  above.target = centre;
  above.position = centre + glm::vec3(0.0f, 0.5f * (b.max.y - b.min.y) + 2.0f * (b.max.x - b.min.x), 0.0f);
  const ReferenceImage r = render_reference(scene, above, small(32, 32, 1));
  uint32_t covered = 0;
  for (uint32_t i = 0; i < 32 * 32; ++i) covered += r.position.rgba[4 * i + 3] > 0.5f ? 1u : 0u;
  EXPECT_GT(covered, 32u * 32u / 4u);
}

TEST(Reference, PassesFollowTheSettings) {
  const Scene scene = make_cornell_scene();
  ReferenceSettings s = small(48, 36, 2);
  s.shadows = false;
  const ReferenceImage r = render_reference(scene, scene.camera, s);
  s.shadows = true;
  const ReferenceImage shadowed = render_reference(scene, scene.camera, s);
  uint32_t covered = 0, dark = 0;
  for (uint32_t i = 0; i < 48 * 36; ++i) {
    if (r.position.rgba[4 * i + 3] > 0.5f) {
      ++covered;
      EXPECT_EQ(r.shading.rgba[4 * i], 1.0f) << "no shadow rays: every surface lit";
      if (shadowed.shading.rgba[4 * i] == 0.0f) ++dark;
    }
  }
  EXPECT_GT(covered, 48u * 36u / 2u) << "the box fills most of the frame";
  EXPECT_GT(dark, 20u) << "with shadow rays the boxes cast shadows";
  EXPECT_LT(dark, covered);
}

TEST(Reference, BadSizesAreInputErrors) {
  const Scene scene = make_cornell_scene();
  EXPECT_THROW(render_reference(scene, scene.camera, small(0, 10)), InputError);
  EXPECT_THROW(render_reference(scene, scene.camera, small(20000, 10)), InputError);
  EXPECT_THROW(render_reference(scene, scene.camera, small(10, 10, 0)), InputError);
}

TEST(Reference, IdAndCache) {
  const Scene scene = make_cornell_scene();
  const ReferenceSettings s = small(32, 24, 4);
  const std::string id = reference_id("builtin:cornell", scene, scene.camera, s);
  EXPECT_EQ(id.size(), 16u);
  EXPECT_EQ(id, reference_id("builtin:cornell", scene, scene.camera, s));
  ReferenceSettings s2 = s;
  s2.samples = 8;
  EXPECT_NE(id, reference_id("builtin:cornell", scene, scene.camera, s2));
  Camera moved = scene.camera;
  moved.position.x += 1e-3f;
  EXPECT_NE(id, reference_id("builtin:cornell", scene, moved, s));

  const ReferenceImage r = render_reference(scene, scene.camera, s);
  const auto dir = std::filesystem::temp_directory_path() / ("hp_ref_cache_" + std::to_string(::getpid()));
  ReferenceImage back;
  EXPECT_FALSE(load_reference(dir.string(), id, 32, 24, back));
  save_reference(dir.string(), id, r);
  ASSERT_TRUE(load_reference(dir.string(), id, 32, 24, back));
  EXPECT_EQ(back.color.rgba, r.color.rgba);
  EXPECT_EQ(back.shading.rgba, r.shading.rgba);
  EXPECT_EQ(back.position.rgba, r.position.rgba);
  EXPECT_FALSE(load_reference(dir.string(), id, 33, 24, back));  // another size is not this reference
  std::filesystem::remove_all(dir);
}

// The frame the reference itself would read back, seen from `camera` in a world scaled by `scale`: its
// colour, shadow mask, normals, and the depth of each exact position.
FrameReadback frame_from_reference(const ReferenceImage& r, const Camera& camera, float scale = 1.0f) {
  const uint32_t w = r.color.width, h = r.color.height;
  FrameReadback f;
  f.view = make_view(camera, float(w) / float(h), false);
  f.color = r.color;
  f.shadow = Image4f(w, h);
  f.normal = Image4f(w, h);
  f.depth.assign(size_t(w) * h, f.view.far_depth());
  for (uint32_t i = 0; i < w * h; ++i) {
    const float* p = &r.position.rgba[4 * i];
    const float* s = &r.shading.rgba[4 * i];
    f.shadow.rgba[4 * i] = s[0];
    f.normal.rgba[4 * i] = s[1], f.normal.rgba[4 * i + 1] = s[2], f.normal.rgba[4 * i + 2] = s[3];
    if (p[3] > 0.5f) f.depth[i] = project_depth(f.view, camera.position + scale * glm::vec3(p[0], p[1], p[2]));
  }
  return f;
}

TEST(Compare, FlipMapIsComputedOnceAndMatchesTheMetric) {
  const Scene scene = make_cornell_scene();
  const uint32_t w = 40, h = 30;
  const ReferenceImage r = render_reference(scene, scene.camera, small(w, h, 2));
  FrameReadback f = frame_from_reference(r, scene.camera);
  for (size_t i = 0; i < f.color.rgba.size(); i += 4) f.color.rgba[i] *= 0.8f;  // a visible difference
  Image4f map;
  const nlohmann::json with_map = compare_with_reference(f, r, {}, {}, &map);
  const nlohmann::json without = compare_with_reference(f, r, {}, {});
  ASSERT_EQ(map.width, w);
  ASSERT_EQ(map.height, h);
  EXPECT_GT(with_map["image"]["flip_mean"].get<double>(), 0.0);
  EXPECT_NEAR(with_map["image"]["flip_mean"].get<double>(), without["image"]["flip_mean"].get<double>(), 1e-9);
  EXPECT_EQ(with_map["image"]["mse"], without["image"]["mse"]);
}

// A "frame" made from the reference itself compares as exact; single-pixel faults are counted.
TEST(Compare, CountsAcneLeaksAndMismatches) {
  const Scene scene = make_cornell_scene();
  const uint32_t w = 64, h = 48;
  const ReferenceImage r = render_reference(scene, scene.camera, small(w, h, 2));
  FrameReadback f = frame_from_reference(r, scene.camera);
  int lit_px = -1, dark_px = -1;
  for (uint32_t i = 0; i < w * h; ++i) {
    if (r.position.rgba[4 * i + 3] < 0.5f) continue;
    const float lit = r.shading.rgba[4 * i];
    if (lit > 0.5f && lit_px < 0 && i > w * h / 2) lit_px = int(i);
    if (lit < 0.5f && dark_px < 0) dark_px = int(i);
  }
  ErrorOptions eo;
  eo.flip = false;
  CompareOptions co;
  co.image = eo;
  nlohmann::json e = compare_with_reference(f, r, {}, co);
  EXPECT_EQ(e["image"]["mse"].get<double>(), 0.0);
  EXPECT_EQ(e["shadow"]["acne"], 0);
  EXPECT_EQ(e["shadow"]["leaks"], 0);
  EXPECT_EQ(e["coverage_mismatch"], 0);
  EXPECT_LT(e["depth"]["max_rel"].get<double>(), 1e-3);
  EXPECT_GT(e["depth"]["bins"].size(), 1u);

  ASSERT_GE(lit_px, 0);
  ASSERT_GE(dark_px, 0);
  f.shadow.rgba[4 * size_t(lit_px)] = 0.0f;
  f.shadow.rgba[4 * size_t(dark_px)] = 1.0f;
  f.depth[size_t(lit_px) + 1] = f.view.far_depth();  // the frame misses a surface the reference hit
  e = compare_with_reference(f, r, {}, co);
  EXPECT_EQ(e["shadow"]["acne"], 1);
  EXPECT_EQ(e["shadow"]["leaks"], 1);
  EXPECT_EQ(e["coverage_mismatch"], 1);

  // A frame of the world scaled by 1e3 is compared in reference units.
  Camera big = scene.camera;
  Scene s2 = scene;
  transform_world(s2, big, 1e3, glm::dvec3(0.0));
  const FrameReadback g = frame_from_reference(r, big, 1e3f);
  e = compare_with_reference(g, r, WorldTransform{1e3, glm::dvec3(0.0)}, co);
  EXPECT_LT(e["depth"]["max_rel"].get<double>(), 1e-3);

  Image4f wrong(w + 1, h);
  FrameReadback bad = f;
  bad.color = wrong;
  EXPECT_THROW(compare_with_reference(bad, r, {}, co), std::invalid_argument);
}

}  // namespace
}  // namespace hp
