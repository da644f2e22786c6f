// Compiled with -ffp-contract=off (see CMakeLists.txt): a fused multiply-add in an edge function rounds
// the two products differently, so the two triangles sharing an edge no longer compute exactly opposite
// values for it, and rays through the edge fall through (watertightness is lost).
#include "bvh/traverse.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace hp::bvh {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

/// 1 + 2 gamma(3) with gamma(n) = n eps / (1 - n eps), eps = 2^-24 (Ize 2013), rounded up to a float so
/// the widening is at least what the bound asks for.
const float kFarUp = [] {
  const double eps = std::ldexp(1.0, -24);
  const double g3 = 3.0 * eps / (1.0 - 3.0 * eps);
  const double v = 1.0 + 2.0 * g3;
  float f = static_cast<float>(v);
  if (static_cast<double>(f) < v) f = std::nextafter(f, 2.0f);
  return f;
}();
/// The same widening for a negative far bound (a box behind an origin when tmin < 0).
const float kFarDown = [] {
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

bool prepare(const Ray& ray, PreparedRay& r) {
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

inline const float* node_floats(const gpu::BvhNode& n) { return &n.bmin.x; }

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

template <bool kAny>
Hit traverse(const Bvh& bvh, const LeafOrderTriangles& lt, const Ray& ray, TraversalStats* stats) {
  Hit best;
  PreparedRay r;
  if (bvh.nodes.empty() || !prepare(ray, r)) return best;
  const bool objects = !lt.object_first.empty();
  const gpu::BvhNode* nodes = bvh.nodes.data();
  const Triangle* tris = lt.triangles.data();
  const uint32_t* scene = lt.scene_index.data();

  float best_t = r.tmax;
  uint32_t best_scene = UINT32_MAX;
  uint64_t visited = 0, tested = 0;
  uint32_t stack[HP_BVH_STACK_SIZE];
  int sp = 0;
  uint32_t node = 0;
  for (;;) {
    const gpu::BvhNode& n = nodes[node];
    ++visited;
    float tn, tf;
    if (slab(r, node_floats(n), best_t, tn, tf)) {
      const uint32_t count = n.prim_axis >> HP_BVH_AXIS_BITS;
      if (count == 0) {
        const uint32_t axis = n.prim_axis & HP_BVH_AXIS_MASK;
        uint32_t near_child = node + 1;
        uint32_t far_child = static_cast<uint32_t>(n.offset);
        if (r.near_at[axis] >= 4) std::swap(near_child, far_child);
        if (sp == HP_BVH_STACK_SIZE) {
          // build_bvh bounds the depth; a tree that breaks it was not built by build_bvh.
          throw std::logic_error("bvh traversal: stack overflow (tree deeper than HP_BVH_STACK_SIZE)");
        }
        stack[sp++] = far_child;
        // The far child is usually visited soon after the near subtree; on trees larger than the caches
        // fetching it now measured 10-30% more rays per second (1M-triangle scenes, random rays).
        __builtin_prefetch(&nodes[far_child]);
        node = near_child;
        continue;
      }
      uint32_t first = static_cast<uint32_t>(n.offset);
      uint32_t last = first + count;
      if (objects) {
        first = lt.object_first[first];
        last = lt.object_first[last];
      }
      for (uint32_t k = first; k < last; ++k) {
        ++tested;
        float t, u, v;
        if (!watertight(r, tris[k], t, u, v)) continue;
        if (!(t >= r.tmin)) continue;
        if constexpr (kAny) {
          if (!(t <= r.tmax)) continue;
          best = Hit{static_cast<int32_t>(scene[k]), t, u, v};
          sp = 0;  // occluded: nothing else matters
          break;
        } else {
          if (t < best_t || (t == best_t && scene[k] < best_scene)) {
            best_t = t;
            best_scene = scene[k];
            best = Hit{static_cast<int32_t>(scene[k]), t, u, v};
          }
        }
      }
    }
    if (sp == 0) break;
    node = stack[--sp];
  }
  if (stats) {
    stats->nodes_visited += visited;
    stats->triangles_tested += tested;
  }
  return best;
}

template <bool kAny>
Hit brute_force(std::span<const Triangle> triangles, const Ray& ray) {
  Hit best;
  PreparedRay r;
  if (!prepare(ray, r)) return best;
  float best_t = r.tmax;
  for (std::size_t k = 0; k < triangles.size(); ++k) {
    if (is_degenerate(triangles[k])) continue;
    float t, u, v;
    if (!watertight(r, triangles[k], t, u, v) || !(t >= r.tmin) || !(t <= best_t)) continue;
    if (kAny) return Hit{static_cast<int32_t>(k), t, u, v};
    // Scene order is increasing k, so "t == best_t" keeps the smaller index already.
    if (t < best_t || best.prim < 0) {
      best_t = t;
      best = Hit{static_cast<int32_t>(k), t, u, v};
    }
  }
  return best;
}

}  // namespace

Hit intersect_closest(const Bvh& bvh, const LeafOrderTriangles& tris, const Ray& ray, TraversalStats* stats) {
  return traverse<false>(bvh, tris, ray, stats);
}

Hit intersect_any(const Bvh& bvh, const LeafOrderTriangles& tris, const Ray& ray, TraversalStats* stats) {
  return traverse<true>(bvh, tris, ray, stats);
}

std::vector<Hit> cast_rays(const Bvh& bvh, const LeafOrderTriangles& tris, std::span<const Ray> rays, HitMode mode,
                           int threads, TraversalStats* stats) {
  std::vector<Hit> hits(rays.size());
  const int workers =
      std::max(1, std::min<int>(threads > 0 ? threads : static_cast<int>(std::thread::hardware_concurrency()),
                                static_cast<int>(rays.size() / 1024 + 1)));
  // Rays are handed out in blocks from a shared counter, so a slow region does not idle the other workers.
  constexpr std::size_t kBlock = 1024;
  std::atomic<std::size_t> next{0};
  std::vector<TraversalStats> partial(workers);
  auto work_block = [&](int w) {
    TraversalStats local;
    for (;;) {
      const std::size_t begin = next.fetch_add(kBlock, std::memory_order_relaxed);
      if (begin >= rays.size()) break;
      const std::size_t end = std::min(rays.size(), begin + kBlock);
      for (std::size_t i = begin; i < end; ++i) {
        hits[i] = mode == HitMode::closest ? traverse<false>(bvh, tris, rays[i], &local)
                                           : traverse<true>(bvh, tris, rays[i], &local);
      }
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

bool intersect_triangle(const Ray& ray, const Triangle& tri, Hit& hit) {
  PreparedRay r;
  if (!prepare(ray, r)) return false;
  float t, u, v;
  if (!watertight(r, tri, t, u, v) || !(t >= r.tmin) || !(t <= r.tmax)) return false;
  hit = Hit{0, t, u, v};
  return true;
}

bool intersect_box(const Ray& ray, const glm::vec3& bmin, const glm::vec3& bmax, float& tnear, float& tfar) {
  PreparedRay r;
  if (!prepare(ray, r)) return false;
  const float box[8] = {bmin.x, bmin.y, bmin.z, 0.0f, bmax.x, bmax.y, bmax.z, 0.0f};
  return slab(r, box, r.tmax, tnear, tfar);
}

Hit brute_force_closest(std::span<const Triangle> triangles, const Ray& ray) {
  return brute_force<false>(triangles, ray);
}

Hit brute_force_any(std::span<const Triangle> triangles, const Ray& ray) { return brute_force<true>(triangles, ray); }

}  // namespace hp::bvh
