// Internal to hp_bvh: what the two builders (binned SAH, full sweep) share.
#pragma once

#include "bvh/bvh.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <exception>
#include <limits>
#include <memory>
#include <mutex>
#include <span>
#include <thread>
#include <vector>

#include <emmintrin.h>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace hp::bvh::detail {

/// Asks for transparent huge pages on a large buffer that is about to be written for the first time. A
/// 1M-triangle build writes about 75 MB of fresh memory (references, nodes); in 4 KiB pages their first-touch
/// faults took a quarter of a single-thread build's CPU time on the 2-core VM. Advice only: where it is
/// ignored (THP off, another OS) nothing changes, and it never changes what is written.
inline void advise_huge_pages([[maybe_unused]] const void* data, [[maybe_unused]] std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  constexpr std::size_t kHuge = std::size_t{2} << 20;
  if (bytes < 2 * kHuge) return;
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t first = (begin + kHuge - 1) & ~(kHuge - 1);
  const std::uintptr_t last = (begin + bytes) & ~(kHuge - 1);
  if (last > first) madvise(reinterpret_cast<void*>(first), last - first, MADV_HUGEPAGE);
#endif
}

/// Milliseconds from a to b on the steady clock (the build's phases).
inline double ms_between(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

/// Faults in the pages of [data, data + bytes) for writing without writing them (MADV_POPULATE_WRITE, Linux
/// 5.14), so that a later copy into them takes no page faults. Only whole pages inside the range. Advice only,
/// like advise_huge_pages: where the kernel lacks it nothing changes, and it never changes what is written.
inline void populate_for_write([[maybe_unused]] const void* data, [[maybe_unused]] std::size_t bytes) {
#if defined(__linux__)
#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23  // the value of Linux's uapi header, for older C libraries
#endif
  constexpr std::size_t kPage = 4096;
  const auto begin = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t first = (begin + kPage - 1) & ~(kPage - 1);
  const std::uintptr_t last = (begin + bytes) & ~(kPage - 1);
  if (last > first) madvise(reinterpret_cast<void*>(first), last - first, MADV_POPULATE_WRITE);
#endif
}

/// A primitive's bounds and its scene index, 32 bytes so that partitioning moves whole cache-line halves.
/// The centroid is never stored: the builders use lo + hi (twice the centroid) everywhere.
struct PrimRef {
  glm::vec3 lo;
  uint32_t id;
  glm::vec3 hi;
  uint32_t pad;
};
static_assert(sizeof(PrimRef) == 32);

/// Bounds of a set of references, folded one reference at a time: their box, the box of their doubled
/// centroids (lo + hi), and whether any bound is -0.0. Lane 3 of every corner is 0.
struct RefBounds {
  __m128 lo = _mm_set1_ps(std::numeric_limits<float>::infinity());
  __m128 hi = _mm_set1_ps(-std::numeric_limits<float>::infinity());
  __m128 clo = lo, chi = hi;
  __m128i neg_zero = _mm_setzero_si128();
  /// Corners with lane 3 = 0.
  void add(__m128 l, __m128 h) {
    lo = _mm_min_ps(lo, l);
    hi = _mm_max_ps(hi, h);
    const __m128 c = _mm_add_ps(l, h);
    clo = _mm_min_ps(clo, c);
    chi = _mm_max_ps(chi, c);
    const __m128i nz = _mm_set1_epi32(static_cast<int>(0x80000000u));
    neg_zero = _mm_or_si128(neg_zero, _mm_or_si128(_mm_cmpeq_epi32(_mm_castps_si128(l), nz),
                                                   _mm_cmpeq_epi32(_mm_castps_si128(h), nz)));
  }
  void add(const PrimRef& r) {
    const __m128 xyz = _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1));
    add(_mm_and_ps(_mm_loadu_ps(&r.lo.x), xyz), _mm_and_ps(_mm_loadu_ps(&r.hi.x), xyz));
  }
  void add(const RefBounds& o) {
    lo = _mm_min_ps(lo, o.lo);
    hi = _mm_max_ps(hi, o.hi);
    clo = _mm_min_ps(clo, o.clo);
    chi = _mm_max_ps(chi, o.chi);
    neg_zero = _mm_or_si128(neg_zero, o.neg_zero);
  }
  bool signed_zeros() const { return _mm_movemask_epi8(neg_zero) != 0; }
};

/// A triangle's reference, or false where is_degenerate(tri) holds: the same results as is_degenerate and
/// a box of glm::min / glm::max over the vertices, computed in SSE registers without a branch per vertex
/// (tests/unit/bvh/build_identity_test.cpp compares the two on edge cases). glm::min(x, y) is (y < x) ? y : x,
/// which is _mm_min_ps(y, x), so even the signs of zeros agree; the cross product is is_degenerate's
/// double arithmetic, component by component. The three loads stay inside the 36-byte triangle. A reference
/// made is also folded into `bounds` where given.
inline bool make_triangle_ref(const Triangle& tri, uint32_t id, PrimRef& out, RefBounds* bounds = nullptr) {
  const float* f = &tri.v0.x;
  const __m128 a = _mm_loadu_ps(f);      // x0 y0 z0 x1
  const __m128 b = _mm_loadu_ps(f + 3);  // x1 y1 z1 x2
  const __m128 c = _mm_loadu_ps(f + 5);  // z1 x2 y2 z2
  const __m128i exponent = _mm_set1_epi32(0x7f800000);
  const auto non_finite = [&](__m128 v) {
    return _mm_cmpeq_epi32(_mm_and_si128(_mm_castps_si128(v), exponent), exponent);
  };
  if (_mm_movemask_epi8(_mm_or_si128(non_finite(a), _mm_or_si128(non_finite(b), non_finite(c)))) != 0) return false;
  const __m128 xyz = _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1));
  const __m128 v0 = _mm_and_ps(a, xyz), v1 = _mm_and_ps(b, xyz);
  const __m128 v2 = _mm_castsi128_ps(_mm_srli_si128(_mm_castps_si128(c), 4));
  // e = v - v0 in double: (x, y) and (z, 0).
  const __m128d d0 = _mm_cvtps_pd(v0), d0z = _mm_cvtps_pd(_mm_movehl_ps(v0, v0));
  const __m128d e1 = _mm_sub_pd(_mm_cvtps_pd(v1), d0), e1z = _mm_sub_pd(_mm_cvtps_pd(_mm_movehl_ps(v1, v1)), d0z);
  const __m128d e2 = _mm_sub_pd(_mm_cvtps_pd(v2), d0), e2z = _mm_sub_pd(_mm_cvtps_pd(_mm_movehl_ps(v2, v2)), d0z);
  // glm::cross(e1, e2) = (e1.y e2.z - e2.y e1.z, e1.z e2.x - e2.z e1.x, e1.x e2.y - e2.x e1.y).
  const __m128d nxy = _mm_sub_pd(_mm_mul_pd(_mm_shuffle_pd(e1, e1z, 1), _mm_shuffle_pd(e2z, e2, 0)),
                                 _mm_mul_pd(_mm_shuffle_pd(e2, e2z, 1), _mm_shuffle_pd(e1z, e1, 0)));
  const __m128d nz = _mm_sub_sd(_mm_mul_sd(e1, _mm_unpackhi_pd(e2, e2)), _mm_mul_sd(e2, _mm_unpackhi_pd(e1, e1)));
  const __m128d zero = _mm_setzero_pd();
  if (_mm_movemask_pd(_mm_cmpeq_pd(nxy, zero)) == 3 && (_mm_movemask_pd(_mm_cmpeq_sd(nz, zero)) & 1) != 0) {
    return false;
  }
  // Lane 3 of both corners is +0: the id goes into the low corner's, the padding stays 0.
  const __m128 lo = _mm_min_ps(_mm_min_ps(v2, v1), v0), hi = _mm_max_ps(_mm_max_ps(v2, v1), v0);
  _mm_storeu_ps(&out.lo.x, _mm_or_ps(lo, _mm_castsi128_ps(_mm_set_epi32(static_cast<int>(id), 0, 0, 0))));
  _mm_storeu_ps(&out.hi.x, hi);
  if (bounds != nullptr) bounds->add(lo, hi);
  return true;
}

/// Half the surface area: the SAH only compares ratios, so the factor 2 is dropped.
inline float half_area(const glm::vec3& lo, const glm::vec3& hi) {
  const glm::vec3 e = hi - lo;
  return e.x * e.y + e.y * e.z + e.z * e.x;
}

/// Interior levels a balanced (median-split) subtree over n primitives needs with leaves of at most
/// `leaf` primitives: the smallest k with leaf * 2^k >= n.
inline int levels_needed(uint64_t n, uint64_t leaf) {
  int k = 0;
  while (leaf < n) {
    leaf *= 2;
    ++k;
  }
  return k;
}

/// Output of a builder before flattening: nodes where an interior node's children are the pair
/// (offset, offset + 1), the root at 0; leaves index `order`. A builder that already produced the final
/// depth-first layout returns it in `flat` instead (then `nodes` is null).
struct PairTree {
  std::unique_ptr<gpu::BvhNode[]> nodes;  ///< uninitialised beyond node_count
  std::size_t node_count = 0;
  std::vector<gpu::BvhNode> flat;  ///< the flattened layout of bvh.hpp, when the builder wrote it directly
  int flat_max_depth = 0;          ///< with `flat`: interior nodes above the deepest leaf
  std::vector<uint32_t> order;     ///< leaf order -> scene index
  std::size_t depth_limited_splits = 0;
  BuildPhases phases;  ///< the fork's part (forked, top, first, second, append); build_bvh sets the rest
};

inline gpu::BvhNode make_leaf(const glm::vec3& lo, const glm::vec3& hi, uint32_t first, uint32_t count) {
  return gpu::BvhNode{lo, static_cast<int>(first), hi, count << HP_BVH_AXIS_BITS};
}
inline gpu::BvhNode make_interior(const glm::vec3& lo, const glm::vec3& hi, uint32_t first_child, uint32_t axis) {
  return gpu::BvhNode{lo, static_cast<int>(first_child), hi, axis};
}

/// Fork-join helper: runs `a` on a new thread when a worker slot is free and the subtree is big enough to
/// pay for a thread start, else inline; runs `b` inline; waits for both. Slots return as soon as a forked
/// subtree finishes, so a long unbalanced branch picks up the core a short one gave back.
class Forker {
 public:
  explicit Forker(int threads) : free_slots_(threads - 1) {}

  template <class A, class B>
  void fork_join(std::size_t size_a, A&& a, B&& b) {
    if (size_a >= kMinForkSize && try_acquire()) {
      std::exception_ptr error;
      std::thread t([&] {
        try {
          a(true);
        } catch (...) {
          error = std::current_exception();
        }
        free_slots_.fetch_add(1, std::memory_order_release);
      });
      try {
        b();
      } catch (...) {
        t.join();
        throw;
      }
      t.join();
      if (error) std::rethrow_exception(error);
    } else {
      a(false);
      b();
    }
  }

  /// For a caller that runs its own thread: takes a worker slot when `size` is big enough to fork and one
  /// is free (the same rule as fork_join); the caller gives it back with release() when its thread ends.
  bool try_fork(std::size_t size) { return size >= kMinForkSize && try_acquire(); }
  void release() { free_slots_.fetch_add(1, std::memory_order_release); }

  /// Splits [0, n) into one contiguous chunk per worker and runs f(begin, end, chunk) on each, in parallel.
  template <class F>
  static void parallel_chunks(std::size_t n, int threads, F&& f) {
    const std::size_t chunks = std::max<std::size_t>(1, std::min<std::size_t>(threads, n / 65536 + 1));
    std::vector<std::thread> pool;
    std::exception_ptr error;
    std::mutex error_mutex;
    for (std::size_t c = 1; c < chunks; ++c) {
      pool.emplace_back([&, c] {
        try {
          f(n * c / chunks, n * (c + 1) / chunks, c);
        } catch (...) {
          std::lock_guard lock(error_mutex);
          error = std::current_exception();
        }
      });
    }
    try {
      f(0, n / chunks, std::size_t{0});
    } catch (...) {
      std::lock_guard lock(error_mutex);
      error = std::current_exception();
    }
    for (auto& t : pool) t.join();
    if (error) std::rethrow_exception(error);
  }

 private:
  static constexpr std::size_t kMinForkSize = 8192;
  bool try_acquire() {
    int n = free_slots_.load(std::memory_order_relaxed);
    while (n > 0) {
      if (free_slots_.compare_exchange_weak(n, n - 1, std::memory_order_acquire)) return true;
    }
    return false;
  }
  std::atomic<int> free_slots_;
};

/// Knobs both builders read, already validated.
struct BuildParams {
  int buckets;
  bool all_axes;
  float traversal_cost;
  uint32_t max_leaf;
  int max_depth;
  int threads;
};

/// The code the binned builder runs: `automatic` is AVX2 where the CPU has it, else the baseline x86-64
/// code. Both build the same tree to the bit (tests/unit/bvh/build_identity_test.cpp compares them).
enum class BinnedIsa { automatic, baseline, avx2 };
/// Binned SAH over `prims` (reordered in place into leaf order). Asking for AVX2 on a CPU without it is a
/// logic error.
/// `bounds`, where given, are those of `prims` (RefBounds folded over them in any order); without them, or
/// where they saw a -0.0 (whose sign depends on the fold order), the builder folds its own.
PairTree build_binned(std::span<PrimRef> prims, const BuildParams& params, BinnedIsa isa = BinnedIsa::automatic,
                      const RefBounds* bounds = nullptr);
/// Whether this CPU (and its OS) runs AVX2 code.
bool binned_avx2_available();
/// Exact full-sweep SAH over all three axes.
PairTree build_full_sweep(std::span<const PrimRef> prims, const BuildParams& params);

}  // namespace hp::bvh::detail
