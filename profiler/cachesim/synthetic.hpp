// Generated BVH-like traces for tests, benchmarks and sensitivity studies, while no real capture
// exists: one ray per pixel of a width x height image (8x8 workgroups) walks a complete binary tree
// of 32-byte nodes laid out depth-first (first child after its parent, as in shared_types.h), loading
// each visited node as two 16-byte halves, two 48-byte triangles (three 16-byte loads each) at every
// leaf, after reading its G-buffer texel (8 bytes, tiled 8x8 image) and before storing one output
// texel (4 bytes, linear image). A ray descends towards its pixel's point in the unit square (split
// axis alternating x/y) and also visits the far child when the point lies within `far_margin` of the
// split (relative to the node's extent): neighbouring rays share paths, as coherent primary rays do.
// A fraction of rays (`incoherent_fraction`) take a random point instead, like secondary rays.
#pragma once

#include <cstdint>

#include "trace/trace_file.hpp"

namespace hp::cachesim {

struct SyntheticBvhOptions {
  uint32_t width = 256, height = 256;
  uint32_t tree_depth = 17;  // 2^(depth+1) - 1 nodes (17: 8 MiB of nodes, 12 MiB of triangles)
  double far_margin = 0.06;
  double incoherent_fraction = 0.0;
  uint64_t seed = 1;
};

// One pass "bvh_like" over buffers 0 nodes, 1 triangles, 2 gbuffer (image_tiled), 3 output
// (image_linear). Deterministic for given options.
trace::Trace make_bvh_like_trace(const SyntheticBvhOptions& options);

}  // namespace hp::cachesim
