// Hard cases: watertightness at shared edges and vertices, axis-aligned rays with +0/-0 components and
// origins on box planes, scale and translation invariance, zero-thickness boxes, degenerate triangles,
// trees that a greedy SAH would make deeper than the traversal stack.
#include "bvh/traverse.hpp"
#include "bvh_test_scenes.hpp"
#include "checked_traversal.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>

namespace hp::bvh {
namespace {

using testing::any;
using testing::build;
using testing::Built;
using testing::closest;
using testing::IndexedMesh;
using testing::random_dir;
using testing::uv_sphere;
using testing::wrap;

/// Möller–Trumbore as the study wrote it (no culling here, epsilon on the determinant, float): only used
/// to show that a ray set is hard, i.e. that a non-watertight test does lose rays on it.
bool moller_trumbore(const Ray& r, const Triangle& t) {
  const glm::vec3 e1 = t.v1 - t.v0, e2 = t.v2 - t.v0;
  const glm::vec3 p = glm::cross(r.dir, e2);
  const float det = glm::dot(e1, p);
  if (std::abs(det) < 1e-8f) return false;
  const float inv = 1.0f / det;
  const glm::vec3 s = r.origin - t.v0;
  const float u = glm::dot(s, p) * inv;
  if (u < 0.0f || u > 1.0f) return false;
  const glm::vec3 q = glm::cross(s, e1);
  const float v = glm::dot(r.dir, q) * inv;
  if (v < 0.0f || u + v > 1.0f) return false;
  return glm::dot(e2, q) * inv >= r.tmin;
}

/// Rays from random origins above (z > 0) aimed at `targets` on a surface in or near z = 0.
/// `spread` bounds the horizontal offset of an origin relative to its height.
std::vector<Ray> rays_at(const std::vector<glm::vec3>& targets, uint32_t seed, int per_target, float spread) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f), h(0.5f, 4.0f);
  std::vector<Ray> rays;
  for (const glm::vec3& t : targets) {
    for (int k = 0; k < per_target; ++k) {
      Ray r;
      const float height = h(rng);
      r.origin = glm::vec3(t.x + spread * height * u(rng), t.y + spread * height * u(rng), t.z + height);
      r.dir = t - r.origin;  // unnormalised: the target is at t = 1
      rays.push_back(r);
    }
  }
  return rays;
}

/// Counts rays that miss everything (they all must hit), and how many Möller–Trumbore would lose.
void expect_no_fall_through(std::span<const Triangle> tris, const std::vector<Ray>& rays, const char* what) {
  const Built b = build(tris);
  std::size_t lost = 0, lost_any = 0, lost_mt = 0;
  for (const Ray& r : rays) {
    lost += !closest(b, r).hit();
    lost_any += !any(b, r).hit();
    bool mt = false;
    for (const Triangle& t : tris) mt = mt || moller_trumbore(r, t);
    lost_mt += !mt;
  }
  EXPECT_EQ(lost, 0u) << what << ": " << lost << " of " << rays.size() << " rays fell through";
  EXPECT_EQ(lost_any, 0u) << what;
  // The ray set is hard: the non-watertight test does lose some of these rays.
  EXPECT_GT(lost_mt, 0u) << what << ": the ray set does not exercise edges";
  std::printf("[ %s ] %zu rays, watertight lost %zu, Moller-Trumbore lost %zu (%.2f%%)\n", what, rays.size(), lost,
              lost_mt, 100.0 * static_cast<double>(lost_mt) / static_cast<double>(rays.size()));
}

TEST(BvhRobust, TriangleFanSharedEdgesAndVertexNeverFallThrough) {
  // 24 triangles around a centre vertex in the plane z = 0, so that every target computed on a spoke lies
  // exactly in the surface (only its x and y round): a ray from above through it must hit, at any angle.
  IndexedMesh fan;
  fan.positions.emplace_back(0.1f, 0.2f, 0.0f);
  const int n = 24;
  for (int k = 0; k < n; ++k) {
    const float a = 6.2831853f * static_cast<float>(k) / n;
    fan.positions.emplace_back(1.3f * std::cos(a), 0.9f * std::sin(a), 0.0f);
  }
  for (int k = 0; k < n; ++k) {
    fan.indices.insert(fan.indices.end(), {0u, 1u + static_cast<uint32_t>(k), 1u + static_cast<uint32_t>((k + 1) % n)});
  }
  const auto tris = fan.triangles();
  std::vector<glm::vec3> targets{fan.positions[0]};  // the shared vertex, exactly
  for (int k = 1; k <= n; ++k) {
    const glm::vec3 c = fan.positions[0], rim = fan.positions[k];
    for (const float s : {0.1f, 0.25f, 0.5f, 0.61f, 0.9f}) targets.push_back(c + s * (rim - c));  // on spokes
  }
  expect_no_fall_through(tris, rays_at(targets, 1, 400, 3.0f), "fan");
}

TEST(BvhRobust, TessellatedGridEdgesAndVerticesNeverFallThrough) {
  // A non-planar 40 x 40 grid; targets on its interior vertices and on all three kinds of edges. A target
  // on an edge rounds off the surface by an ulp, so rays come in steeper than any slope of the surface
  // (<= 0.43 here, rays >= 2.5): a ray that passes an ulp above the surface then must cross it nearby.
  const int n = 40;
  IndexedMesh grid;
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; j <= n; ++j) {
      const float x = 0.1f * i, y = 0.1f * j;
      grid.positions.emplace_back(x, y, 0.05f * std::sin(7.0f * x) * std::cos(5.0f * y));
    }
  }
  const auto at = [&](int i, int j) { return static_cast<uint32_t>(i * (n + 1) + j); };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      grid.indices.insert(grid.indices.end(),
                          {at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  }
  const auto tris = grid.triangles();
  std::vector<glm::vec3> targets;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> s(0.0f, 1.0f);
  for (int i = 1; i < n; ++i) {
    for (int j = 1; j < n; ++j) {
      const glm::vec3 p = grid.positions[at(i, j)];
      targets.push_back(p);                                                    // vertex
      targets.push_back(p + s(rng) * (grid.positions[at(i + 1, j)] - p));      // edge along x
      targets.push_back(p + s(rng) * (grid.positions[at(i, j + 1)] - p));      // edge along y
      targets.push_back(p + s(rng) * (grid.positions[at(i + 1, j + 1)] - p));  // diagonal
    }
  }
  expect_no_fall_through(tris, rays_at(targets, 2, 12, 0.28f), "grid");
}

TEST(BvhRobust, BoxTestWithZeroDirectionsAndOriginsOnPlanes) {
  const glm::vec3 lo(0, 0, 0), hi(1, 2, 3);
  float tn = 0, tf = 0;
  for (const float zero : {0.0f, -0.0f}) {
    for (const float plane_y : {0.0f, 2.0f}) {  // origin exactly on the bmin.y and the bmax.y plane
      Ray r;
      r.origin = glm::vec3(0.5f, plane_y, -1.0f);
      r.dir = glm::vec3(zero, zero, 1.0f);
      ASSERT_TRUE(intersect_box(r, lo, hi, tn, tf)) << "zero " << std::signbit(zero) << " plane " << plane_y;
      EXPECT_FALSE(std::isnan(tn) || std::isnan(tf));
      EXPECT_EQ(tn, 1.0f);
      EXPECT_GE(tf, 4.0f);
      EXPECT_LT(tf, 4.0001f);
      // Just outside the plane: a zero component can never get in.
      r.origin.y = plane_y == 0.0f ? -1e-30f : std::nextafter(2.0f, 3.0f);
      EXPECT_FALSE(intersect_box(r, lo, hi, tn, tf));
    }
    // Origin on an edge of the box (two planes), moving along the third axis in both directions.
    for (const float dz : {1.0f, -1.0f}) {
      Ray r;
      r.origin = glm::vec3(1.0f, 0.0f, dz > 0 ? -5.0f : 8.0f);
      r.dir = glm::vec3(zero, -zero, dz);
      ASSERT_TRUE(intersect_box(r, lo, hi, tn, tf));
      EXPECT_FALSE(std::isnan(tn) || std::isnan(tf));
    }
  }
  // A zero-thickness box (a quad at z = 1) is hit head-on and by a ray lying in its plane.
  Ray head;
  head.origin = glm::vec3(0.5f, 0.5f, -2.0f);
  head.dir = glm::vec3(0.0f, -0.0f, 1.0f);
  ASSERT_TRUE(intersect_box(head, glm::vec3(0, 0, 1), glm::vec3(1, 1, 1), tn, tf));
  EXPECT_EQ(tn, 3.0f);
  Ray in_plane;
  in_plane.origin = glm::vec3(-1.0f, 0.5f, 1.0f);
  in_plane.dir = glm::vec3(1.0f, 0.0f, -0.0f);
  EXPECT_TRUE(intersect_box(in_plane, glm::vec3(0, 0, 1), glm::vec3(1, 1, 1), tn, tf));
}

/// Axis-aligned unit cubes on an integer lattice, as 12 triangles each, plus axis-aligned quads.
std::vector<Triangle> lattice_scene() {
  std::vector<Triangle> tris;
  const auto quad = [&](glm::vec3 o, glm::vec3 a, glm::vec3 b) {
    tris.push_back({o, o + a, o + a + b});
    tris.push_back({o, o + a + b, o + b});
  };
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      if ((i + j) % 2) continue;
      const glm::vec3 o(2.0f * i, 2.0f * j, 0.0f);
      const glm::vec3 X(1, 0, 0), Y(0, 1, 0), Z(0, 0, 1);
      quad(o, Y, X);
      quad(o + Z, X, Y);
      quad(o, X, Z);
      quad(o + Y, Z, X);
      quad(o, Z, Y);
      quad(o + X, Y, Z);
    }
  }
  quad(glm::vec3(-1, -1, 3), glm::vec3(9, 0, 0), glm::vec3(0, 9, 0));  // a ceiling: zero thickness in z
  quad(glm::vec3(-1, 7, 0), glm::vec3(9, 0, 0), glm::vec3(0, 0, 3));   // a wall: zero thickness in y
  return tris;
}

TEST(BvhRobust, AxisAlignedRaysWithSignedZerosOnBoxPlanes) {
  const auto tris = lattice_scene();
  // Every origin lies on planes of the cubes (integer coordinates, also the quads' planes), every direction
  // has exact +0 or -0 components.
  std::vector<Ray> rays;
  const float zeros[2] = {0.0f, -0.0f};
  for (int x = -1; x <= 8; ++x) {
    for (int y = -1; y <= 7; ++y) {
      for (int z = -1; z <= 3; ++z) {
        for (int axis = 0; axis < 3; ++axis) {
          for (int sign = 0; sign < 2; ++sign) {
            for (int zs = 0; zs < 4; ++zs) {
              Ray r;
              r.origin = glm::vec3(x, y, z);
              glm::vec3 d(zeros[zs & 1], zeros[(zs >> 1) & 1], zeros[zs & 1]);
              d[axis] = sign ? -1.0f : 1.0f;
              r.dir = d;
              rays.push_back(r);
              // Half a unit off the lattice on the other two axes, still on planes along the ray.
              Ray h = r;
              h.origin[(axis + 1) % 3] += 0.5f;
              rays.push_back(h);
            }
          }
        }
      }
    }
  }
  for (const bool sweep : {false, true}) {
    for (const int leaf : {1, 4}) {
      BuildOptions o;
      o.full_sweep = sweep;
      o.max_leaf_size = leaf;
      const Built b = build(tris, o);
      std::size_t hits = 0, mismatches = 0;
      for (const Ray& r : rays) {
        const Hit want = brute_force_closest(tris, r);
        const Hit got = closest(b, r);
        const bool any_hit = any(b, r).hit();
        if (want.prim != got.prim || want.t != got.t || any_hit != want.hit()) ++mismatches;
        hits += want.hit();
      }
      EXPECT_EQ(mismatches, 0u) << "sweep " << sweep << " leaf " << leaf;
      EXPECT_GT(hits, rays.size() / 4);
    }
  }
  // One case spelled out: a ray along +x at y = 0 (the cube's bottom plane) hits the cube's x = 0 face on
  // its edge, at t = 1.
  const Built b = build(tris);
  Ray r;
  r.origin = glm::vec3(-1.0f, 0.0f, 0.5f);
  r.dir = glm::vec3(1.0f, -0.0f, 0.0f);
  const Hit h = closest(b, r);
  ASSERT_TRUE(h.hit());
  EXPECT_EQ(h.t, 1.0f);
}

TEST(BvhRobust, ZeroThicknessWallsOfAClosedBoxCatchEveryRay) {
  // A closed Cornell-like room of six axis-aligned walls (each 2 triangles, each leaf box flat) with two
  // blocks inside: every ray from inside hits something, and the answers equal brute force.
  std::vector<Triangle> tris;
  const auto quad = [&](glm::vec3 o, glm::vec3 a, glm::vec3 b) {
    tris.push_back({o, o + a, o + a + b});
    tris.push_back({o, o + a + b, o + b});
  };
  const glm::vec3 X(5.55f, 0, 0), Y(0, 5.48f, 0), Z(0, 0, 5.59f), O(0.0f);
  quad(O, X, Z);      // floor
  quad(O + Y, Z, X);  // ceiling
  quad(O, Y, X);      // back
  quad(O + Z, X, Y);  // front (closed)
  quad(O, Z, Y);      // left
  quad(O + X, Y, Z);  // right
  for (const glm::vec3 c : {glm::vec3(1.3f, 0, 1.1f), glm::vec3(3.5f, 0, 3.1f)}) {
    const glm::vec3 a(1.6f, 0, 0), bb(0, 1.65f, 0), cc(0, 0, 1.6f);
    quad(c, bb, a);
    quad(c + cc, a, bb);
    quad(c, a, cc);
    quad(c + bb, cc, a);
    quad(c, cc, bb);
    quad(c + a, bb, cc);
  }
  const Built b = build(tris);
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> ux(0.01f, 5.54f), uy(1.7f, 5.47f), uz(0.01f, 5.58f);
  std::size_t lost = 0, mismatches = 0;
  for (int i = 0; i < 20000; ++i) {
    Ray r;
    r.origin = glm::vec3(ux(rng), uy(rng), uz(rng));
    r.dir = random_dir(rng);
    if (i % 4 == 0) {
      // Axis-aligned, with signed zeros.
      const int axis = i / 4 % 3;
      r.dir = glm::vec3((i & 8) ? -0.0f : 0.0f, (i & 16) ? -0.0f : 0.0f, (i & 32) ? -0.0f : 0.0f);
      r.dir[axis] = (i & 64) ? -1.0f : 1.0f;
    }
    const Hit got = closest(b, r);
    const Hit want = brute_force_closest(tris, r);
    lost += !got.hit();
    mismatches += got.prim != want.prim || got.t != want.t;
  }
  EXPECT_EQ(lost, 0u);
  EXPECT_EQ(mismatches, 0u);
  // The walls really are flat leaves.
  std::size_t flat = 0;
  for (const auto& n : b.bvh.nodes) flat += n.bmin.x == n.bmax.x || n.bmin.y == n.bmax.y || n.bmin.z == n.bmax.z;
  EXPECT_GT(flat, 0u);
}

/// A closed sphere with vertices on a 1/64 grid, so that translating it by 1e5 (float spacing 1/128 there)
/// is exact, and rays whose origins and targets are on the same grid.
struct ScaleCase {
  std::vector<Triangle> tris;
  std::vector<Ray> inside;  ///< aimed at points well inside: every one must hit
  std::vector<Ray> random;  ///< through the bounding region: some hit, some miss
};
ScaleCase scale_case(float scale, float shift) {
  const auto snap = [](glm::vec3 p) { return glm::round(p * 64.0f) / 64.0f; };
  IndexedMesh m = uv_sphere(120, 160, 4.0f);
  for (auto& p : m.positions) p = snap(p);
  const auto xf = [&](glm::vec3 p) { return p * scale + glm::vec3(shift); };
  ScaleCase c;
  for (auto t : m.triangles()) c.tris.push_back({xf(t.v0), xf(t.v1), xf(t.v2)});
  std::mt19937 rng(77);
  std::uniform_real_distribution<float> far(-12.0f, 12.0f), near(-2.0f, 2.0f), box(-5.0f, 5.0f);
  for (int i = 0; i < 100000; ++i) {
    glm::vec3 o;
    do {
      o = snap(glm::vec3(far(rng), far(rng), far(rng)));
    } while (glm::length(o) < 6.0f);
    const glm::vec3 target = snap(glm::vec3(near(rng), near(rng), near(rng)));
    const glm::vec3 other = snap(glm::vec3(box(rng), box(rng), box(rng)) * 1.3f);
    Ray r;
    r.origin = xf(o);
    r.dir = xf(target) - r.origin;
    c.inside.push_back(r);
    r.dir = xf(other) - r.origin;
    c.random.push_back(r);
  }
  return c;
}

TEST(BvhRobust, ScaleAndTranslationInvariance) {
  std::size_t base_random_hits = 0;
  for (const auto& [scale, shift] :
       std::vector<std::pair<float, float>>{{1.0f, 0.0f}, {1e-4f, 0.0f}, {1e4f, 0.0f}, {1.0f, 1e5f}}) {
    const ScaleCase c = scale_case(scale, shift);
    const Built b = build(c.tris);
    const std::vector<Hit> in = cast_rays(b.bvh, b.lt, c.inside, HitMode::closest, 2);
    const std::vector<Hit> in_any = cast_rays(b.bvh, b.lt, c.inside, HitMode::any, 2);
    const std::vector<Hit> rnd = cast_rays(b.bvh, b.lt, c.random, HitMode::closest, 2);
    std::size_t lost = 0, lost_any = 0, random_hits = 0;
    for (const Hit& h : in) lost += !h.hit();
    for (const Hit& h : in_any) lost_any += !h.hit();
    for (const Hit& h : rnd) random_hits += h.hit();
    std::size_t wide_differs = 0;
    for (std::size_t i = 0; i < c.random.size(); ++i) {
      wide_differs += !testing::same_bits(in[i], intersect_closest(b.wide, c.inside[i])) ||
                      !testing::same_bits(rnd[i], intersect_closest(b.wide, c.random[i])) ||
                      !intersect_any(b.wide, c.inside[i]).hit();
    }
    EXPECT_EQ(wide_differs, 0u) << "scale " << scale << " shift " << shift;
    EXPECT_EQ(lost, 0u) << "scale " << scale << " shift " << shift;
    EXPECT_EQ(lost_any, 0u) << "scale " << scale << " shift " << shift;
    if (scale == 1.0f && shift == 0.0f) {
      base_random_hits = random_hits;
      EXPECT_GT(random_hits, c.random.size() / 5);
      EXPECT_LT(random_hits, c.random.size());
    } else {
      // Rounding of scaled vertices moves silhouettes by an ulp: a few grazing rays per million may change.
      const double diff = std::abs(static_cast<double>(random_hits) - static_cast<double>(base_random_hits));
      EXPECT_LE(diff, 4e-6 * static_cast<double>(c.random.size()) + 1.0)
          << "scale " << scale << " shift " << shift << ": " << random_hits << " vs " << base_random_hits;
    }
  }
}

TEST(BvhRobust, DegenerateTrianglesNeverHitNeverCrash) {
  const float nan = std::nanf("");
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<Triangle> tris = {
      {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}},         // 0: a real one
      {{2, 2, 0}, {2, 2, 0}, {2, 2, 0}},         // 1: a point
      {{3, 0, 0}, {4, 1, 0}, {4, 1, 0}},         // 2: two equal vertices
      {{5, 0, 0}, {6, 1, 0}, {7, 2, 0}},         // 3: collinear
      {{0, 3, 0}, {0.5f, 3.5f, 0}, {1, 4, 0}},   // 4: collinear, through the ray targets below
      {{nan, 0, 0}, {1, 1, 1}, {0, 1, 1}},       // 5: NaN vertex
      {{inf, 0, 0}, {1, 1, 1}, {0, 1, 1}},       // 6: infinite vertex
      {{-inf, 0, 0}, {inf, 1, 1}, {0, nan, 1}},  // 7: all bad
      {{0, 0, 2}, {1, 0, 2}, {0, 1, 2}},         // 8: a real one above 0
  };
  std::vector<uint32_t> expected_valid{0, 8};
  Built b = build(tris);
  EXPECT_EQ(b.bvh.prim_ids.size(), 2u);
  // Rays aimed exactly at the degenerate triangles' points and segments, from several directions.
  std::vector<Ray> rays;
  std::mt19937 rng(4);
  for (const glm::vec3 t : {glm::vec3(2, 2, 0), glm::vec3(3.5f, 0.5f, 0), glm::vec3(4, 1, 0), glm::vec3(6, 1, 0),
                            glm::vec3(0.25f, 3.25f, 0), glm::vec3(0.5f, 3.5f, 0), glm::vec3(0.5f, 0.5f, 1)}) {
    for (int k = 0; k < 50; ++k) {
      Ray r;
      r.dir = random_dir(rng);
      r.origin = t - 5.0f * r.dir;
      rays.push_back(r);
    }
    Ray straight;
    straight.origin = t + glm::vec3(0, 0, 5);
    straight.dir = glm::vec3(0, 0, -1);
    rays.push_back(straight);
  }
  for (const Ray& r : rays) {
    for (const Hit h : {closest(b, r), any(b, r), brute_force_closest(tris, r)}) {
      if (h.hit()) {
        EXPECT_TRUE(h.prim == 0 || h.prim == 8) << "hit degenerate triangle " << h.prim;
      }
    }
  }
  // Object granularity keeps degenerate triangles inside their objects: still never hit.
  BuildOptions o;
  o.granularity = Granularity::object;
  // Object 0 mixes the real triangle 0 with degenerate ones; objects 1 and 2 hold no valid triangle at all
  // and are left out; object 3 is triangle 8.
  const std::vector<uint32_t> objects{0, 4, 5, 8, 9};
  const Built ob = wrap(build_bvh(tris, o, objects), tris);
  EXPECT_EQ(ob.bvh.prim_ids.size(), 2u);
  std::size_t hits = 0;
  for (const Ray& r : rays) {
    for (const Hit h : {closest(ob, r), any(ob, r)}) {
      if (h.hit()) {
        EXPECT_TRUE(h.prim == 0 || h.prim == 8) << "hit degenerate triangle " << h.prim;
      }
      hits += h.hit();
    }
  }
  EXPECT_GT(hits, 0u);  // the real triangles are hit by the straight ray aimed at (0.5, 0.5)
  // Only degenerate triangles: an empty tree that every ray misses.
  const std::vector<Triangle> bad(tris.begin() + 1, tris.begin() + 8);
  const Built e = build(bad);
  for (const Ray& r : rays) EXPECT_FALSE(closest(e, r).hit());
}

/// Checks depth against a bound and a few rays against brute force.
void check_deep(const std::vector<Triangle>& tris, const BuildOptions& o, const std::vector<Ray>& rays) {
  const Built b = build(tris, o);
  EXPECT_LE(b.bvh.max_depth, o.max_depth);
  EXPECT_EQ(bvh_stats(b.bvh).max_depth, b.bvh.max_depth);
  for (const Ray& r : rays) {
    const Hit want = brute_force_closest(tris, r);
    const Hit got = closest(b, r);
    EXPECT_EQ(want.prim, got.prim);
    EXPECT_EQ(want.t, got.t);
    EXPECT_EQ(want.hit(), any(b, r).hit());
  }
}

/// Rays at the centroids of every `step`-th triangle from two directions, and one along the whole line.
std::vector<Ray> rays_at_triangles(const std::vector<Triangle>& tris, std::size_t step) {
  std::vector<Ray> rays;
  for (std::size_t i = step / 2; i < tris.size(); i += step) {
    const glm::vec3 c = (tris[i].v0 + tris[i].v1 + tris[i].v2) / 3.0f;
    for (const glm::vec3 d : {glm::vec3(0.3f, -0.2f, 1.0f), glm::vec3(-0.1f, 1.0f, 0.2f)}) {
      Ray r;
      r.origin = c - d;
      r.dir = d;
      rays.push_back(r);
    }
  }
  Ray along;
  along.origin = glm::vec3(-1.0f, 1e-7f, 2e-7f);
  along.dir = glm::vec3(1, 0, 0);
  rays.push_back(along);
  return rays;
}

TEST(BvhRobust, ExponentialClustersStayWithinTheStack) {
  // 241 clusters at 2^-120 .. 2^120: the binned SAH alone would go deeper than the stack.
  const auto tris = testing::exponential_clusters(-120, 120, 256, 8);
  const auto rays = rays_at_triangles(tris, 997);
  for (const bool sweep : {false, true}) {
    BuildOptions o;
    o.full_sweep = sweep;
    const Bvh bvh = build_bvh(tris, o);
    if (!sweep) {
      EXPECT_GT(bvh.depth_limited_splits, 0u) << "the scene no longer drives the SAH past the stack";
      EXPECT_EQ(bvh.max_depth, HP_BVH_STACK_SIZE) << "the bound should be reached, not undershot";
    }
    check_deep(tris, o, rays);
    o.max_depth = 20;
    check_deep(tris, o, rays);
  }
}

TEST(BvhRobust, MillionTrianglesAlongALineStayWithinTheStack) {
  // About a million triangles along x in exponential clusters (241 clusters of 4150).
  const auto tris = testing::exponential_clusters(-120, 120, 4150, 9);
  ASSERT_GT(tris.size(), 1000000u);
  const auto rays = rays_at_triangles(tris, tris.size() / 12);
  BuildOptions o;
  const Bvh bvh = build_bvh(tris, o);
  std::printf("[ line ] %zu triangles, depth %d, depth-limited splits %zu\n", tris.size(), bvh.max_depth,
              bvh.depth_limited_splits);
  EXPECT_GT(bvh.depth_limited_splits, 0u);
  check_deep(tris, o, rays);
}

TEST(BvhRobust, TraversalRefusesATreeDeeperThanTheStack) {
  // A hand-made chain of 70 interior nodes (build_bvh never makes one): the traversal must stop with an
  // error instead of writing past its fixed stack.
  Bvh bvh;
  const int chain = HP_BVH_STACK_SIZE + 6;
  for (int i = 0; i < chain; ++i) bvh.nodes.push_back(gpu::BvhNode{glm::vec3(-1), chain, glm::vec3(1), 0u});
  bvh.nodes.push_back(gpu::BvhNode{glm::vec3(-1), 0, glm::vec3(1), 1u << HP_BVH_AXIS_BITS});
  bvh.prim_ids = {0};
  const std::vector<Triangle> tri{{{-1, -1, 0}, {1, -1, 0}, {0, 1, 0}}};
  const LeafOrderTriangles lt = leaf_order(bvh, tri);
  Ray r;
  r.origin = glm::vec3(0, 0, -5);
  r.dir = glm::vec3(0, 0, 1);
  EXPECT_THROW(intersect_closest(bvh, lt, r), std::logic_error);
  EXPECT_THROW(cast_rays(bvh, lt, std::vector<Ray>(3000, r), HitMode::any, 2), std::logic_error);
  // The 8-wide form takes up to seven chain levels per node, ten nodes deep: within its own stack bound.
  EXPECT_TRUE(intersect_closest(make_bvh8(bvh, lt), r).hit());
  // A chain that is too deep for it too is refused when it is made.
  Bvh longer = bvh;
  longer.nodes.insert(longer.nodes.begin(), (Bvh8::kWidth - 1) * HP_BVH_STACK_SIZE + 20 - chain, bvh.nodes[0]);
  for (auto& n : longer.nodes) {
    if (!node_is_leaf(n)) n.offset = static_cast<int>(longer.nodes.size() - 1);
  }
  EXPECT_THROW(make_bvh8(longer, lt), std::logic_error);
  // The same chain within the stack works.
  bvh.nodes.erase(bvh.nodes.begin(), bvh.nodes.begin() + 10);
  for (auto& n : bvh.nodes) {
    if (!node_is_leaf(n)) n.offset = static_cast<int>(bvh.nodes.size() - 1);
  }
  EXPECT_TRUE(intersect_closest(bvh, lt, r).hit());
  EXPECT_TRUE(intersect_closest(make_bvh8(bvh, lt), r).hit());
}

}  // namespace
}  // namespace hp::bvh
