// Internal to hp_bvh: the per-ray setup, slab test and watertight triangle test that every CPU traversal
// (the binary reference in traverse.cpp, the 8-wide one in bvh8.cpp) shares, so that they compute the
// same values to the last bit. Include only from files compiled with -ffp-contract=off (CMakeLists.txt).
#pragma once

#include "bvh/geometry.hpp"

#include "bvh/traverse.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <limits>
#include <mutex>
#include <span>
#include <thread>
#include <type_traits>
#include <vector>

namespace hp::bvh::detail {

constexpr float kInf = std::numeric_limits<float>::infinity();

/// 1 + 2 gamma(3) with gamma(n) = n eps / (1 - n eps), eps = 2^-24 (Ize 2013), rounded up to a float so
/// the widening is at least what the bound asks for.
inline const float kFarUp = [] {
  const double eps = std::ldexp(1.0, -24);
  const double g3 = 3.0 * eps / (1.0 - 3.0 * eps);
  const double v = 1.0 + 2.0 * g3;
  float f = static_cast<float>(v);
  if (static_cast<double>(f) < v) f = std::nextafter(f, 2.0f);
  return f;
}();
/// The same widening for a negative far bound (a box behind an origin when tmin < 0).
inline const float kFarDown = [] {
  const double eps = std::ldexp(1.0, -24);
  const double g3 = 3.0 * eps / (1.0 - 3.0 * eps);
  const double v = 1.0 - 2.0 * g3;
  float f = static_cast<float>(v);
  if (static_cast<double>(f) > v) f = std::nextafter(f, 0.0f);
  return f;
}();

inline float widen_far(float t) { return t >= 0.0f ? t * kFarUp : t * kFarDown; }

inline bool finite3(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

/// Per-ray constants of the slab and the watertight tests.
struct PreparedRay {
  float org[3];
  float inv[3];
  int near_at[3];  // float offset of the near plane in a node: 0..2 = bmin, 4..6 = bmax
  int far_at[3];
  float tmin, tmax;
  // Watertight test: the axis of largest |dir| is kz; kx, ky follow it, swapped when dir[kz] < 0 so the
  // winding is preserved; the shear maps the ray onto +z.
  int kx, ky, kz;
  float sx, sy, sz;
};

inline bool prepare(const Ray& ray, PreparedRay& r) {
  if (!finite3(ray.origin) || !finite3(ray.dir) || std::isnan(ray.tmin) || std::isnan(ray.tmax)) return false;
  if (ray.dir.x == 0.0f && ray.dir.y == 0.0f && ray.dir.z == 0.0f) return false;
  const float d[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  const float o[3] = {ray.origin.x, ray.origin.y, ray.origin.z};
  for (int a = 0; a < 3; ++a) {
    r.org[a] = o[a];
    // 1/(+0) = +inf and 1/(-0) = -inf: the sign of the reciprocal, not of d, picks the planes (Williams).
    r.inv[a] = 1.0f / d[a];
    const bool neg = std::signbit(r.inv[a]);
    r.near_at[a] = (neg ? 4 : 0) + a;
    r.far_at[a] = (neg ? 0 : 4) + a;
  }
  r.tmin = ray.tmin;
  r.tmax = ray.tmax;
  const float ad[3] = {std::abs(d[0]), std::abs(d[1]), std::abs(d[2])};
  r.kz = ad[0] >= ad[1] ? (ad[0] >= ad[2] ? 0 : 2) : (ad[1] >= ad[2] ? 1 : 2);
  r.kx = (r.kz + 1) % 3;
  r.ky = (r.kx + 1) % 3;
  if (d[r.kz] < 0.0f) std::swap(r.kx, r.ky);
  r.sx = d[r.kx] / d[r.kz];
  r.sy = d[r.ky] / d[r.kz];
  r.sz = 1.0f / d[r.kz];
  return true;
}

/// Slab test against a node's box, with the far bound min(box far, t_hi) widened. Reads the node as floats:
/// bmin at 0..2, bmax at 4..6 (the layout shared_types.h pins).
inline bool slab(const PreparedRay& r, const float* box, float t_hi, float& tnear, float& tfar) {
  float tn = r.tmin;
  float tf = kInf;
  for (int a = 0; a < 3; ++a) {
    const float t0 = (box[r.near_at[a]] - r.org[a]) * r.inv[a];
    const float t1 = (box[r.far_at[a]] - r.org[a]) * r.inv[a];
    // Written so that a NaN t0/t1 (0 * inf) leaves the bound unchanged: the comparison is false.
    tn = t0 > tn ? t0 : tn;
    tf = t1 < tf ? t1 : tf;
  }
  tf = t_hi < tf ? t_hi : tf;
  tf = widen_far(tf);
  tnear = tn;
  tfar = tf;
  return tn <= tf;
}

/// Watertight ray/triangle (Woop, Benthin, Wald 2013). Returns true for a hit anywhere on the line
/// (edges and vertices included); t, u, v are written; the caller checks the range of t.
inline bool watertight(const PreparedRay& r, const Triangle& tri, float& t, float& u, float& v) {
  const float* p0 = &tri.v0.x;
  const float* p1 = &tri.v1.x;
  const float* p2 = &tri.v2.x;
  const int kx = r.kx, ky = r.ky, kz = r.kz;
  const float ax = p0[kx] - r.org[kx], ay = p0[ky] - r.org[ky], az = p0[kz] - r.org[kz];
  const float bx = p1[kx] - r.org[kx], by = p1[ky] - r.org[ky], bz = p1[kz] - r.org[kz];
  const float cx = p2[kx] - r.org[kx], cy = p2[ky] - r.org[ky], cz = p2[kz] - r.org[kz];
  // Shear: each vertex's value depends only on that vertex and the ray, so a vertex shared by two
  // triangles gets bit-identical values in both, and their shared edge's function is exactly negated.
  const float Ax = ax - r.sx * az, Ay = ay - r.sy * az;
  const float Bx = bx - r.sx * bz, By = by - r.sy * bz;
  const float Cx = cx - r.sx * cz, Cy = cy - r.sy * cz;
  float U = Cx * By - Cy * Bx;
  float V = Ax * Cy - Ay * Cx;
  float W = Bx * Ay - By * Ax;
  if (U == 0.0f || V == 0.0f || W == 0.0f) {
    // On (or within rounding of) an edge: the float products are exact in double, so the sign is exact.
    U = static_cast<float>(static_cast<double>(Cx) * By - static_cast<double>(Cy) * Bx);
    V = static_cast<float>(static_cast<double>(Ax) * Cy - static_cast<double>(Ay) * Cx);
    W = static_cast<float>(static_cast<double>(Bx) * Ay - static_cast<double>(By) * Ax);
  }
  if ((U < 0.0f || V < 0.0f || W < 0.0f) && (U > 0.0f || V > 0.0f || W > 0.0f)) return false;
  const float det = U + V + W;
  if (det == 0.0f) return false;
  const float Az = r.sz * az, Bz = r.sz * bz, Cz = r.sz * cz;
  const float T = U * Az + V * Bz + W * Cz;
  t = T / det;
  u = V / det;
  v = W / det;
  return true;
}

/// Tests the primitives of one leaf, [first, last) in leaf order (object slots, mapped through
/// lt.object_first, where the tree holds objects), counting each test in `tested`. Closest hit: keeps the
/// smallest t in `best` (ties to the smallest scene index, `best_scene`), pruning bound `best_t`. Any hit:
/// returns true at the first hit in [tmin, tmax], in `best`.
template <bool kAny>
inline bool test_leaf(const PreparedRay& r, const LeafOrderTriangles& lt, uint32_t first, uint32_t last, Hit& best,
                      float& best_t, uint32_t& best_scene, uint64_t& tested) {
  if (!lt.object_first.empty()) {
    first = lt.object_first[first];
    last = lt.object_first[last];
  }
  const Triangle* tris = lt.triangles.data();
  const uint32_t* scene = lt.scene_index.data();
  for (uint32_t k = first; k < last; ++k) {
    ++tested;
    float t, u, v;
    if (!watertight(r, tris[k], t, u, v)) continue;
    if (!(t >= r.tmin)) continue;
    if constexpr (kAny) {
      if (!(t <= r.tmax)) continue;
      best = Hit{static_cast<int32_t>(scene[k]), t, u, v};
      return true;
    } else {
      if (t < best_t || (t == best_t && scene[k] < best_scene)) {
        best_t = t;
        best_scene = scene[k];
        best = Hit{static_cast<int32_t>(scene[k]), t, u, v};
      }
    }
  }
  return false;
}

/// Casts `rays` on `threads` workers (0 = all cores) with `trace(ray, stats) -> Hit`; hit i belongs to rays[i],
/// `stats` (optional) receives the sum over all rays. Rays are handed out in blocks from a shared counter, so
/// a slow region does not idle the other workers; the first exception a worker throws is rethrown.
template <typename Trace>
std::vector<Hit> cast_parallel(std::span<const Ray> rays, int threads, TraversalStats* stats, Trace trace) {
  std::vector<Hit> hits(rays.size());
  const int workers =
      std::max(1, std::min<int>(threads > 0 ? threads : static_cast<int>(std::thread::hardware_concurrency()),
                                static_cast<int>(rays.size() / 1024 + 1)));
  constexpr std::size_t kBlock = 1024;
  std::atomic<std::size_t> next{0};
  std::vector<TraversalStats> partial(workers);
  auto work_block = [&](int w) {
    TraversalStats local;
    for (;;) {
      const std::size_t begin = next.fetch_add(kBlock, std::memory_order_relaxed);
      if (begin >= rays.size()) break;
      const std::size_t end = std::min(rays.size(), begin + kBlock);
      for (std::size_t i = begin; i < end; ++i) hits[i] = trace(rays[i], &local);
    }
    partial[w] = local;
  };
  std::exception_ptr error;
  std::mutex error_mutex;
  auto work = [&](int w) noexcept {
    try {
      work_block(w);
    } catch (...) {
      std::lock_guard lock(error_mutex);
      error = std::current_exception();
      next.store(rays.size());  // stop the other workers early
    }
  };
  std::vector<std::thread> pool;
  for (int w = 1; w < workers; ++w) pool.emplace_back(work, w);
  work(0);
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);
  if (stats) {
    for (const auto& p : partial) *stats += p;
  }
  return hits;
}

/// cast_parallel for a hit mode: `trace(std::bool_constant<any>, ray, stats) -> Hit`, instantiated for both.
template <typename Trace>
std::vector<Hit> cast_mode(std::span<const Ray> rays, HitMode mode, int threads, TraversalStats* stats, Trace trace) {
  if (mode == HitMode::closest) {
    return cast_parallel(rays, threads, stats,
                         [&](const Ray& ray, TraversalStats* local) { return trace(std::false_type{}, ray, local); });
  }
  return cast_parallel(rays, threads, stats,
                       [&](const Ray& ray, TraversalStats* local) { return trace(std::true_type{}, ray, local); });
}

}  // namespace hp::bvh::detail
