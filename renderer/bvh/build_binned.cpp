// Top-down binned SAH (Wald 2007, "On fast construction of SAH-based bounding volume hierarchies"; the
// scheme of pbrt's BVHAggregate): primitives are binned by centroid, the best bin boundary is chosen by
// t_trav + (N_A*S_A + N_B*S_B)/S against the leaf cost N, and the range is partitioned in place.
//
// Axes: `all_axes` bins the three axes at once and takes the cheapest split; otherwise only the axis of
// largest centroid extent is binned (the study's and pbrt's rule). Each node costs one binning pass and one
// partition pass; the partition pass also collects the children's centroid bounds and the bins give their
// boxes, so no third pass is needed. Bounds are kept in 4-wide SSE registers (x, y, z, unused).
//
// The tree is a pure function of the input and the options (tests/unit/bvh/build_identity_test.cpp pins
// it): every speed-up computes the same floats in the same order per value, and regrouping min/max folds
// (which can only change the sign of a zero) is limited to inputs without -0.0 bounds (signed_zeros_).
// Nodes are appended in the final depth-first layout; a subtree built on another thread is appended after
// its sibling's (see finish_interior).
#include "bvh/build_common.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>
#include <thread>

#include <immintrin.h>

namespace hp::bvh::detail {
namespace {
namespace baseline {
#define HP_BINNED_BLENDV 0
#include "bvh/build_binned.inl"
#undef HP_BINNED_BLENDV
}  // namespace baseline
}  // namespace

// The same code for AVX2 CPUs: VEX encodings (three operands, fewer register copies) make the builder a few
// percent faster (docs/bvh-performance.md) and compute the same floats: the target brings no fused
// multiply-add, and the intrinsics are the same operations. Everything included above keeps the baseline
// target, so no shared inline function is ever emitted for AVX2 alone. (Clang takes the target as an
// attribute pushed onto every function of the region.)
#if defined(__clang__)
#pragma clang attribute push(__attribute__((target("avx2"))), apply_to = function)
#else
#pragma GCC push_options
#pragma GCC target("avx2")
#endif
namespace {
namespace avx2 {
#define HP_BINNED_BLENDV 1
#include "bvh/build_binned.inl"
#undef HP_BINNED_BLENDV
}  // namespace avx2
}  // namespace
#if defined(__clang__)
#pragma clang attribute pop
#else
#pragma GCC pop_options
#endif

PairTree build_binned(std::span<PrimRef> prims, const BuildParams& params, BinnedIsa isa, const RefBounds* bounds) {
  if (isa == BinnedIsa::automatic) isa = binned_avx2_available() ? BinnedIsa::avx2 : BinnedIsa::baseline;
  if (isa == BinnedIsa::avx2) {
    if (!binned_avx2_available()) throw std::logic_error("bvh build: AVX2 asked for on a CPU without it");
    return avx2::BinnedBuilder(prims, params).run(bounds);
  }
  return baseline::BinnedBuilder(prims, params).run(bounds);
}

bool binned_avx2_available() {
  static const bool has = __builtin_cpu_supports("avx2");
  return has;
}

}  // namespace hp::bvh::detail
